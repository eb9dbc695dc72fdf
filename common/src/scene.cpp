#include <afr/common/scene.h>

#include <afr/common/error.h>
#include <afr/common/image.h>

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>

namespace afr {

// ---------------------------------------------------------------------------------------------
// Textures

namespace {

using Wrap = Texture::Wrap;

// Texel i of a row (or column) of n texels under wrap mode w.
int address(long i, int n, Wrap w) {
  switch (w) {
    case Wrap::kClampToEdge:
      return int(std::clamp<long>(i, 0, n - 1));
    case Wrap::kMirroredRepeat: {
      const long period = 2L * n, p = ((i % period) + period) % period;
      return int(p < n ? p : period - 1 - p);
    }
    case Wrap::kRepeat:
      break;
  }
  return int(((i % n) + n) % n);
}

// A texture coordinate brought into one period of its wrap mode first, so that huge ones keep
// their precision (and their texel index fits a long): [0, 1) for REPEAT, [0, 2) for
// MIRRORED_REPEAT; CLAMP_TO_EDGE needs nothing beyond [-1, 2]. Not finite: 0.
double reduce(float c, Wrap w) {
  if (!std::isfinite(c)) return 0.0;
  switch (w) {
    case Wrap::kClampToEdge:
      return std::clamp(double(c), -1.0, 2.0);
    case Wrap::kMirroredRepeat:
      return double(c) - 2.0 * std::floor(double(c) / 2.0);
    case Wrap::kRepeat:
      break;
  }
  return double(c) - std::floor(double(c));
}

// 8-bit codes to linear values: sRGB-encoded (the formula, as the loader decoded before codes
// were kept) and linear (v / 255).
struct CodeTables {
  std::array<float, 256> srgb, linear;
};
const CodeTables& code_tables() {
  static const CodeTables tables = [] {
    CodeTables t;
    for (int v = 0; v < 256; ++v) {
      t.srgb[size_t(v)] = srgb_to_linear(float(v) / 255.0f);
      t.linear[size_t(v)] = float(v) / 255.0f;
    }
    return t;
  }();
  return tables;
}

const std::array<float, 256>& table_of(Texture::Encoding e) {
  return e == Texture::Encoding::kSrgb ? code_tables().srgb : code_tables().linear;
}

glm::vec3 decode(uint32_t code, const std::array<float, 256>& table) {
  return glm::vec3(table[code & 0xff], table[(code >> 8) & 0xff], table[(code >> 16) & 0xff]);
}

float decode_alpha(uint32_t code) { return code_tables().linear[code >> 24]; }

// A linear value's code: the sRGB formula's (rounded) or v x 255 rounded, clamped to [0, 255].
uint32_t encode(float v, Texture::Encoding e) {
  if (e == Texture::Encoding::kSrgb) return linear_to_srgb8(v);
  return uint32_t(std::lround(std::clamp(std::isfinite(v) ? v : 0.0f, 0.0f, 1.0f) * 255.0f));
}

uint32_t encode(const glm::vec3& c, Texture::Encoding e) {
  return encode(c.r, e) | (encode(c.g, e) << 8) | (encode(c.b, e) << 16) | (0xffu << 24);
}

// The lookup of a level whose texel (x, y) is at(x, y): the four texels around uv blended (or
// the one uv falls in, when `nearest`), through the texture's wrap modes.
template <typename At>
auto lookup(int width, int height, const Texture& t, glm::vec2 uv, bool nearest, const At& at) {
  const double u = reduce(uv.x, t.wrap_s) * width;
  const double v = reduce(uv.y, t.wrap_t) * height;
  if (nearest) {
    return at(address(long(std::floor(u)), width, t.wrap_s),
              address(long(std::floor(v)), height, t.wrap_t));
  }
  const double fx = u - 0.5;
  const double fy = v - 0.5;
  const double x0f = std::floor(fx);
  const double y0f = std::floor(fy);
  const float ax = float(fx - x0f);
  const float ay = float(fy - y0f);
  const int x0 = address(long(x0f), width, t.wrap_s), x1 = address(long(x0f) + 1, width, t.wrap_s);
  const int y0 = address(long(y0f), height, t.wrap_t);
  const int y1 = address(long(y0f) + 1, height, t.wrap_t);
  const auto top = glm::mix(at(x0, y0), at(x1, y0), ax);
  const auto bottom = glm::mix(at(x0, y1), at(x1, y1), ax);
  return glm::mix(top, bottom, ay);
}

// A level's lookup, of its floats or of its codes.
glm::vec3 lookup_level(const glm::vec3* texels, const uint32_t* codes, Texture::Encoding e,
                       int width, int height, const Texture& t, glm::vec2 uv, bool nearest) {
  const size_t w = size_t(width);
  if (codes != nullptr) {
    const std::array<float, 256>& table = table_of(e);
    return lookup(width, height, t, uv, nearest,
                  [&](int x, int y) { return decode(codes[size_t(y) * w + size_t(x)], table); });
  }
  return lookup(width, height, t, uv, nearest,
                [&](int x, int y) { return texels[size_t(y) * w + size_t(x)]; });
}

}  // namespace

glm::vec3 Texture::texel(size_t i) const {
  return codes.empty() ? texels[i] : decode(codes[i], table_of(encoding));
}

float Texture::texel_alpha(size_t i) const {
  if (!codes.empty()) return coded_alpha ? decode_alpha(codes[i]) : 1.0f;
  return alpha.empty() ? 1.0f : alpha[i];
}

glm::vec3 Texture::sample_bilinear(glm::vec2 uv) const {
  if (!whole()) return glm::vec3(1.0f);
  return lookup_level(texels.data(), codes.empty() ? nullptr : codes.data(), encoding, width,
                      height, *this, uv, nearest);
}

float Texture::sample_alpha(glm::vec2 uv) const {
  if (!whole()) return 1.0f;
  const size_t w = size_t(width);
  if (!codes.empty()) {
    if (!coded_alpha) return 1.0f;
    return lookup(width, height, *this, uv, nearest,
                  [&](int x, int y) { return decode_alpha(codes[size_t(y) * w + size_t(x)]); });
  }
  if (alpha.size() != texels.size()) return 1.0f;
  return lookup(width, height, *this, uv, nearest,
                [&](int x, int y) { return alpha[size_t(y) * w + size_t(x)]; });
}

void Texture::build_mips() {
  mips.clear();
  if (!whole()) return;
  // Each level halves the one before through the binomial low-pass 1 5 10 10 5 1 (/ 32) in x,
  // then in y, centred on the pair of texels 2i, 2i + 1 that a 2 x 2 box would average, with
  // the texture's wrap modes at the edges. The box lets a pattern just above a level's Nyquist rate
  // through almost whole, aliased to a beat one repeat wide (a floor of 17 dots per 128 texels came
  // out in blotches: residual contrast 0.21 at 32 texels, 0.043 at 16); this kernel keeps 0.042 and
  // 0.014 of it, and being positive it never rings below black (docs/scene-model.md).
  constexpr float kTap[6] = {1.0f / 32, 5.0f / 32, 10.0f / 32, 10.0f / 32, 5.0f / 32, 1.0f / 32};
  // A coded texture's levels are filtered in linear values and coded afterwards; the level
  // being halved is kept as floats meanwhile.
  const bool coded = !codes.empty();
  std::vector<glm::vec3> level0, previous;
  if (coded) {
    level0.resize(codes.size());
    for (size_t i = 0; i < codes.size(); ++i) level0[i] = texel(i);
  }
  const glm::vec3* src = coded ? level0.data() : texels.data();
  int w = width, h = height;
  std::vector<glm::vec3> rows;  // the level's width, the source's height: after the x pass
  while (w > 1 || h > 1) {
    Level l;
    l.width = (w + 1) / 2;
    l.height = (h + 1) / 2;
    rows.assign(size_t(l.width) * size_t(h), glm::vec3(0.0f));
    for (int y = 0; y < h; ++y) {
      const glm::vec3* in = src + size_t(y) * size_t(w);
      glm::vec3* out = rows.data() + size_t(y) * size_t(l.width);
      for (int x = 0; x < l.width; ++x) {
        glm::vec3 sum(0.0f);
        for (int k = 0; k < 6; ++k) sum += kTap[k] * in[address(2L * x - 2 + k, w, wrap_s)];
        out[x] = sum;
      }
    }
    l.texels.resize(size_t(l.width) * size_t(l.height));
    for (int y = 0; y < l.height; ++y) {
      for (int x = 0; x < l.width; ++x) {
        glm::vec3 sum(0.0f);
        for (int k = 0; k < 6; ++k) {
          sum += kTap[k] *
                 rows[size_t(address(2L * y - 2 + k, h, wrap_t)) * size_t(l.width) + size_t(x)];
        }
        l.texels[size_t(y) * size_t(l.width) + size_t(x)] = sum;
      }
    }
    w = l.width;
    h = l.height;
    if (coded) {
      l.codes.resize(l.texels.size());
      for (size_t i = 0; i < l.codes.size(); ++i) l.codes[i] = encode(l.texels[i], encoding);
      previous = std::move(l.texels);
      l.texels = {};
      src = previous.data();
      mips.push_back(std::move(l));
    } else {
      mips.push_back(std::move(l));
      src = mips.back().texels.data();
    }
  }
}

glm::vec3 Texture::sample(glm::vec2 uv, float lod) const {
  if (!(lod > 0.0f) || mips.empty()) return sample_bilinear(uv);
  const float top = float(mips.size());
  lod = std::min(lod, top);
  const int lower = int(lod);
  const float f = lod - float(lower);
  const auto level = [&](int i) {
    if (i == 0) return sample_bilinear(uv);
    const Level& l = mips[size_t(std::min(i, int(mips.size()))) - 1];
    return lookup_level(l.texels.data(), l.codes.empty() ? nullptr : l.codes.data(), encoding,
                        l.width, l.height, *this, uv, false);
  };
  const glm::vec3 a = level(lower);
  return f > 0.0f ? glm::mix(a, level(lower + 1), f) : a;
}

glm::dmat3 Material::UvTransform::matrix() const {
  const double c = std::cos(rotation), s = std::sin(rotation);
  glm::dmat3 m(1.0);  // m[column][row]
  m[0] = glm::dvec3(c * scale.x, -s * scale.x, 0.0);
  m[1] = glm::dvec3(s * scale.y, c * scale.y, 0.0);
  m[2] = glm::dvec3(offset, 1.0);
  return m;
}

// ---------------------------------------------------------------------------------------------
// Normals

namespace {

// Area-weighted sums of the normals of the triangles around each vertex, not normalised.
void sum_triangle_normals(const glm::vec3* positions, size_t vertex_count,
                          const std::vector<uint32_t>& indices, glm::vec3* normals) {
  std::fill_n(normals, vertex_count, glm::vec3(0.0f));
  for (size_t i = 0; i + 2 < indices.size(); i += 3) {
    const uint32_t a = indices[i], b = indices[i + 1], c = indices[i + 2];
    // The cross product's length is twice the area: an area-weighted sum.
    const glm::vec3 n = glm::cross(positions[b] - positions[a], positions[c] - positions[a]);
    if (!std::isfinite(n.x) || !std::isfinite(n.y) || !std::isfinite(n.z)) continue;
    normals[a] += n;
    normals[b] += n;
    normals[c] += n;
  }
}

}  // namespace

void generate_normals(Primitive* p) {
  p->normals.resize(p->positions.size());
  sum_triangle_normals(p->positions.data(), p->positions.size(), p->indices, p->normals.data());
  for (glm::vec3& n : p->normals) {
    const float len = glm::length(n);
    n = len > 0.0f && std::isfinite(len) ? n / len : glm::vec3(0.0f, 0.0f, 1.0f);
  }
  p->generated_normals = true;
}

void generate_tangents(Primitive* p, int uv_set) {
  const std::vector<glm::vec2>& uvs = p->uv_set(uv_set);
  const size_t n = p->positions.size();
  if (uvs.size() != n || p->normals.size() != n) return;
  std::vector<glm::vec3> along_u(n, glm::vec3(0.0f)), along_v(n, glm::vec3(0.0f));
  for (size_t i = 0; i + 2 < p->indices.size(); i += 3) {
    const uint32_t a = p->indices[i], b = p->indices[i + 1], c = p->indices[i + 2];
    const glm::vec3 e1 = p->positions[b] - p->positions[a], e2 = p->positions[c] - p->positions[a];
    const glm::vec2 d1 = uvs[b] - uvs[a], d2 = uvs[c] - uvs[a];
    const float det = d1.x * d2.y - d2.x * d1.y;
    if (!(std::abs(det) > 1e-20f)) continue;
    const glm::vec3 du = (e1 * d2.y - e2 * d1.y) / det;  // dp/du
    const glm::vec3 dv = (e2 * d1.x - e1 * d2.x) / det;  // dp/dv
    const float du_len = glm::length(du), dv_len = glm::length(dv);
    const float area = glm::length(glm::cross(e1, e2));
    if (!(du_len > 0.0f && dv_len > 0.0f) || !std::isfinite(du_len + dv_len + area)) continue;
    for (const uint32_t v : {a, b, c}) {
      along_u[v] += du * (area / du_len);
      along_v[v] += dv * (area / dv_len);
    }
  }
  p->tangents.resize(n);
  for (size_t v = 0; v < n; ++v) {
    const glm::vec3& normal = p->normals[v];
    glm::vec3 t = along_u[v] - normal * glm::dot(normal, along_u[v]);
    const float len = glm::length(t);
    if (len > 1e-20f && std::isfinite(len)) {
      t /= len;
    } else {  // any direction in the surface
      const glm::vec3 other =
          std::abs(normal.x) < 0.9f ? glm::vec3(1.0f, 0.0f, 0.0f) : glm::vec3(0.0f, 1.0f, 0.0f);
      t = glm::normalize(glm::cross(other, normal));
    }
    const float w = glm::dot(glm::cross(normal, t), along_v[v]) > 0.0f ? -1.0f : 1.0f;
    p->tangents[v] = glm::vec4(t, w);
  }
  p->tangent_set = uv_set;
}

// ---------------------------------------------------------------------------------------------
// Validation and derived data

namespace {

bool finite3(const glm::vec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

}  // namespace

namespace {

// The most vertex updates (Scene::finalize, deformation_work_) one deformation of the displayed
// scene may take: about 1 s of a tracer's set_time.
constexpr size_t kMaxDeformationWork = size_t(1) << 24;

}  // namespace

void Scene::finalize() {
  for (Texture& t : textures) t.build_mips();
  const auto err = [&](const std::string& what) {
    return Error(fmt::format("{}: {}", source, what));
  };
  const auto in_range = [](int i, size_t n) { return i >= 0 && size_t(i) < n; };
  // Morph targets and skinning data of one primitive of a mesh with `target_count` targets.
  const auto check_deformation = [&](const Primitive& p, size_t target_count,
                                     const std::string& where) {
    const size_t vertices = p.positions.size();
    if (p.targets.size() != target_count) {
      throw err(fmt::format("{}: {} morph targets, but the mesh has {} morph weights", where,
                            p.targets.size(), target_count));
    }
    for (size_t k = 0; k < p.targets.size(); ++k) {
      const MorphTarget& target = p.targets[k];
      for (const auto* deltas : {&target.positions, &target.normals, &target.tangents}) {
        const char* what = deltas == &target.positions ? "position"
                           : deltas == &target.normals ? "normal"
                                                       : "tangent";
        if (!deltas->empty() && deltas->size() != vertices) {
          throw err(fmt::format("{}: morph target {} has {} {} displacements for {} vertices",
                                where, k, deltas->size(), what, vertices));
        }
        for (const glm::vec3& d : *deltas) {
          if (!finite3(d)) {
            throw err(fmt::format("{}: morph target {} has a {} displacement that is not finite",
                                  where, k, what));
          }
        }
      }
    }
    if (p.joints.size() != p.joint_weights.size() ||
        (!p.joints.empty() && p.joints.size() != vertices)) {
      throw err(fmt::format("{}: {} joints and {} joint weights for {} vertices", where,
                            p.joints.size(), p.joint_weights.size(), vertices));
    }
    for (size_t v = 0; v < p.joint_weights.size(); ++v) {
      const glm::vec4& w = p.joint_weights[v];
      const bool ok = std::isfinite(w.x) && std::isfinite(w.y) && std::isfinite(w.z) &&
                      std::isfinite(w.w) && w.x >= 0.0f && w.y >= 0.0f && w.z >= 0.0f &&
                      w.w >= 0.0f && w.x + w.y + w.z + w.w > 0.0f;
      if (!ok) {
        throw err(fmt::format(
            "{}: the joint weights of vertex {} ({}, {}, {}, {}) are not >= 0 with a positive sum",
            where, v, w.x, w.y, w.z, w.w));
      }
    }
  };
  // A node's skin and morph weights against its mesh. `largest_joint`: per mesh, the largest
  // joint index its primitives name.
  std::vector<int> largest_joint;
  const auto check_node_deformation = [&](int i) {
    const Node& n = nodes[i];
    const std::string where = fmt::format("node {} ('{}')", i, n.name);
    if (n.skin != -1) {
      if (n.mesh == -1) throw err(fmt::format("{} has skin {} but no mesh", where, n.skin));
      const Skin& skin = skins[n.skin];
      const Mesh& mesh = meshes[n.mesh];
      for (size_t pi = 0; pi < mesh.primitives.size(); ++pi) {
        const Primitive& p = mesh.primitives[pi];
        if (p.joints.empty()) {
          throw err(fmt::format("{} has skin {}, but primitive {} of its mesh {} has no joints",
                                where, n.skin, pi, n.mesh));
        }
        // Many nodes may show one large mesh: its vertices are scanned only when its largest
        // joint index (found once, below) is out of this skin's range.
        if (size_t(largest_joint[size_t(n.mesh)]) < skin.joints.size()) continue;
        for (size_t v = 0; v < p.joints.size(); ++v) {
          for (uint16_t j : p.joints[v]) {
            if (j >= skin.joints.size()) {
              throw err(fmt::format(
                  "{}: vertex {} of primitive {} of mesh {} names joint {}, but skin {} has {} "
                  "joints",
                  where, v, pi, n.mesh, j, n.skin, skin.joints.size()));
            }
          }
        }
      }
    }
    if (!n.weights.empty()) {
      const size_t targets = n.mesh == -1 ? 0 : meshes[n.mesh].weights.size();
      if (n.mesh == -1) throw err(where + " has morph weights but no mesh");
      if (n.weights.size() != targets) {
        throw err(fmt::format("{} has {} morph weights, but its mesh has {} morph targets", where,
                              n.weights.size(), targets));
      }
      for (float w : n.weights) {
        if (!std::isfinite(w)) throw err(where + " has a morph weight that is not finite");
      }
    }
  };

  for (size_t t = 0; t < textures.size(); ++t) {
    const Texture& tex = textures[t];
    if (!tex.texels.empty() && !tex.codes.empty()) {
      throw err(fmt::format("texture {} ('{}') has both texels and codes", t, tex.name));
    }
    if (!tex.whole()) {
      throw err(fmt::format("texture {} ('{}') has {} texels for {}x{}", t, tex.name,
                            tex.texel_count(), tex.width, tex.height));
    }
    if (!tex.alpha.empty() && tex.alpha.size() != tex.texels.size()) {
      throw err(fmt::format("texture {} ('{}') has {} alpha values for {} texels", t, tex.name,
                            tex.alpha.size(), tex.texels.size()));
    }
    for (float a : tex.alpha) {
      if (!(a >= 0.0f && a <= 1.0f)) {
        throw err(fmt::format("texture {} ('{}') has an alpha outside [0, 1]", t, tex.name));
      }
    }
  }
  for (size_t m = 0; m < materials.size(); ++m) {
    const Material& mat = materials[m];
    for (const int t :
         {mat.base_color_texture, mat.metallic_roughness_texture, mat.emissive_texture,
          mat.occlusion_texture, mat.normal_texture, mat.transmission_texture, mat.specular_texture,
          mat.specular_color_texture, mat.clearcoat_texture, mat.clearcoat_roughness_texture,
          mat.clearcoat_normal_texture, mat.sheen_color_texture, mat.sheen_roughness_texture,
          mat.anisotropy_texture, mat.glossiness_texture, mat.iridescence_texture,
          mat.iridescence_thickness_texture, mat.diffuse_transmission_texture,
          mat.diffuse_transmission_color_texture}) {
      if (t != -1 && !in_range(t, textures.size())) {
        throw err(fmt::format("material {} ('{}') names texture {} of {}", m, mat.name, t,
                              textures.size()));
      }
    }
    if (!std::isfinite(mat.normal_scale) || !std::isfinite(mat.clearcoat_normal_scale)) {
      throw err(
          fmt::format("material {} ('{}') has a normal scale that is not finite", m, mat.name));
    }
    if (!(mat.alpha_cutoff >= 0.0f && std::isfinite(mat.alpha_cutoff))) {
      throw err(fmt::format("material {} ('{}') has alpha cutoff {} (a number >= 0)", m, mat.name,
                            mat.alpha_cutoff));
    }
    if (!std::isfinite(mat.anisotropy_rotation)) {
      throw err(fmt::format("material {} ('{}') has an anisotropy rotation that is not finite", m,
                            mat.name));
    }
    if (!(mat.occlusion_strength >= 0.0f && mat.occlusion_strength <= 1.0f)) {
      throw err(fmt::format("material {} ('{}') has occlusion strength {} (0 to 1)", m, mat.name,
                            mat.occlusion_strength));
    }
  }
  mesh_lo_.assign(meshes.size(), glm::vec3(std::numeric_limits<float>::max()));
  mesh_hi_.assign(meshes.size(), glm::vec3(std::numeric_limits<float>::lowest()));
  for (size_t m = 0; m < meshes.size(); ++m) {
    for (size_t pi = 0; pi < meshes[m].primitives.size(); ++pi) {
      Primitive& p = meshes[m].primitives[pi];
      const std::string where = fmt::format("mesh {} ('{}') primitive {}", m, meshes[m].name, pi);
      if (p.indices.size() % 3 != 0) {
        throw err(fmt::format("{}: {} indices is not a multiple of 3", where, p.indices.size()));
      }
      for (uint32_t i : p.indices) {
        if (i >= p.positions.size()) {
          throw err(fmt::format("{}: index {} out of range of {} vertices", where, i,
                                p.positions.size()));
        }
      }
      for (const glm::vec3& v : p.positions) {
        if (!finite3(v)) throw err(fmt::format("{}: a vertex position is not finite", where));
        mesh_lo_[m] = glm::min(mesh_lo_[m], v);
        mesh_hi_[m] = glm::max(mesh_hi_[m], v);
      }
      for (size_t k = 0; k <= p.more_uvs.size(); ++k) {
        const std::vector<glm::vec2>& uvs = p.uv_set(int(k));
        if (!uvs.empty() && uvs.size() != p.positions.size()) {
          throw err(fmt::format("{}: {} uvs in set {} for {} vertices", where, uvs.size(), k,
                                p.positions.size()));
        }
      }
      if (!p.colors.empty() && p.colors.size() != p.positions.size()) {
        throw err(fmt::format("{}: {} vertex colors for {} vertices", where, p.colors.size(),
                              p.positions.size()));
      }
      for (const glm::vec3& c : p.colors) {
        if (!finite3(c) || c.x < 0.0f || c.y < 0.0f || c.z < 0.0f) {
          throw err(fmt::format("{}: a vertex color is negative or not finite", where));
        }
      }
      if (!p.tangents.empty() && p.tangents.size() != p.positions.size()) {
        throw err(fmt::format("{}: {} tangents for {} vertices", where, p.tangents.size(),
                              p.positions.size()));
      }
      for (const glm::vec4& t : p.tangents) {
        if (!finite3(glm::vec3(t)) || (t.w != 1.0f && t.w != -1.0f)) {
          throw err(fmt::format("{}: a tangent is not finite or its w is not +1 or -1", where));
        }
      }
      if (!p.color_alpha.empty() && p.color_alpha.size() != p.positions.size()) {
        throw err(fmt::format("{}: {} vertex alphas for {} vertices", where, p.color_alpha.size(),
                              p.positions.size()));
      }
      for (const float a : p.color_alpha) {
        if (!(a >= 0.0f && a <= 1.0f)) {
          throw err(fmt::format("{}: a vertex alpha is outside 0 to 1", where));
        }
      }
      if (p.normals.size() != p.positions.size()) {
        if (!p.normals.empty()) {
          throw err(fmt::format("{}: {} normals for {} vertices", where, p.normals.size(),
                                p.positions.size()));
        }
        generate_normals(&p);
      }
      if (p.material != -1 && !in_range(p.material, materials.size())) {
        throw err(fmt::format("{}: material {} of {}", where, p.material, materials.size()));
      }
      check_deformation(p, meshes[m].weights.size(), where);
    }
    for (size_t k = 0; k < meshes[m].weights.size(); ++k) {
      if (!std::isfinite(meshes[m].weights[k])) {
        throw err(
            fmt::format("mesh {} ('{}'): morph weight {} is not finite", m, meshes[m].name, k));
      }
    }
  }
  for (size_t k = 0; k < skins.size(); ++k) {
    const Skin& skin = skins[k];
    const std::string where = fmt::format("skin {} ('{}')", k, skin.name);
    if (skin.joints.empty()) throw err(where + " has no joints");
    if (skin.inverse_bind_matrices.size() != skin.joints.size()) {
      throw err(fmt::format("{} has {} inverse bind matrices for {} joints", where,
                            skin.inverse_bind_matrices.size(), skin.joints.size()));
    }
    for (size_t j = 0; j < skin.joints.size(); ++j) {
      if (!in_range(skin.joints[j], nodes.size())) {
        throw err(
            fmt::format("{}: joint {} is node {} of {}", where, j, skin.joints[j], nodes.size()));
      }
      const glm::dmat4& ibm = skin.inverse_bind_matrices[j];
      for (int c = 0; c < 4; ++c) {
        for (int r = 0; r < 4; ++r) {
          if (!std::isfinite(ibm[c][r])) {
            throw err(fmt::format("{}: inverse bind matrix {} is not finite", where, j));
          }
        }
      }
    }
    if (skin.skeleton != -1 && !in_range(skin.skeleton, nodes.size())) {
      throw err(fmt::format("{}: skeleton is node {} of {}", where, skin.skeleton, nodes.size()));
    }
  }

  largest_joint.assign(meshes.size(), -1);
  for (size_t m = 0; m < meshes.size(); ++m) {
    for (const Primitive& p : meshes[m].primitives) {
      for (const std::array<uint16_t, 4>& j : p.joints) {
        largest_joint[m] = std::max({largest_joint[m], int(j[0]), int(j[1]), int(j[2]), int(j[3])});
      }
    }
  }

  // Node graph: children define parents; every node has at most one parent and no cycles.
  for (Node& n : nodes) n.parent = -1;
  for (size_t i = 0; i < nodes.size(); ++i) {
    const Node& n = nodes[i];
    const auto check_ref = [&](int ref, size_t count, const char* kind) {
      if (ref != -1 && !in_range(ref, count)) {
        throw err(fmt::format("node {} ('{}') names {} {} of {}", i, n.name, kind, ref, count));
      }
    };
    check_ref(n.mesh, meshes.size(), "mesh");
    check_ref(n.camera, cameras.size(), "camera");
    check_ref(n.light, lights.size(), "light");
    check_ref(n.skin, skins.size(), "skin");
    check_node_deformation(int(i));
    for (int c : n.children) {
      if (!in_range(c, nodes.size())) {
        throw err(fmt::format("node {} ('{}') has child {} of {}", i, n.name, c, nodes.size()));
      }
      if (nodes[c].parent != -1 || size_t(c) == i) {
        throw err(
            fmt::format("node {} has more than one parent (the node graph is not a tree)", c));
      }
      nodes[c].parent = int(i);
    }
  }
  order_.clear();
  for (size_t i = 0; i < nodes.size(); ++i) {
    if (nodes[i].parent == -1) order_.push_back(int(i));
  }
  for (size_t k = 0; k < order_.size(); ++k) {
    for (int c : nodes[order_[k]].children) order_.push_back(c);
  }
  if (order_.size() != nodes.size()) {
    throw err("the node graph has a cycle");
  }
  if (roots.empty()) {
    for (size_t i = 0; i < nodes.size(); ++i) {
      if (nodes[i].parent == -1) roots.push_back(int(i));
    }
  }
  scene_nodes_.clear();
  for (int r : roots) {
    if (!in_range(r, nodes.size())) {
      throw err(fmt::format("scene root {} of {} nodes", r, nodes.size()));
    }
    if (nodes[r].parent != -1) throw err(fmt::format("scene root {} has a parent", r));
    scene_nodes_.push_back(r);
  }
  for (size_t k = 0; k < scene_nodes_.size(); ++k) {
    for (int c : nodes[scene_nodes_[k]].children) scene_nodes_.push_back(c);
  }

  // Channels, grouped by node.
  channel_start_.assign(nodes.size() + 1, 0);
  duration_ = 0.0;
  for (size_t c = 0; c < channels.size(); ++c) {
    const AnimationChannel& ch = channels[c];
    if (!in_range(ch.node, nodes.size())) {
      throw err(
          fmt::format("animation channel {} targets node {} of {}", c, ch.node, nodes.size()));
    }
    ch.validate(fmt::format("{}: animation channel {} ({} of node {})", source, c,
                            to_string(ch.path), ch.node));
    if (ch.path == AnimatedPath::kWeights) {
      const Node& n = nodes[ch.node];
      const size_t targets = n.mesh == -1 ? 0 : meshes[n.mesh].weights.size();
      if (targets == 0) {
        throw err(fmt::format(
            "animation channel {} animates the morph weights of node {} ('{}'), whose {}", c,
            ch.node, n.name, n.mesh == -1 ? "has no mesh" : "mesh has no morph targets"));
      }
      if (ch.weight_count != targets) {
        throw err(fmt::format(
            "animation channel {} animates {} morph weights of node {} ('{}'), whose mesh has {} "
            "morph targets",
            c, ch.weight_count, ch.node, n.name, targets));
      }
    } else if (nodes[ch.node].matrix) {
      throw err(fmt::format("node {} ('{}') is animated but given as a matrix", ch.node,
                            nodes[ch.node].name));
    }
    channel_start_[ch.node + 1]++;
    duration_ = std::max(duration_, ch.end_time());
  }
  for (size_t i = 0; i < nodes.size(); ++i) channel_start_[i + 1] += channel_start_[i];
  finalize_property_channels();
  channel_index_.assign(channels.size(), 0);
  {
    std::vector<uint32_t> fill(channel_start_.begin(), channel_start_.end() - 1);
    for (size_t c = 0; c < channels.size(); ++c) channel_index_[fill[channels[c].node]++] = c;
  }

  // A node moves when a channel drives its transform (a weights channel does not) or its
  // parent moves.
  std::vector<char> weights_animated(nodes.size(), 0);
  std::vector<char> transform_animated(nodes.size(), 0);
  for (const AnimationChannel& ch : channels) {
    (ch.path == AnimatedPath::kWeights ? weights_animated : transform_animated)[ch.node] = 1;
  }
  node_moves_.assign(nodes.size(), 0);
  for (int i : order_) {
    const Node& n = nodes[i];
    node_moves_[i] = transform_animated[i] || (n.parent != -1 && node_moves_[n.parent]);
  }
  // Likewise a node's visibility varies when a channel drives it or its parent's.
  std::vector<char> visibility_animated(nodes.size(), 0);
  for (const PropertyChannel& pc : property_channels) {
    if (is_node_property(pc.property)) visibility_animated[size_t(pc.index)] = 1;
  }
  visibility_varies_.assign(nodes.size(), 0);
  visibility_used_ = false;
  for (int i : order_) {
    const Node& n = nodes[i];
    visibility_varies_[i] =
        visibility_animated[i] || (n.parent != -1 && visibility_varies_[n.parent]);
    visibility_used_ = visibility_used_ || visibility_animated[i] || !n.visible;
  }

  // Deformation: which nodes deform and move, where each node's morph weights and each skin's
  // joint matrices go in a SceneState.
  node_deforms_.assign(nodes.size(), 0);
  node_geometry_moves_.assign(nodes.size(), 0);
  weight_start_.assign(nodes.size() + 1, 0);
  default_weights_.clear();
  for (size_t i = 0; i < nodes.size(); ++i) {
    const Node& n = nodes[i];
    weight_start_[i] = default_weights_.size();
    if (n.mesh == -1) continue;
    const Mesh& mesh = meshes[n.mesh];
    const bool morphed = !mesh.weights.empty();
    node_deforms_[i] = n.skin != -1 || morphed;
    bool moves = n.skin == -1 && node_moves_[i];
    if (n.skin != -1) {
      for (int joint : skins[n.skin].joints) moves = moves || node_moves_[joint];
    }
    node_geometry_moves_[i] = moves || (morphed && weights_animated[i]);
    if (morphed) {
      const std::vector<float>& w = n.weights.empty() ? mesh.weights : n.weights;
      default_weights_.insert(default_weights_.end(), w.begin(), w.end());
    }
  }
  weight_start_[nodes.size()] = default_weights_.size();
  skin_start_.assign(skins.size() + 1, 0);
  for (size_t k = 0; k < skins.size(); ++k) {
    skin_start_[k + 1] = skin_start_[k] + skins[k].joints.size();
  }
  joint_matrix_count_ = skin_start_[skins.size()];

  // What deforming the displayed scene takes at one time: a vertex update for each deformed
  // vertex of each node, and one more for each morph target that moves it. Bounded, so that a
  // small file cannot ask for an endless deformation (many nodes showing one large mesh).
  deformation_work_ = 0;
  for (int i : scene_nodes_) {
    if (!node_deforms_[i]) continue;
    for (const Primitive& p : meshes[nodes[i].mesh].primitives) {
      size_t targets = 0;
      for (const MorphTarget& t : p.targets) targets += t.positions.empty() ? 0 : 1;
      deformation_work_ += p.positions.size() * (1 + targets);
    }
  }
  if (deformation_work_ > kMaxDeformationWork) {
    throw err(fmt::format(
        "the scene deforms {} vertices at every time (counting a vertex once more for each morph "
        "target that moves it, and once for each node that shows it), more than afr accepts ({})",
        deformation_work_, kMaxDeformationWork));
  }

  has_moving_geometry_ = false;
  camera_node_ = -1;
  for (int i : scene_nodes_) {
    if (nodes[i].mesh != -1 && node_geometry_moves_[i]) has_moving_geometry_ = true;
    if (nodes[i].camera != -1 && camera_node_ == -1) camera_node_ = i;
  }
  if (camera_node_ == -1) frame_default_camera();
}

// Checks each property channel's target and curve, and notes which kinds and materials they
// animate.
void Scene::finalize_property_channels() {
  animated_materials_.clear();
  lights_animated_ = cameras_animated_ = false;
  for (size_t c = 0; c < property_channels.size(); ++c) {
    const PropertyChannel& pc = property_channels[c];
    const bool light = is_light_property(pc.property), camera = is_camera_property(pc.property);
    const bool node = is_node_property(pc.property);
    const size_t count = light    ? lights.size()
                         : camera ? cameras.size()
                         : node   ? nodes.size()
                                  : materials.size();
    const char* kind = light ? "light" : camera ? "camera" : node ? "node" : "material";
    const std::string what = fmt::format("{}: property channel {} ({} of {} {})", source, c,
                                         to_string(pc.property), kind, pc.index);
    if (pc.index < 0 || size_t(pc.index) >= count) {
      throw Error(fmt::format("{}: there are {} {}s", what, count, kind));
    }
    if (is_uv_property(pc.property) &&
        (pc.uv_set < 0 || size_t(pc.uv_set) >= materials[size_t(pc.index)].uv_transforms.size())) {
      throw Error(fmt::format("{}: the material has no animated texture coordinate set {}", what,
                              pc.uv_set));
    }
    pc.curve.validate(what);
    duration_ = std::max(duration_, pc.curve.end_time());
    lights_animated_ |= light;
    cameras_animated_ |= camera;
    if (!light && !camera && !node) animated_materials_.push_back(pc.index);
  }
  std::sort(animated_materials_.begin(), animated_materials_.end());
  animated_materials_.erase(std::unique(animated_materials_.begin(), animated_materials_.end()),
                            animated_materials_.end());
}

// ---------------------------------------------------------------------------------------------
// The default camera

namespace {

// At most this many instants of the animation are evaluated to frame it (a scene with more
// distinct keyframe times is sampled evenly over them).
constexpr size_t kMaxFramingTimes = 4096;
// Framing a deforming mesh deforms all its vertices at every instant: fewer instants (at least
// 0 s and one more) when that would take more than this many vertex updates in all
// (deformation_work_ at each).
constexpr size_t kMaxFramingWork = size_t(1) << 25;
constexpr size_t kMinFramingTimes = 2;

}  // namespace

void Scene::frame_default_camera() {
  // The times at which the animation is framed: 0 and every keyframe time. Between keys a
  // LINEAR channel stays inside its keys' hull; STEP takes a key's value; only a CUBICSPLINE
  // overshoot may leave the frame a little.
  std::vector<double> times = {0.0};
  for (const AnimationChannel& ch : channels) {
    times.insert(times.end(), ch.times.begin(), ch.times.end());
  }
  std::sort(times.begin(), times.end());
  times.erase(std::unique(times.begin(), times.end()), times.end());
  const size_t max_times = deformation_work_ == 0 ? kMaxFramingTimes
                                                  : std::clamp(kMaxFramingWork / deformation_work_,
                                                               kMinFramingTimes, kMaxFramingTimes);
  if (times.size() > max_times) {
    std::vector<double> picked(max_times);
    for (size_t k = 0; k < max_times; ++k) {
      picked[k] = times[k * (times.size() - 1) / (max_times - 1)];
    }
    times = std::move(picked);
  }
  glm::dvec3 lo(std::numeric_limits<double>::max());
  glm::dvec3 hi(std::numeric_limits<double>::lowest());
  SceneState state;
  for (double t : times) {
    glm::dvec3 l, h;
    evaluate(t, &state);
    bounds(state, &l, &h);
    lo = glm::min(lo, l);
    hi = glm::max(hi, h);
  }

  // Look at the bounds from +Z, far enough to see them whole. Lengths are relative to the
  // scene's own size, so that a scene in micrometres is framed as one in metres (an absolute
  // floor of 1e-3 made it a dot in the middle of the view). Only a scene of one point (or
  // none) gets a size from where it is.
  const glm::dvec3 center = 0.5 * (lo + hi);
  const glm::dvec3 size = hi - lo;
  const double extent = 0.5 * glm::length(size);
  const double radius = extent > 0.0 ? extent : std::max(1e-3 * glm::length(center), 1e-3);
  const double yfov = 0.8;
  const double distance = radius / std::sin(0.5 * yfov);
  // A scene flat in y (a ground, a terrain, a plane lying in xz) or in x would be seen edge on
  // from +Z, as nothing: it is looked at from 45 degrees above (or beside) instead.
  const double flat = 1e-3 * std::max({size.x, size.y, size.z});
  const glm::dvec3 from =
      glm::normalize(glm::dvec3(size.x <= flat ? 1.0 : 0.0, size.y <= flat ? 1.0 : 0.0, 1.0));
  default_camera_ = Camera::look_at(center + distance * from, center, glm::dvec3(0.0, 1.0, 0.0),
                                    yfov, (distance - radius) * 0.1);
}

// ---------------------------------------------------------------------------------------------
// Evaluation at a time

void Scene::evaluate(double t, SceneState* state) const {
  state->time = t;
  state->world.resize(nodes.size());
  state->morph_weights = default_weights_;  // keeps its capacity: no allocation once sized
  for (int i : order_) {
    const Node& n = nodes[i];
    glm::dmat4 local;
    if (n.matrix) {
      local = *n.matrix;
    } else {
      glm::dvec3 translation = n.translation;
      glm::dquat rotation = n.rotation;
      glm::dvec3 scale = n.scale;
      for (uint32_t k = channel_start_[i]; k < channel_start_[i + 1]; ++k) {
        const AnimationChannel& ch = channels[channel_index_[k]];
        if (ch.path == AnimatedPath::kWeights) continue;  // below
        const glm::dvec4 v = ch.evaluate(t);
        switch (ch.path) {
          case AnimatedPath::kTranslation:
            translation = glm::dvec3(v);
            break;
          case AnimatedPath::kRotation:
            rotation = glm::dquat(v.w, v.x, v.y, v.z);
            break;
          case AnimatedPath::kScale:
            scale = glm::dvec3(v);
            break;
          case AnimatedPath::kWeights:
            break;
        }
      }
      local = compose_trs(translation, rotation, scale);
    }
    state->world[i] = n.parent == -1 ? local : state->world[n.parent] * local;
  }
  evaluate_properties(t, state);
  // Weights channels may drive nodes given as a matrix too: a loop of their own.
  for (const AnimationChannel& ch : channels) {
    if (ch.path == AnimatedPath::kWeights) {
      ch.evaluate_weights(t, &state->morph_weights[weight_start_[ch.node]]);
    }
  }
  state->joint_matrices.resize(joint_matrix_count_);
  for (size_t k = 0; k < skins.size(); ++k) {
    const Skin& skin = skins[k];
    for (size_t j = 0; j < skin.joints.size(); ++j) {
      state->joint_matrices[skin_start_[k] + j] =
          glm::mat4x3(state->world[skin.joints[j]] * skin.inverse_bind_matrices[j]);
    }
  }
}

namespace {

// A property's value as the renderer may use it: a cubic spline may overshoot its keys (the
// loader checks each key against the same ranges).
// A visibility channel's value at time t: each key's holds from its time to the next (the
// first's before it), whatever the channel's interpolation, since a visibility does not blend;
// visible where it is not 0.
bool visible_key(const PropertyChannel& pc, double t) {
  const AnimationChannel& c = pc.curve;
  const size_t after =
      size_t(std::upper_bound(c.times.begin(), c.times.end(), t) - c.times.begin());
  const size_t key = after == 0 ? 0 : after - 1;
  const bool cubic = c.interpolation == Interpolation::kCubicSpline;
  return c.values[cubic ? 3 * key + 1 : key].x != 0.0;
}

void apply(AnimatedProperty property, const glm::dvec4& v, Light* light, CameraModel* camera,
           Material* material, int uv_set) {
  const float x = float(v.x);
  switch (property) {
    case AnimatedProperty::kLightColor:
      light->color = glm::max(glm::vec3(v), glm::vec3(0.0f));
      break;
    case AnimatedProperty::kLightIntensity:
      light->intensity = std::max(x, 0.0f);
      break;
    case AnimatedProperty::kLightRange:
      light->range = std::max(x, 1e-6f);  // 0 would mean no range at all
      break;
    case AnimatedProperty::kLightInnerCone:
      light->inner_cone_angle = std::clamp(x, 0.0f, float(0.5 * std::numbers::pi));
      break;
    case AnimatedProperty::kLightOuterCone:
      light->outer_cone_angle = std::clamp(x, 0.0f, float(0.5 * std::numbers::pi));
      break;
    case AnimatedProperty::kCameraYfov:
      camera->yfov = std::clamp(v.x, 1e-6, std::numbers::pi - 1e-6);
      break;
    case AnimatedProperty::kCameraZnear:
      camera->znear = std::max(v.x, 1e-9);
      break;
    case AnimatedProperty::kCameraYmag:
      // Only an orthographic camera's (a perspective one stays perspective).
      if (camera->ymag > 0.0) camera->ymag = std::max(std::abs(v.x), 1e-12);
      break;
    case AnimatedProperty::kBaseColorFactor:
      material->base_color_factor = glm::clamp(glm::vec4(v), glm::vec4(0.0f), glm::vec4(1.0f));
      break;
    case AnimatedProperty::kMetallicFactor:
      material->metallic = std::clamp(x, 0.0f, 1.0f);
      break;
    case AnimatedProperty::kRoughnessFactor:
      material->roughness = std::clamp(x, 0.0f, 1.0f);
      break;
    case AnimatedProperty::kEmissiveFactor:
      material->emissive_factor = glm::max(glm::vec3(v), glm::vec3(0.0f));
      material->emissive = material->emissive_factor * material->emissive_strength;
      break;
    case AnimatedProperty::kEmissiveStrength:
      material->emissive_strength = std::max(x, 0.0f);
      material->emissive = material->emissive_factor * material->emissive_strength;
      break;
    case AnimatedProperty::kAlphaCutoff:
      material->alpha_cutoff = std::max(x, 0.0f);
      break;
    case AnimatedProperty::kNormalScale:
      material->normal_scale = x;
      break;
    case AnimatedProperty::kOcclusionStrength:
      material->occlusion_strength = std::clamp(x, 0.0f, 1.0f);
      break;
    case AnimatedProperty::kClearcoatFactor:
      material->clearcoat = std::clamp(x, 0.0f, 1.0f);
      break;
    case AnimatedProperty::kClearcoatRoughnessFactor:
      material->clearcoat_roughness = std::clamp(x, 0.0f, 1.0f);
      break;
    case AnimatedProperty::kSheenColorFactor:
      material->sheen_color = glm::clamp(glm::vec3(v), glm::vec3(0.0f), glm::vec3(1.0f));
      break;
    case AnimatedProperty::kSheenRoughnessFactor:
      material->sheen_roughness = std::clamp(x, 0.0f, 1.0f);
      break;
    case AnimatedProperty::kSpecularFactor:
      material->specular = std::clamp(x, 0.0f, 1.0f);
      break;
    case AnimatedProperty::kSpecularColorFactor:
      material->specular_color = glm::max(glm::vec3(v), glm::vec3(0.0f));
      break;
    case AnimatedProperty::kIridescenceFactor:
      material->iridescence = std::clamp(x, 0.0f, 1.0f);
      break;
    case AnimatedProperty::kIridescenceIor:
      material->iridescence_ior = std::max(x, 1.0f);
      break;
    case AnimatedProperty::kIridescenceThicknessMinimum:
      material->iridescence_thickness_min = std::max(x, 0.0f);
      break;
    case AnimatedProperty::kIridescenceThicknessMaximum:
      material->iridescence_thickness_max = std::max(x, 0.0f);
      break;
    case AnimatedProperty::kAnisotropyStrength:
      material->anisotropy = std::clamp(x, 0.0f, 1.0f);
      break;
    case AnimatedProperty::kAnisotropyRotation:
      material->anisotropy_rotation = x;
      break;
    case AnimatedProperty::kTransmissionFactor:
      material->transmission = std::clamp(x, 0.0f, 1.0f);
      break;
    case AnimatedProperty::kIor:
      material->ior = std::max(x, 1.0f);
      break;
    case AnimatedProperty::kThicknessFactor:
      material->thickness = std::max(x, 0.0f);
      break;
    case AnimatedProperty::kAttenuationDistance:
      // A cubic spline may overshoot below its keys (all > 0): a tiny distance absorbs all.
      material->attenuation_distance = std::max(x, 1e-30f);
      break;
    case AnimatedProperty::kAttenuationColor:
      material->attenuation_color = glm::clamp(glm::vec3(v), glm::vec3(0.0f), glm::vec3(1.0f));
      break;
    case AnimatedProperty::kDispersion:
      material->dispersion = std::max(x, 0.0f);
      break;
    case AnimatedProperty::kDiffuseTransmissionFactor:
      material->diffuse_transmission = std::clamp(x, 0.0f, 1.0f);
      break;
    case AnimatedProperty::kDiffuseTransmissionColor:
      material->diffuse_transmission_color =
          glm::clamp(glm::vec3(v), glm::vec3(0.0f), glm::vec3(1.0f));
      break;
    case AnimatedProperty::kUvOffset:
      material->uv_transforms[size_t(uv_set)].offset = glm::dvec2(v);
      break;
    case AnimatedProperty::kUvRotation:
      material->uv_transforms[size_t(uv_set)].rotation = v.x;
      break;
    case AnimatedProperty::kUvScale:
      material->uv_transforms[size_t(uv_set)].scale = glm::dvec2(v);
      break;
    case AnimatedProperty::kNodeVisible:
      break;  // evaluate_properties
  }
}

}  // namespace

void Scene::evaluate_properties(double t, SceneState* state) const {
  if (lights_animated_) state->lights = lights;
  if (cameras_animated_) state->cameras = cameras;
  if (!animated_materials_.empty()) state->materials = materials;
  state->hidden.clear();
  if (visibility_used_) {
    // Each node's own visibility, then its ancestors' hiding it.
    state->hidden.resize(nodes.size());
    for (size_t i = 0; i < nodes.size(); ++i) state->hidden[i] = !nodes[i].visible;
    for (const PropertyChannel& pc : property_channels) {
      if (is_node_property(pc.property))
        state->hidden[size_t(pc.index)] = visible_key(pc, t) ? 0 : 1;
    }
    for (int i : order_) {
      const int parent = nodes[size_t(i)].parent;
      if (parent != -1 && state->hidden[size_t(parent)]) state->hidden[size_t(i)] = 1;
    }
  }
  for (const PropertyChannel& pc : property_channels) {
    if (is_node_property(pc.property)) continue;
    const size_t i = size_t(pc.index);
    const bool light = is_light_property(pc.property), camera = is_camera_property(pc.property);
    apply(pc.property, pc.curve.evaluate(t), light ? &state->lights[i] : nullptr,
          camera ? &state->cameras[i] : nullptr, !light && !camera ? &state->materials[i] : nullptr,
          pc.uv_set);
  }
}

SceneState Scene::evaluate(double t) const {
  SceneState state;
  evaluate(t, &state);
  return state;
}

// ---------------------------------------------------------------------------------------------
// Deformation

namespace {

// Normals under the linear part of a matrix (columns c0, c1, c2): by the inverse transpose, up
// to the positive factor |det|, whose columns are c1 x c2, c2 x c0, c0 x c1 (the cofactors),
// negated where the matrix mirrors so that a normal stays on its side.
struct NormalTransform {
  glm::vec3 x, y, z;

  NormalTransform(const glm::vec3& c0, const glm::vec3& c1, const glm::vec3& c2)
      : x(glm::cross(c1, c2)), y(glm::cross(c2, c0)), z(glm::cross(c0, c1)) {
    if (glm::dot(c0, x) < 0.0f) {
      x = -x;
      y = -y;
      z = -z;
    }
  }
  // Unit length, or zero where the matrix flattens the normal.
  glm::vec3 operator()(const glm::vec3& n) const {
    const glm::vec3 out = n.x * x + n.y * y + n.z * z;
    const float len2 = glm::dot(out, out);
    if (!(len2 > 0.0f) || !(len2 < std::numeric_limits<float>::infinity())) return glm::vec3(0.0f);
    return out * (1.0f / std::sqrt(len2));
  }
};

}  // namespace

void Scene::deform(int node, size_t primitive, const SceneState& state, glm::vec3* positions,
                   glm::vec3* normals, glm::vec4* tangents) const {
  const Node& n = nodes[node];
  const Primitive& p = meshes[n.mesh].primitives[primitive];
  const size_t count = p.positions.size();

  // Morph targets, in the mesh's space (glTF 2.0, 3.7.2.2): base + sum_k w_k target_k.
  const std::span<const float> w = morph_weights(state, node);
  std::copy_n(p.positions.data(), count, positions);
  for (size_t k = 0; k < p.targets.size(); ++k) {
    const std::vector<glm::vec3>& d = p.targets[k].positions;
    if (w[k] == 0.0f || d.empty()) continue;
    for (size_t v = 0; v < count; ++v) positions[v] += w[k] * d[v];
  }
  if (normals != nullptr) {
    if (p.generated_normals && !p.targets.empty()) {
      // Normals the loader made from the base shape would not fit a morphed one.
      sum_triangle_normals(positions, count, p.indices, normals);
    } else {
      std::copy_n(p.normals.data(), count, normals);
      for (size_t k = 0; k < p.targets.size(); ++k) {
        const std::vector<glm::vec3>& d = p.targets[k].normals;
        if (w[k] == 0.0f || d.empty()) continue;
        for (size_t v = 0; v < count; ++v) normals[v] += w[k] * d[v];
      }
    }
  }
  if (p.tangents.size() != count) tangents = nullptr;
  if (tangents != nullptr) {
    std::copy_n(p.tangents.data(), count, tangents);
    for (size_t k = 0; k < p.targets.size(); ++k) {
      const std::vector<glm::vec3>& d = p.targets[k].tangents;
      if (w[k] == 0.0f || d.empty()) continue;
      for (size_t v = 0; v < count; ++v) tangents[v] += glm::vec4(w[k] * d[v], 0.0f);
    }
  }
  // A tangent moves as the surface does (the linear part); a mirroring part turns its w, the
  // bitangent's sign, as it turns the faces (glTF 2.0, 3.7.2.1).
  const auto move_tangent = [](const glm::mat3& linear, glm::vec4* t) {
    const float mirror = glm::determinant(linear) < 0.0f ? -1.0f : 1.0f;
    *t = glm::vec4(linear * glm::vec3(*t), t->w * mirror);
  };

  if (n.skin != -1) {
    // Linear blend skinning (glTF 2.0, 3.7.3): the node's own transform is ignored.
    const glm::mat4x3* joint = &state.joint_matrices[skin_start_[n.skin]];
    for (size_t v = 0; v < count; ++v) {
      const std::array<uint16_t, 4>& j = p.joints[v];
      const glm::vec4& jw = p.joint_weights[v];
      // Most vertices have fewer than four influences: unused slots cost nothing.
      glm::mat4x3 m = jw.x * joint[j[0]];
      if (jw.y != 0.0f) m += jw.y * joint[j[1]];
      if (jw.z != 0.0f) m += jw.z * joint[j[2]];
      if (jw.w != 0.0f) m += jw.w * joint[j[3]];
      positions[v] = m * glm::vec4(positions[v], 1.0f);
      if (normals != nullptr) normals[v] = NormalTransform(m[0], m[1], m[2])(normals[v]);
      if (tangents != nullptr) move_tangent(glm::mat3(m), &tangents[v]);
    }
    return;
  }
  const glm::mat4x3 world(state.world[node]);
  const NormalTransform normal_transform(world[0], world[1], world[2]);
  for (size_t v = 0; v < count; ++v) {
    positions[v] = world * glm::vec4(positions[v], 1.0f);
    if (normals != nullptr) normals[v] = normal_transform(normals[v]);
    if (tangents != nullptr) move_tangent(glm::mat3(world), &tangents[v]);
  }
}

void Scene::bounds(const SceneState& state, glm::dvec3* lo, glm::dvec3* hi) const {
  *lo = glm::dvec3(std::numeric_limits<double>::max());
  *hi = glm::dvec3(std::numeric_limits<double>::lowest());
  std::vector<glm::vec3> deformed;
  for (int i : scene_nodes_) {
    const int m = nodes[i].mesh;
    if (m == -1 || mesh_lo_[m].x > mesh_hi_[m].x) continue;
    if (node_deforms_[i]) {
      // Every vertex where it is at this time: a skin can take them anywhere.
      for (size_t pi = 0; pi < meshes[m].primitives.size(); ++pi) {
        deformed.resize(meshes[m].primitives[pi].positions.size());
        deform(i, pi, state, deformed.data(), nullptr);
        for (const glm::vec3& v : deformed) {
          *lo = glm::min(*lo, glm::dvec3(v));
          *hi = glm::max(*hi, glm::dvec3(v));
        }
      }
      continue;
    }
    for (int corner = 0; corner < 8; ++corner) {
      const glm::dvec3 local((corner & 1) ? mesh_hi_[m].x : mesh_lo_[m].x,
                             (corner & 2) ? mesh_hi_[m].y : mesh_lo_[m].y,
                             (corner & 4) ? mesh_hi_[m].z : mesh_lo_[m].z);
      const glm::dvec3 w(state.world[i] * glm::dvec4(local, 1.0));
      *lo = glm::min(*lo, w);
      *hi = glm::max(*hi, w);
    }
  }
  if (lo->x > hi->x) *lo = *hi = glm::dvec3(0.0);
}

Camera Scene::camera_at(const SceneState& state) const {
  if (camera_node_ == -1) return default_camera_;
  const int index = nodes[camera_node_].camera;
  const CameraModel& model = state.cameras.empty() ? cameras[index] : state.cameras[index];
  Camera camera = Camera::from_transform(state.world[camera_node_], model.yfov, model.znear);
  camera.ymag = model.ymag;
  return camera;
}

size_t Scene::triangle_count() const {
  size_t count = 0;
  for (int i : scene_nodes_) {
    if (nodes[i].mesh == -1) continue;
    for (const Primitive& p : meshes[nodes[i].mesh].primitives) count += p.triangle_count();
  }
  return count;
}

}  // namespace afr
