#include <afr/common/camera_path.h>

#include <afr/common/error.h>

#include <fmt/format.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <iterator>
#include <numbers>
#include <sstream>

namespace afr {

namespace {

constexpr double kMinRotationNorm = 1e-6;

bool finite(const glm::dvec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

// The largest absolute component of a finite quaternion: dividing by it first keeps its length
// from overflowing (components near 1e308) or underflowing.
double largest_component(const glm::dquat& q) {
  return std::max({std::abs(q.x), std::abs(q.y), std::abs(q.z), std::abs(q.w)});
}

// Length and unit quaternion of a finite, nonzero quaternion, without overflow.
double safe_length(const glm::dquat& q) {
  const double m = largest_component(q);
  return m > 0.0 ? m * glm::length(q / m) : 0.0;
}
glm::dquat safe_normalize(const glm::dquat& q) { return glm::normalize(q / largest_component(q)); }

// What is wrong with a key on its own (empty when nothing), with `previous` the key before it
// or nullptr.
std::string key_problem(const CameraKey& k, const CameraKey* previous) {
  if (!std::isfinite(k.time)) return "the time is not finite";
  if (previous != nullptr && !(k.time > previous->time)) {
    return fmt::format("time {} is not after the previous key's {}", k.time, previous->time);
  }
  if (!finite(k.eye)) return "the eye is not finite";
  const glm::dvec4 q(k.rotation.x, k.rotation.y, k.rotation.z, k.rotation.w);
  if (!std::isfinite(q.x) || !std::isfinite(q.y) || !std::isfinite(q.z) || !std::isfinite(q.w)) {
    return "the rotation is not finite";
  }
  if (safe_length(k.rotation) < kMinRotationNorm) {
    return "the rotation quaternion has (nearly) zero length";
  }
  if (!(k.yfov > 0.0 && k.yfov < std::numbers::pi)) {
    return fmt::format("yfov {} is outside (0, pi) radians", k.yfov);
  }
  if (!(k.ymag >= 0.0 && std::isfinite(k.ymag))) {
    return fmt::format("ymag {} is not finite and >= 0", k.ymag);
  }
  if (previous != nullptr && (k.ymag > 0.0) != (previous->ymag > 0.0)) {
    return fmt::format(
        "ymag {} after the previous key's {}: a path is perspective (0) or "
        "orthographic (> 0) throughout",
        k.ymag, previous->ymag);
  }
  return {};
}

// Splits on spaces and tabs.
std::vector<std::string_view> fields_of(std::string_view line) {
  std::vector<std::string_view> out;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    const size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t') ++i;
    if (i > start) out.push_back(line.substr(start, i - start));
  }
  return out;
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r'))
    s.remove_suffix(1);
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  return s;
}

}  // namespace

CameraPath::CameraPath(std::vector<CameraKey> keys) : keys_(std::move(keys)) {
  if (keys_.empty()) throw Error("camera path: no keys");
  if (keys_.size() > kMaxCameraPathKeys) {
    throw Error(
        fmt::format("camera path: {} keys exceed the limit {}", keys_.size(), kMaxCameraPathKeys));
  }
  for (size_t i = 0; i < keys_.size(); ++i) {
    const std::string problem = key_problem(keys_[i], i > 0 ? &keys_[i - 1] : nullptr);
    if (!problem.empty()) throw Error(fmt::format("camera path: key {}: {}", i, problem));
    // A written path reads back bit for bit: rotations already of unit length are kept.
    if (std::abs(safe_length(keys_[i].rotation) - 1.0) > 1e-12) {
      keys_[i].rotation = safe_normalize(keys_[i].rotation);
    }
  }
}

CameraKey CameraPath::pose(double t) const {
  if (!(t > keys_.front().time)) return keys_.front();  // NaN too
  if (t >= keys_.back().time) return keys_.back();
  // The first key after t; t lies in [a.time, b.time).
  const auto it = std::upper_bound(keys_.begin(), keys_.end(), t,
                                   [](double v, const CameraKey& k) { return v < k.time; });
  const CameraKey& b = *it;
  const CameraKey& a = *(it - 1);
  const double u = (t - a.time) / (b.time - a.time);
  CameraKey out;
  out.time = t;
  out.eye = glm::mix(a.eye, b.eye, u);
  out.yfov = a.yfov + (b.yfov - a.yfov) * u;
  out.ymag = a.ymag + (b.ymag - a.ymag) * u;
  // Slerp along the shorter arc (q and -q are the same rotation).
  glm::dquat qb = b.rotation;
  if (glm::dot(a.rotation, qb) < 0.0) qb = -qb;
  out.rotation = glm::normalize(glm::slerp(a.rotation, qb, u));
  return out;
}

Camera CameraPath::camera(double t, double znear) const {
  const CameraKey k = pose(t);
  Camera camera =
      Camera::from_transform(compose_trs(k.eye, k.rotation, glm::dvec3(1.0)), k.yfov, znear);
  camera.ymag = k.ymag;
  return camera;
}

CameraKey camera_key(double time, const Camera& camera) {
  // The rotation's columns are the world directions of the camera's local axes.
  const glm::dmat3 basis(camera.right, camera.up, -camera.forward);
  CameraKey k;
  k.time = time;
  k.eye = camera.eye;
  k.rotation = glm::normalize(glm::quat_cast(basis));
  k.yfov = camera.yfov;
  k.ymag = camera.ymag;
  return k;
}

CameraPath parse_camera_path(std::string_view text, std::string_view name) {
  const auto error = [&](size_t line, const std::string& what) {
    return Error(fmt::format("{}:{}: {}", name, line, what));
  };
  std::vector<CameraKey> keys;
  size_t line_number = 0;
  size_t pos = 0;
  bool header_seen = false;
  while (pos < text.size() || (line_number == 0 && text.empty())) {
    const size_t end = std::min(text.find('\n', pos), text.size());
    const std::string_view raw = text.substr(pos, end - pos);
    pos = end + 1;
    ++line_number;
    const std::string_view line = trim(raw);
    if (!header_seen) {
      if (line != kCameraPathHeader) {
        throw error(line_number, fmt::format("expected the header '{}'", kCameraPathHeader));
      }
      header_seen = true;
      continue;
    }
    if (line.empty() || line.front() == '#') continue;
    const std::vector<std::string_view> fields = fields_of(line);
    if (fields.size() != 9 && fields.size() != 10) {
      throw error(line_number,
                  fmt::format("expected 9 or 10 numbers (t ex ey ez qx qy qz qw yfov [ymag]), "
                              "found {}",
                              fields.size()));
    }
    double v[10] = {};
    for (size_t i = 0; i < fields.size(); ++i) {
      const std::string_view f = fields[i];
      const auto [ptr, ec] = std::from_chars(f.data(), f.data() + f.size(), v[i]);
      if (ec != std::errc() || ptr != f.data() + f.size()) {
        throw error(line_number, fmt::format("'{}' is not a number", f));
      }
    }
    if (keys.size() >= kMaxCameraPathKeys) {
      throw error(line_number, fmt::format("more than {} keys", kMaxCameraPathKeys));
    }
    CameraKey k;
    k.time = v[0];
    k.eye = glm::dvec3(v[1], v[2], v[3]);
    k.rotation = glm::dquat(v[7], v[4], v[5], v[6]);
    k.yfov = v[8];
    k.ymag = v[9];
    const std::string problem = key_problem(k, keys.empty() ? nullptr : &keys.back());
    if (!problem.empty()) throw error(line_number, problem);
    keys.push_back(k);
  }
  if (!header_seen) throw error(1, fmt::format("expected the header '{}'", kCameraPathHeader));
  if (keys.empty()) throw error(line_number, "no keys after the header");
  return CameraPath(std::move(keys));
}

CameraPath read_camera_path(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(fmt::format("{}: cannot open the camera path", path.string()));
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw Error(fmt::format("{}: read error", path.string()));
  return parse_camera_path(text.str(), path.string());
}

std::string format_camera_path(const CameraPath& path) {
  // A perspective path keeps the nine columns every reader of the format knows.
  const bool orthographic = path.keys().front().ymag > 0.0;
  std::string out = fmt::format("{}\n# t ex ey ez qx qy qz qw yfov{}\n", kCameraPathHeader,
                                orthographic ? " ymag" : "");
  auto it = std::back_inserter(out);
  for (const CameraKey& k : path.keys()) {
    // fmt's "{}" writes the shortest text that reads back as the same double.
    fmt::format_to(it, "{} {} {} {} {} {} {} {} {}", k.time, k.eye.x, k.eye.y, k.eye.z,
                   k.rotation.x, k.rotation.y, k.rotation.z, k.rotation.w, k.yfov);
    if (orthographic) fmt::format_to(it, " {}", k.ymag);
    out.push_back('\n');
  }
  return out;
}

void write_camera_path(const CameraPath& path, const std::filesystem::path& file) {
  std::ofstream out(file, std::ios::binary);
  if (!out) throw Error(fmt::format("{}: cannot write the camera path", file.string()));
  out << format_camera_path(path);
  if (!out.flush()) throw Error(fmt::format("{}: write error", file.string()));
}

}  // namespace afr
