// libFuzzer target for the camera-path parser (camera_path.h). Besides "no crash, no
// undefined behaviour", it checks what the format promises of every path it accepts: the
// written text reads back key for key, bit for bit, and every pose is finite.
#include <afr/common/camera_path.h>
#include <afr/common/check.h>
#include <afr/common/error.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string_view>

namespace {

bool finite(const afr::CameraKey& k) {
  return std::isfinite(k.time) && std::isfinite(k.eye.x) && std::isfinite(k.eye.y) &&
         std::isfinite(k.eye.z) && std::isfinite(k.rotation.w) && std::isfinite(k.rotation.x) &&
         std::isfinite(k.rotation.y) && std::isfinite(k.rotation.z) && std::isfinite(k.yfov);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  afr::CameraPath path;
  try {
    path = afr::parse_camera_path(text, "fuzz.path");
  } catch (const afr::Error&) {
    return 0;  // rejected with a message: what bad input should get
  }
  const afr::CameraPath again = afr::parse_camera_path(afr::format_camera_path(path), "again");
  AFR_CHECK(again.keys().size() == path.keys().size());
  for (size_t i = 0; i < path.keys().size(); ++i) {
    const afr::CameraKey& a = path.keys()[i];
    const afr::CameraKey& b = again.keys()[i];
    AFR_CHECK(a.time == b.time && a.eye == b.eye && a.rotation == b.rotation && a.yfov == b.yfov);
  }
  // Poses at the keys, between them and outside the path's range.
  const double t0 = path.start_time(), t1 = path.end_time();
  for (const double t : {t0 - 1.0, t0, 0.5 * t0 + 0.5 * t1, t0 + 0.3 * (t1 - t0), t1, t1 + 1.0}) {
    AFR_CHECK(finite(path.pose(t)));
  }
  return 0;
}
