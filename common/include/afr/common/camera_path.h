// Camera paths: a camera pose over time, as keys read from and written to a small text file.
// The evaluation replays recorded interactions from these files; display_node records and
// replays the same format. The format (docs/evaluation.md, "Camera paths"):
//
//   # afr camera path v1
//   # t ex ey ez qx qy qz qw yfov [ymag]
//   0.000 3.75 2.30 3.60 -0.233 0.236 0.057 0.942 0.7
//   ...
//
// The first line is exactly the header. After it, one key per line: time in seconds
// (strictly increasing), the eye in world space, the camera's world rotation as a unit
// quaternion (x, y, z, w; the camera looks down its local -Z with +Y up, as glTF cameras do)
// and the full vertical field of view in radians; a tenth number, when there is one, is an
// orthographic camera's ymag (Camera::ymag; 0 or absent: perspective). Blank lines and lines
// starting with '#' are ignored; numbers are separated by spaces or tabs. Between keys the eye,
// yfov and ymag are interpolated linearly and the rotation by slerp; before the first key and
// after the last the path holds still.
#pragma once

#include <afr/common/camera.h>
#include <afr/common/math.h>

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace afr {

inline constexpr std::string_view kCameraPathHeader = "# afr camera path v1";
// Paths longer than this are refused (a day of 60 Hz keys is 5.2 million).
inline constexpr size_t kMaxCameraPathKeys = size_t(1) << 24;

struct CameraKey {
  double time = 0.0;  // seconds
  glm::dvec3 eye{0.0};
  glm::dquat rotation{1.0, 0.0, 0.0, 0.0};  // glm order: w, x, y, z; unit length
  double yfov = 0.8;                        // radians, in (0, pi)
  double ymag = 0.0;  // > 0: orthographic (Camera::ymag); a path's keys are all 0 or all > 0
};

class CameraPath {
 public:
  CameraPath() = default;
  // Throws afr::Error if the keys are empty, times not finite and strictly increasing, an eye
  // or rotation not finite, a rotation of (nearly) zero length, a yfov outside (0, pi), or a
  // ymag not finite, negative, or 0 in a path whose first key's is not (and the other way).
  // Rotations are normalised.
  explicit CameraPath(std::vector<CameraKey> keys);

  const std::vector<CameraKey>& keys() const { return keys_; }
  double start_time() const { return keys_.front().time; }
  double end_time() const { return keys_.back().time; }

  // The pose at time t (clamped to the keys' range).
  CameraKey pose(double t) const;
  Camera camera(double t, double znear = 0.01) const;

 private:
  std::vector<CameraKey> keys_;
};

// The key that reproduces `camera` (its eye, basis, yfov and ymag) at `time`: what a recorder
// writes.
CameraKey camera_key(double time, const Camera& camera);

// Parses the text of a camera path file. `name` (a file name) starts every error message,
// followed by the line number: "paths/a.path:7: expected 9 or 10 numbers, found 8".
CameraPath parse_camera_path(std::string_view text, std::string_view name);
// Reads and parses a file; a missing or unreadable file is an afr::Error naming it.
CameraPath read_camera_path(const std::filesystem::path& path);

// The file text of a path: the header, a column comment and one line per key, with every
// number written so that it reads back exactly.
std::string format_camera_path(const CameraPath& path);
void write_camera_path(const CameraPath& path, const std::filesystem::path& file);

}  // namespace afr
