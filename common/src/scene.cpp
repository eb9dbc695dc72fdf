#include <afr/common/scene.h>

#include <afr/common/error.h>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace afr {

// ---------------------------------------------------------------------------------------------
// Textures

glm::vec3 Texture::sample_bilinear(glm::vec2 uv) const {
  if (width <= 0 || height <= 0) return glm::vec3(1.0f);
  // Keep only the fractional part first (REPEAT), so huge UVs keep their precision.
  double u = std::isfinite(uv.x) ? uv.x - std::floor(double(uv.x)) : 0.0;
  double v = std::isfinite(uv.y) ? uv.y - std::floor(double(uv.y)) : 0.0;
  const double fx = u * width - 0.5;
  const double fy = v * height - 0.5;
  const double x0f = std::floor(fx);
  const double y0f = std::floor(fy);
  const float ax = float(fx - x0f);
  const float ay = float(fy - y0f);
  auto wrap = [](long i, int n) { return int(((i % n) + n) % n); };
  const int x0 = wrap(long(x0f), width), x1 = wrap(long(x0f) + 1, width);
  const int y0 = wrap(long(y0f), height), y1 = wrap(long(y0f) + 1, height);
  auto at = [&](int x, int y) { return texels[size_t(y) * size_t(width) + size_t(x)]; };
  const glm::vec3 top = glm::mix(at(x0, y0), at(x1, y0), ax);
  const glm::vec3 bottom = glm::mix(at(x0, y1), at(x1, y1), ax);
  return glm::mix(top, bottom, ay);
}

// ---------------------------------------------------------------------------------------------
// Normals

void generate_normals(Primitive* p) {
  p->normals.assign(p->positions.size(), glm::vec3(0.0f));
  for (size_t i = 0; i + 2 < p->indices.size(); i += 3) {
    const uint32_t a = p->indices[i], b = p->indices[i + 1], c = p->indices[i + 2];
    // The cross product's length is twice the area: an area-weighted sum.
    const glm::vec3 n =
        glm::cross(p->positions[b] - p->positions[a], p->positions[c] - p->positions[a]);
    if (!std::isfinite(n.x) || !std::isfinite(n.y) || !std::isfinite(n.z)) continue;
    p->normals[a] += n;
    p->normals[b] += n;
    p->normals[c] += n;
  }
  for (glm::vec3& n : p->normals) {
    const float len = glm::length(n);
    n = len > 0.0f && std::isfinite(len) ? n / len : glm::vec3(0.0f, 0.0f, 1.0f);
  }
}

// ---------------------------------------------------------------------------------------------
// Validation and derived data

namespace {

bool finite3(const glm::vec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

}  // namespace

void Scene::finalize() {
  const auto err = [&](const std::string& what) {
    return Error(fmt::format("{}: {}", source, what));
  };
  const auto in_range = [](int i, size_t n) { return i >= 0 && size_t(i) < n; };

  for (size_t t = 0; t < textures.size(); ++t) {
    const Texture& tex = textures[t];
    if (tex.width <= 0 || tex.height <= 0 ||
        tex.texels.size() != size_t(tex.width) * size_t(tex.height)) {
      throw err(fmt::format("texture {} ('{}') has {} texels for {}x{}", t, tex.name,
                            tex.texels.size(), tex.width, tex.height));
    }
  }
  for (size_t m = 0; m < materials.size(); ++m) {
    const Material& mat = materials[m];
    if (mat.base_color_texture != -1 && !in_range(mat.base_color_texture, textures.size())) {
      throw err(fmt::format("material {} ('{}') names texture {} of {}", m, mat.name,
                            mat.base_color_texture, textures.size()));
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
      if (!p.uvs.empty() && p.uvs.size() != p.positions.size()) {
        throw err(
            fmt::format("{}: {} uvs for {} vertices", where, p.uvs.size(), p.positions.size()));
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
    if (nodes[ch.node].matrix) {
      throw err(fmt::format("node {} ('{}') is animated but given as a matrix", ch.node,
                            nodes[ch.node].name));
    }
    channel_start_[ch.node + 1]++;
    duration_ = std::max(duration_, ch.end_time());
  }
  for (size_t i = 0; i < nodes.size(); ++i) channel_start_[i + 1] += channel_start_[i];
  channel_index_.assign(channels.size(), 0);
  {
    std::vector<uint32_t> fill(channel_start_.begin(), channel_start_.end() - 1);
    for (size_t c = 0; c < channels.size(); ++c) channel_index_[fill[channels[c].node]++] = c;
  }

  node_moves_.assign(nodes.size(), 0);
  for (int i : order_) {
    const Node& n = nodes[i];
    node_moves_[i] =
        channel_start_[i + 1] > channel_start_[i] || (n.parent != -1 && node_moves_[n.parent]);
  }
  has_moving_geometry_ = false;
  camera_node_ = -1;
  for (int i : scene_nodes_) {
    if (nodes[i].mesh != -1 && node_moves_[i]) has_moving_geometry_ = true;
    if (nodes[i].camera != -1 && camera_node_ == -1) camera_node_ = i;
  }
  if (camera_node_ == -1) frame_default_camera();
}

// ---------------------------------------------------------------------------------------------
// The default camera

namespace {

// At most this many instants of the animation are evaluated to frame it (a scene with more
// distinct keyframe times is sampled evenly over them).
constexpr size_t kMaxFramingTimes = 4096;

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
  if (times.size() > kMaxFramingTimes) {
    std::vector<double> picked(kMaxFramingTimes);
    for (size_t k = 0; k < kMaxFramingTimes; ++k) {
      picked[k] = times[k * (times.size() - 1) / (kMaxFramingTimes - 1)];
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
  const double extent = 0.5 * glm::length(hi - lo);
  const double radius = extent > 0.0 ? extent : std::max(1e-3 * glm::length(center), 1e-3);
  const double yfov = 0.8;
  const double distance = radius / std::sin(0.5 * yfov);
  default_camera_ = Camera::look_at(center + glm::dvec3(0.0, 0.0, distance), center,
                                    glm::dvec3(0.0, 1.0, 0.0), yfov, (distance - radius) * 0.1);
}

// ---------------------------------------------------------------------------------------------
// Evaluation at a time

void Scene::evaluate(double t, SceneState* state) const {
  state->time = t;
  state->world.resize(nodes.size());
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
        }
      }
      local = compose_trs(translation, rotation, scale);
    }
    state->world[i] = n.parent == -1 ? local : state->world[n.parent] * local;
  }
}

SceneState Scene::evaluate(double t) const {
  SceneState state;
  evaluate(t, &state);
  return state;
}

void Scene::bounds(const SceneState& state, glm::dvec3* lo, glm::dvec3* hi) const {
  *lo = glm::dvec3(std::numeric_limits<double>::max());
  *hi = glm::dvec3(std::numeric_limits<double>::lowest());
  for (int i : scene_nodes_) {
    const int m = nodes[i].mesh;
    if (m == -1 || mesh_lo_[m].x > mesh_hi_[m].x) continue;
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
  const CameraModel& model = cameras[nodes[camera_node_].camera];
  return Camera::from_transform(state.world[camera_node_], model.yfov, model.znear);
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
