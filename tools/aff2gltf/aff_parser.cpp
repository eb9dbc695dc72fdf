#include "aff_parser.h"

#include <afr/common/error.h>

#include <spdlog/spdlog.h>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <numbers>
#include <optional>
#include <set>
#include <tuple>

namespace afr::aff {
namespace {

constexpr int kMaxIncludeDepth = 64;
// Transforms nested deeper than this are refused (the kitchen nests 6 deep); the conversion
// recurses once per level.
constexpr size_t kMaxTransformDepth = 1000;
// Frames of `a`: they are not backed by bytes of the file, and each becomes a baked sample of
// every animation channel (the kitchen has 800; 100000 is 55 minutes at 30 frames/s).
constexpr int kMaxFrames = 100000;

bool is_space(char c) {
  return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f' || c == '\v';
}
bool is_letter(char c) { return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z'); }

// Bytes of a file, exactly as stored (Latin-1 comments and CRLF line ends are fine).
std::string read_bytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(path.string() + ": cannot open file");
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw Error(path.string() + ": read error");
  return bytes;
}

// ---- Cursor: the lexer over one file's bytes ----------------------------------------------

class Cursor {
 public:
  Cursor(std::string_view text, std::string file)
      : begin_(text.data()),
        p_(text.data()),
        end_(text.data() + text.size()),
        file_(std::move(file)) {}

  // Bytes read, and in all.
  size_t consumed() const { return size_t(p_ - begin_); }
  size_t size() const { return size_t(end_ - begin_); }

  const std::string& file() const { return file_; }
  Location here() const { return {file_, line_}; }
  bool at_end() const { return p_ == end_; }
  char peek() const { return *p_; }
  void advance() { ++p_; }

  void skip_space() {
    while (p_ != end_ && is_space(*p_)) {
      if (*p_ == '\n') ++line_;
      ++p_;
    }
  }
  void skip_line() {
    while (p_ != end_ && *p_ != '\n') ++p_;
  }

  [[noreturn]] void fail(const std::string& what) const { throw Error(here().str() + ": " + what); }

  // The whitespace-delimited token at the cursor, shortened for messages.
  std::string token_for_message() const {
    const char* q = p_;
    while (q != end_ && !is_space(*q)) ++q;
    std::string s(p_, q);
    if (s.size() > 40) s = s.substr(0, 40) + "...";
    return s;
  }

  // A run of non-whitespace characters (names, file names, keywords).
  std::string_view word(std::string_view what) {
    skip_space();
    if (at_end()) fail("unexpected end of file, expected " + std::string(what));
    const char* start = p_;
    while (p_ != end_ && !is_space(*p_)) ++p_;
    return std::string_view(start, size_t(p_ - start));
  }

  void keyword(std::string_view expected, std::string_view directive) {
    skip_space();
    const Location at = here();
    const std::string_view w = word("'" + std::string(expected) + "'");
    if (w != expected) {
      throw Error(at.str() + ": expected '" + std::string(expected) + "' in " +
                  std::string(directive) + ", found '" + std::string(w) + "'");
    }
  }

  // Reals are finite: "nan" and "inf" are refused (as decimals beyond the double range are).
  double real(std::string_view what) {
    skip_space();
    const char* start = p_;
    const double x = number<double>(what);
    if (!std::isfinite(x)) {
      p_ = start;
      fail("expected " + std::string(what) + ", found '" + token_for_message() +
           "', which is not a finite number");
    }
    return x;
  }
  int integer(std::string_view what) { return number<int>(what); }
  // A count of items that follow, each written with at least `min_bytes` bytes of the file
  // (a number and its separator take at least 2): what is allocated for the items stays
  // within a few times the size of the file, whatever count it claims.
  int count(std::string_view what, size_t min_bytes) {
    const Location at = (skip_space(), here());
    const int n = count(what);
    expect_room(n, min_bytes, at, what);
    return n;
  }
  // A count that is checked against the bytes left later (with expect_room).
  int count(std::string_view what) {
    const Location at = (skip_space(), here());
    const int n = integer(what);
    if (n < 0) throw Error(at.str() + ": negative " + std::string(what) + " " + std::to_string(n));
    return n;
  }
  void expect_room(int n, size_t min_bytes, const Location& at, std::string_view what) const {
    if (size_t(n) > size_t(end_ - p_) / min_bytes) {
      throw Error(at.str() + ": " + std::string(what) + " " + std::to_string(n) +
                  " is more than the rest of the file holds");
    }
  }
  glm::dvec3 vec3(std::string_view what) {
    glm::dvec3 v;
    v.x = real(what);
    v.y = real(what);
    v.z = real(what);
    return v;
  }

  // True if the next token starts like a number (for the optional colour of `l` and `la`).
  bool number_follows() {
    skip_space();
    if (at_end()) return false;
    const char c = *p_;
    return (c >= '0' && c <= '9') || c == '-' || c == '+' || c == '.';
  }

  void open_brace(std::string_view directive) {
    skip_space();
    if (at_end() || *p_ != '{') {
      fail("expected '{' after the header of " + std::string(directive) + ", found '" +
           (at_end() ? std::string("end of file") : token_for_message()) + "'");
    }
    ++p_;
  }

 private:
  // C strtod-style reals (also a leading '+'), decimal integers. A number must end at
  // whitespace, the end of the file or a brace.
  template <typename T>
  T number(std::string_view what) {
    skip_space();
    if (at_end()) fail("unexpected end of file, expected " + std::string(what));
    const char* start = p_;
    if (*start == '+' && start + 1 != end_ && start[1] != '-') ++start;
    T value{};
    const auto [ptr, ec] = std::from_chars(start, end_, value);
    if (ec == std::errc::result_out_of_range) {
      fail(std::string(what) + " out of range: '" + token_for_message() + "'");
    }
    if (ec != std::errc() || (ptr != end_ && !is_space(*ptr) && *ptr != '{' && *ptr != '}')) {
      fail("expected " + std::string(what) + ", found '" + token_for_message() + "'");
    }
    p_ = ptr;
    return value;
  }

  const char* begin_;
  const char* p_;
  const char* end_;
  int line_ = 1;
  std::string file_;
};

// ---- Parser: the directives and the parse state of section 1.2 ------------------------------

class Parser {
 public:
  Parser(const std::filesystem::path& root_dir, const ParseOptions& options, Scene* scene)
      : root_dir_(root_dir), options_(options), scene_(scene), detail_level_(options.detail_level) {
    scene_->nodes.emplace_back();  // the root
    merged_.emplace_back();
    stack_.push_back({0, {}});
    started_ = last_progress_ = std::chrono::steady_clock::now();
  }

  void parse_root(std::string_view text, const std::string& name) {
    parse_file(text, name, root_dir_, 0);
    if (stack_.size() > 1) {
      throw Error(stack_.back().opened.str() + ": '{' is never closed");
    }
    check_references();
  }

 private:
  std::chrono::steady_clock::time_point started_, last_progress_;
  struct OpenNode {
    int node;
    Location opened;
  };
  // Key of the per-node triangle set that collects small primitives (p, pp, s, c, tt, ttp):
  // material, has normals, has uvs.
  using MergeKey = std::tuple<int, bool, bool>;

  // Returns the number of directives and braces read (comments aside).
  uint64_t parse_file(std::string_view text, const std::string& name,
                      const std::filesystem::path& dir, int depth) {
    Cursor in(text, name);
    uint64_t read = 0;
    for (uint64_t steps = 0;; ++steps) {
      if (steps % 4096 == 0) progress(in);
      in.skip_space();
      if (in.at_end()) return read;
      const char c = in.peek();
      if (c == '#' || c == '%') {
        in.skip_line();
        continue;
      }
      ++read;
      if (c == '}') {
        if (stack_.size() == 1) in.fail("'}' without a matching '{'");
        in.advance();
        stack_.pop_back();
        continue;
      }
      if (c == '{') in.fail("'{' outside the header of x, xs or k");
      directive(in, dir, depth);
    }
  }

  // A line now and then on a long parse (ParseOptions::progress_interval).
  void progress(const Cursor& in) {
    const auto now = std::chrono::steady_clock::now();
    if (options_.progress_interval > 0.0 &&
        now - last_progress_ < std::chrono::duration<double>(options_.progress_interval)) {
      return;
    }
    if (options_.progress_interval > 0.0 && in.consumed() == 0) return;  // a file's start
    last_progress_ = now;
    size_t triangles = 0;
    for (const Node& n : scene_->nodes) {
      for (const TriangleSet& t : n.meshes) triangles += t.triangle_count();
    }
    spdlog::info("parsing {}: {:.1f} of {:.1f} MB, {} triangles so far ({:.1f} s)", in.file(),
                 double(in.consumed()) / 1e6, double(in.size()) / 1e6, triangles,
                 std::chrono::duration<double>(now - started_).count());
  }

  void directive(Cursor& in, const std::filesystem::path& dir, int depth) {
    const Location at = in.here();
    std::string code;
    while (!in.at_end() && is_letter(in.peek())) {
      code += in.peek();
      in.advance();
    }
    if (code.empty() || (!in.at_end() && !is_space(in.peek()))) {
      throw Error(at.str() + ": unknown directive '" + code + in.token_for_message() + "'");
    }
    if (code == "v") return view(in);
    if (code == "b") return void(scene_->background = in.vec3("a background colour component"));
    if (code == "am") return void(scene_->ambient = in.vec3("an ambient colour component"));
    if (code == "l") return light(in, at, false);
    if (code == "la") return light(in, at, true);
    if (code == "f") return fill_nff(in);
    if (code == "fm") return fill_material(in);
    if (code == "p") return polygon(in, false);
    if (code == "pp") return polygon(in, true);
    if (code == "s") return sphere(in);
    if (code == "c") return cone(in);
    if (code == "tt") return textured_triangle(in, false);
    if (code == "ttp") return textured_triangle(in, true);
    if (code == "tpa") return animated_triangle(in);
    if (code == "m") return mesh(in);
    if (code == "xs") return static_transform(in, at);
    if (code == "x") return animated_transform(in, at);
    if (code == "a") return animation_range(in);
    if (code == "k") return keyframes(in, at);
    if (code == "i") return include(in, at, dir, depth);
    if (code == "d") return void(detail_level_ = in.integer("a detail level"));
    throw Error(at.str() + ": unknown directive '" + code + "'");
  }

  // -- scene-level directives --

  void view(Cursor& in) {
    View v;
    in.keyword("from", "v");
    v.from = in.vec3("a 'from' coordinate");
    in.keyword("at", "v");
    v.at = in.vec3("an 'at' coordinate");
    in.keyword("up", "v");
    v.up = in.vec3("an 'up' coordinate");
    in.keyword("angle", "v");
    v.angle = in.real("the view angle");
    in.keyword("hither", "v");
    v.hither = in.real("the hither distance");
    if (v.hither < 1e-4) v.hither = 1.0;
    in.keyword("resolution", "v");
    v.width = in.integer("the x resolution");
    v.height = in.integer("the y resolution");
    scene_->view = v;
  }

  void light(Cursor& in, const Location& at, bool animated) {
    Light l;
    l.where = at;
    if (animated) l.name = std::string(in.word("a light name"));
    l.position = in.vec3("a light position coordinate");
    if (in.number_follows()) l.color = in.vec3("a light colour component");
    scene_->lights.push_back(std::move(l));
  }

  void animation_range(Cursor& in) {
    AnimationRange a;
    a.start = in.real("the animation start time");
    a.end = in.real("the animation end time");
    const Location frames_at = (in.skip_space(), in.here());
    a.frames = in.integer("the number of frames");
    if (a.frames < 0 || a.frames > kMaxFrames) {
      throw Error(frames_at.str() + ": " + std::to_string(a.frames) + " frames; afr accepts 0 to " +
                  std::to_string(kMaxFrames));
    }
    scene_->animation = a;
  }

  // -- materials --

  void fill_nff(Cursor& in) {
    const glm::dvec3 color = in.vec3("an f colour component");
    const double kd = in.real("Kd");
    const double ks = in.real("Ks");
    Material m;
    m.diffuse = kd * color;
    m.specular = glm::dvec3(ks);
    m.shine = in.real("the Phong exponent");
    m.transmittance = in.real("the transmittance");
    m.ior = in.real("the index of refraction");
    set_material(m);
  }

  void fill_material(Cursor& in) {
    Material m;
    m.ambient = in.vec3("an fm ambient component");
    m.diffuse = in.vec3("an fm diffuse component");
    m.specular = in.vec3("an fm specular component");
    m.shine = in.real("the Phong exponent");
    m.transmittance = in.real("the transmittance");
    m.ior = in.real("the index of refraction");
    set_material(m);
  }

  void set_material(const Material& m) {
    material_ = m;
    material_defined_ = true;
    material_cache_.clear();
  }

  // Index of the current material combined with `texture` (empty: none).
  int material_index(const std::filesystem::path& texture, const Location& at) {
    if (!material_defined_ && !warned_undefined_material_) {
      warned_undefined_material_ = true;
      scene_->warnings.push_back(at.str() +
                                 ": geometry before any f/fm; using the reference's zeroed "
                                 "(black) material");
    }
    const auto cached = material_cache_.find(texture);
    if (cached != material_cache_.end()) return cached->second;
    Material m = material_;
    m.texture = texture;
    auto& all = scene_->materials;
    int index = int(std::find(all.begin(), all.end(), m) - all.begin());
    if (index == int(all.size())) all.push_back(std::move(m));
    material_cache_.emplace(texture, index);
    return index;
  }

  // Section 1.1: <root>/../TextureFiles/NAME, then <root>/NAME.
  std::filesystem::path texture_path(std::string_view name, const Location& at) {
    const auto cached = texture_paths_.find(std::string(name));
    if (cached != texture_paths_.end()) return cached->second;
    const std::filesystem::path candidates[] = {root_dir_ / ".." / "TextureFiles" / name,
                                                root_dir_ / name};
    for (const auto& candidate : candidates) {
      std::error_code ec;
      if (std::filesystem::is_regular_file(candidate, ec)) {
        const std::filesystem::path resolved = candidate.lexically_normal();
        texture_paths_.emplace(std::string(name), resolved);
        return resolved;
      }
    }
    throw Error(at.str() + ": texture '" + std::string(name) + "' not found (looked for " +
                candidates[0].lexically_normal().string() + " and " +
                candidates[1].lexically_normal().string() + ")");
  }

  // -- geometry --

  Node& current() { return scene_->nodes[size_t(stack_.back().node)]; }

  // The triangle set of the current node that collects small primitives of one kind.
  TriangleSet& merged_set(int material, bool normals, bool uvs) {
    const int node = stack_.back().node;
    auto& sets = merged_[size_t(node)];
    const MergeKey key{material, normals, uvs};
    const auto it = sets.find(key);
    if (it != sets.end()) return scene_->nodes[size_t(node)].meshes[it->second];
    Node& n = scene_->nodes[size_t(node)];
    n.meshes.emplace_back();
    n.meshes.back().material = material;
    sets.emplace(key, n.meshes.size() - 1);
    return n.meshes.back();
  }

  void polygon(Cursor& in, bool patch) {
    const Location at = in.here();
    const int n = in.count("a vertex count", patch ? 12 : 6);
    std::vector<glm::vec3> positions(static_cast<size_t>(n)), normals(patch ? positions.size() : 0);
    for (int k = 0; k < n; ++k) {
      positions[size_t(k)] = glm::vec3(in.vec3("a polygon vertex coordinate"));
      if (patch) normals[size_t(k)] = glm::vec3(in.vec3("a polygon normal component"));
    }
    if (n < 3) {
      scene_->warnings.push_back(at.str() + ": polygon with " + std::to_string(n) +
                                 " vertices skipped");
      return;
    }
    append_polygon(positions, normals, {}, &merged_set(material_index({}, at), patch, false));
  }

  void sphere(Cursor& in) {
    const Location at = in.here();
    const glm::dvec3 center = in.vec3("a sphere centre coordinate");
    const double radius = in.real("the sphere radius");
    append_sphere(center, radius, options_.tessellation,
                  &merged_set(material_index({}, at), true, false));
  }

  void cone(Cursor& in) {
    const Location at = in.here();
    const glm::dvec3 base = in.vec3("a cone base coordinate");
    const double r0 = in.real("the cone base radius");
    const glm::dvec3 apex = in.vec3("a cone apex coordinate");
    const double r1 = in.real("the cone apex radius");
    append_cone(base, r0, apex, r1, options_.tessellation,
                &merged_set(material_index({}, at), true, false));
  }

  void textured_triangle(Cursor& in, bool patch) {
    const Location at = in.here();
    const std::filesystem::path texture = texture_path(in.word("a texture name"), at);
    glm::vec3 positions[3], normals[3];
    glm::vec2 uvs[3];
    for (int k = 0; k < 3; ++k) {
      positions[k] = glm::vec3(in.vec3("a triangle vertex coordinate"));
      if (patch) normals[k] = glm::vec3(in.vec3("a triangle normal component"));
      uvs[k].x = float(in.real("a texture coordinate"));
      uvs[k].y = float(in.real("a texture coordinate"));
    }
    const std::span<const glm::vec3> patch_normals =
        patch ? std::span<const glm::vec3>(normals) : std::span<const glm::vec3>();
    append_polygon(positions, patch_normals, uvs,
                   &merged_set(material_index(texture, at), patch, true));
  }

  void animated_triangle(Cursor& in) {
    const Location at = in.here();
    const int n = in.count("a number of times", 38);
    if (n < 1) in.fail("tpa needs at least one time");
    AnimatedTriangle tri;
    tri.material = material_index({}, at);
    tri.times.resize(size_t(n));
    tri.positions.resize(size_t(n));
    tri.normals.resize(size_t(n));
    for (size_t j = 0; j < size_t(n); ++j) {
      const Location time_at = (in.skip_space(), in.here());
      tri.times[j] = in.real("a tpa time");
      if (j > 0 && tri.times[j] < tri.times[j - 1]) {
        throw Error(time_at.str() + ": tpa times must not decrease");
      }
      for (int k = 0; k < 3; ++k) {
        tri.positions[j][size_t(k)] = glm::vec3(in.vec3("a tpa vertex coordinate"));
        tri.normals[j][size_t(k)] = glm::vec3(in.vec3("a tpa normal component"));
      }
    }
    current().animated_triangles.push_back(std::move(tri));
  }

  void mesh(Cursor& in) {
    const Location at = in.here();
    in.keyword("vertices", "m");
    const int nv = in.count("a vertex count", 6);
    std::vector<glm::vec3> positions(static_cast<size_t>(nv));
    for (auto& p : positions) p = glm::vec3(in.vec3("a vertex coordinate"));

    std::vector<glm::vec3> normals;
    std::vector<glm::vec2> uvs;
    std::filesystem::path texture;
    in.skip_space();
    Location word_at = in.here();
    std::string_view w = in.word("'normals', 'texturecoords' or 'triangles'");
    if (w == "normals") {
      normals.resize(size_t(in.count("a normal count", 6)));
      for (auto& n : normals) n = glm::vec3(in.vec3("a normal component"));
      in.skip_space();
      word_at = in.here();
      w = in.word("'texturecoords' or 'triangles'");
    }
    if (w == "texturecoords") {
      uvs.resize(size_t(in.count("a texture coordinate count", 4)));
      in.skip_space();
      const Location name_at = in.here();
      texture = texture_path(in.word("a texture name"), name_at);
      for (auto& uv : uvs) {
        uv.x = float(in.real("a texture coordinate"));
        uv.y = float(in.real("a texture coordinate"));
      }
      in.skip_space();
      word_at = in.here();
      w = in.word("'triangles'");
    }
    if (w != "triangles") {
      throw Error(word_at.str() + ": expected " +
                  (uvs.empty() ? (normals.empty() ? "'normals', 'texturecoords' or 'triangles'"
                                                  : "'texturecoords' or 'triangles'")
                               : "'triangles'") +
                  " in m, found '" + std::string(w) + "'");
    }
    const int ntri = in.count("a triangle count", 6);

    TriangleSet set;
    set.material = material_index(texture, at);
    set.indices.reserve(size_t(ntri) * 3);
    set.positions.reserve(positions.size());
    // De-index (v, n, t) tuples: for each position, a chain of the (n, t) pairs seen with it.
    struct Corner {
      int n, t;
      uint32_t out;
      uint32_t next;
    };
    constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();
    std::vector<uint32_t> head(positions.size(), kNone);
    std::vector<Corner> corners;
    corners.reserve(positions.size());
    auto index = [&](std::string_view what, size_t size) {
      in.skip_space();
      const Location index_at = in.here();
      const int i = in.integer(what);
      if (i < 0 || size_t(i) >= size) {
        throw Error(index_at.str() + ": " + std::string(what) + " " + std::to_string(i) +
                    " out of range (" + std::to_string(size) + " defined)");
      }
      return i;
    };
    for (int tri = 0; tri < ntri; ++tri) {
      int v[3], n[3] = {0, 0, 0}, t[3] = {0, 0, 0};
      for (int k = 0; k < 3; ++k) v[k] = index("vertex index", positions.size());
      if (!normals.empty()) {
        for (int k = 0; k < 3; ++k) n[k] = index("normal index", normals.size());
      }
      if (!uvs.empty()) {
        for (int k = 0; k < 3; ++k) t[k] = index("texture coordinate index", uvs.size());
      }
      for (int k = 0; k < 3; ++k) {
        uint32_t* link = &head[size_t(v[k])];
        while (*link != kNone && (corners[*link].n != n[k] || corners[*link].t != t[k])) {
          link = &corners[*link].next;
        }
        uint32_t corner = *link;
        if (corner == kNone) {
          corner = uint32_t(corners.size());
          *link = corner;  // before push_back, which may move `corners` (and `link` into it)
          corners.push_back({n[k], t[k], uint32_t(set.positions.size()), kNone});
          set.positions.push_back(positions[size_t(v[k])]);
          if (!normals.empty()) set.normals.push_back(normals[size_t(n[k])]);
          if (!uvs.empty()) set.uvs.push_back(uvs[size_t(t[k])]);
        }
        set.indices.push_back(corners[corner].out);
      }
    }
    if (!set.indices.empty()) current().meshes.push_back(std::move(set));
  }

  // -- transforms and animation --

  void push_node(Node node, const Location& at) {
    if (stack_.size() > kMaxTransformDepth) {
      throw Error(at.str() + ": transforms nested more than " + std::to_string(kMaxTransformDepth) +
                  " deep");
    }
    const int index = int(scene_->nodes.size());
    current().children.push_back(index);
    scene_->nodes.push_back(std::move(node));
    merged_.emplace_back();
    stack_.push_back({index, at});
  }

  void static_transform(Cursor& in, const Location& at) {
    Node node;
    node.kind = Node::Kind::kStatic;
    node.where = at;
    node.scale = in.vec3("an xs scale component");
    node.axis = in.vec3("an xs rotation axis component");
    node.angle_deg = in.real("the xs rotation angle");
    node.translation = in.vec3("an xs translation component");
    in.open_brace("xs");
    push_node(std::move(node), at);
  }

  void animated_transform(Cursor& in, const Location& at) {
    Node node;
    node.kind = Node::Kind::kAnimated;
    node.where = at;
    node.name = std::string(in.word("an animation name"));
    if (node.name == "{") in.fail("x needs an animation name before '{'");
    in.open_brace("x " + node.name);
    used_names_.insert(node.name);
    push_node(std::move(node), at);
  }

  void keyframes(Cursor& in, const Location& at) {
    Keyframes k;
    k.where = at;
    k.name = std::string(in.word("an animation name"));
    if (k.name == "{") in.fail("k needs an animation name before '{'");
    in.open_brace("k " + k.name);
    std::set<std::string> seen;
    for (;;) {
      in.skip_space();
      if (in.at_end()) throw Error(at.str() + ": k " + k.name + " is never closed with '}'");
      if (in.peek() == '}') {
        in.advance();
        break;
      }
      const Location type_at = in.here();
      const std::string type(in.word("a keyframe type"));
      if (!seen.insert(type).second) {
        throw Error(type_at.str() + ": '" + type + "' given twice in k " + k.name);
      }
      const Location count_at = (in.skip_space(), in.here());
      const int n = in.count("a key count");
      backwards_ = std::nullopt;
      if (type == "transl" || type == "scale") {
        if (n < 4) throw Error(type_at.str() + ": " + type + " needs at least 4 keys");
        in.expect_room(n, 14, count_at, "a key count");  // 7 numbers a key
        auto& keys = type == "transl" ? k.translation : k.scale;
        keys.resize(size_t(n));
        for (auto& key : keys) {
          key.t = key_time(in, &keys.front(), &key);
          key.value = in.vec3(type == "transl" ? "a translation component" : "a scale component");
          key.tension = in.real("a tension");
          key.continuity = in.real("a continuity");
          key.bias = in.real("a bias");
        }
        repair_key_order(&keys, k.name, type, type_at, 4);
      } else if (type == "rot") {
        if (n < 4) throw Error(type_at.str() + ": rot needs at least 4 keys");
        in.expect_room(n, 16, count_at, "a key count");  // 8 numbers a key
        k.rotation.resize(size_t(n));
        for (auto& key : k.rotation) {
          key.t = key_time(in, &k.rotation.front(), &key);
          key.axis = in.vec3("a rotation axis component");
          key.angle = in.real("a rotation angle") * std::numbers::pi / 180.0;
          key.tension = in.real("a tension");
          key.continuity = in.real("a continuity");
          key.bias = in.real("a bias");
        }
        repair_key_order(&k.rotation, k.name, type, type_at, 4);
      } else if (type == "visibility") {
        if (n < 1) throw Error(type_at.str() + ": visibility needs at least 1 key");
        in.expect_room(n, 4, count_at, "a key count");  // 2 numbers a key
        k.visibility.resize(size_t(n));
        for (auto& key : k.visibility) {
          key.t = key_time(in, &k.visibility.front(), &key);
          key.visible = in.integer("a visibility flag") != 0;
        }
        repair_key_order(&k.visibility, k.name, type, type_at, 1);
      } else {
        throw Error(type_at.str() + ": unknown keyframe type '" + type + "' in k " + k.name +
                    " (expected transl, rot, scale or visibility)");
      }
    }
    scene_->keyframes[k.name] = std::move(k);
  }

  // Reads the time of `key`; notes where the first key earlier than the one before it is.
  template <typename Key>
  double key_time(Cursor& in, const Key* first, const Key* key) {
    in.skip_space();
    const Location at = in.here();
    const double t = in.real("a key time");
    if (key != first && t < key[-1].t && !backwards_) backwards_ = Backwards{at, key[-1].t, t};
    return t;
  }

  // A channel whose key times go backwards (BART's robots: one block of Robot1.aff holds a
  // second run of keys that starts before the first one ends) is repaired with a warning:
  // keys sorted by time (stable), and of the keys that share a time only the last in the
  // file is kept, as of two `k` blocks with one name the last is. An ordered channel is left
  // as it is, repeated times included (they shape KB tangents and jumps).
  template <typename Key>
  void repair_key_order(std::vector<Key>* keys, const std::string& name, const std::string& type,
                        const Location& at, size_t min_keys) {
    if (!backwards_) return;
    const size_t before = keys->size();
    std::stable_sort(keys->begin(), keys->end(),
                     [](const Key& a, const Key& b) { return a.t < b.t; });
    std::vector<Key> kept;
    for (const Key& key : *keys) {
      if (!kept.empty() && kept.back().t == key.t) {
        kept.back() = key;  // the later in the file
      } else {
        kept.push_back(key);
      }
    }
    if (kept.size() < min_keys) {
      throw Error(at.str() + ": " + type + " of k " + name + " has " + std::to_string(kept.size()) +
                  " keys at distinct times once sorted; it needs " + std::to_string(min_keys));
    }
    *keys = std::move(kept);
    scene_->warnings.push_back(
        at.str() + ": k " + name + ": " + type + " key times go backwards (" +
        format_time(backwards_->previous) + " then " + format_time(backwards_->time) + " at " +
        backwards_->at.str() + "); keys sorted by time, " + std::to_string(before - keys->size()) +
        " of " + std::to_string(before) +
        " dropped where a later key in the file has the same time");
    backwards_ = std::nullopt;
  }

  static std::string format_time(double t) {
    std::string s = std::to_string(t);
    while (s.size() > 1 && s.back() == '0') s.pop_back();
    if (!s.empty() && s.back() == '.') s.pop_back();
    return s;
  }

  void include(Cursor& in, const Location& at, const std::filesystem::path& dir, int depth) {
    const int level = in.integer("an include detail level");
    const std::string name(in.word("an include file name"));
    if (level > detail_level_) return;
    if (depth + 1 > kMaxIncludeDepth) {
      throw Error(at.str() + ": includes nested more than " + std::to_string(kMaxIncludeDepth) +
                  " deep (an include cycle?)");
    }
    // Section 1.1: against the root file's directory, then the including file's.
    std::filesystem::path path;
    for (const auto& base : {root_dir_, dir}) {
      std::error_code ec;
      if (std::filesystem::is_regular_file(base / name, ec)) {
        path = base / name;
        break;
      }
    }
    if (path.empty()) {
      std::string looked = root_dir_.string();
      if (dir.lexically_normal() != root_dir_.lexically_normal()) looked += " and " + dir.string();
      throw Error(at.str() + ": cannot open include file '" + name + "' (looked in " + looked +
                  ")");
    }
    const std::string key = path.lexically_normal().string();
    auto it = files_.find(key);
    if (it == files_.end()) {
      it = files_.emplace(key, std::make_unique<std::string>(read_bytes(path))).first;
    }
    // A file emptied by a failed copy or download converts to nothing: say so, once a file.
    if (parse_file(*it->second, path.string(), path.parent_path(), depth + 1) == 0 &&
        empty_includes_.insert(key).second) {
      scene_->warnings.push_back(at.str() + ": include file '" + name +
                                 "' holds no directives: it adds nothing to the scene");
    }
  }

  // Warnings for names that refer to nothing (the scene still converts: identity motion).
  void check_references() {
    for (const Light& l : scene_->lights) {
      if (!l.name.empty()) used_names_.insert(l.name);
    }
    for (const std::string& name : used_names_) {
      if (!scene_->keyframes.count(name)) {
        scene_->warnings.push_back("no 'k " + name + "' block: '" + name + "' does not move");
      }
    }
    for (const auto& [name, k] : scene_->keyframes) {
      if (name != "camera" && !used_names_.count(name)) {
        scene_->warnings.push_back(k.where.str() + ": k " + name + " animates nothing");
      }
    }
  }

  std::filesystem::path root_dir_;
  ParseOptions options_;
  Scene* scene_;
  int detail_level_;
  std::vector<OpenNode> stack_;
  std::vector<std::map<MergeKey, size_t>> merged_;  // per node
  // The first backwards key time of the channel being read.
  struct Backwards {
    Location at;
    double previous = 0.0;
    double time = 0.0;
  };
  std::optional<Backwards> backwards_;
  Material material_;
  bool material_defined_ = false;
  bool warned_undefined_material_ = false;
  std::map<std::filesystem::path, int> material_cache_;  // texture -> index, current material
  std::map<std::string, std::filesystem::path> texture_paths_;
  std::map<std::string, std::unique_ptr<std::string>> files_;  // include bytes, read once
  std::set<std::string> empty_includes_;                       // warned of already
  std::set<std::string> used_names_;
};

}  // namespace

Scene parse_aff_file(const std::filesystem::path& path, const ParseOptions& options) {
  const std::string bytes = read_bytes(path);
  std::filesystem::path dir = path.parent_path();
  if (dir.empty()) dir = ".";
  Scene scene = parse_aff_text(bytes, path.string(), dir, options);
  scene.root_file = path;
  return scene;
}

Scene parse_aff_text(std::string_view text, const std::string& name,
                     const std::filesystem::path& root_dir, const ParseOptions& options) {
  Scene scene;
  scene.root_file = root_dir / name;
  Parser parser(root_dir, options, &scene);
  parser.parse_root(text, name);
  return scene;
}

}  // namespace afr::aff
