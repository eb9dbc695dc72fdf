// What the display's web dashboard shows (docs/service.md, "Dashboard"): the latest image and
// its tiling overlay as PNG, and a bounded history of the stats periods and of membership and
// recut events. The display thread feeds it; the metrics server's threads read it. Images are
// made only while a page asks for them (a GPU backend's image then leaves the GPU a few times
// a second, never otherwise).
#pragma once

#include <afr/common/image.h>

#include <cstdint>
#include <deque>
#include <mutex>
#include <string>
#include <vector>

namespace afr::service {

// One stats period as the dashboard charts it.
struct DashboardPeriod {
  double time = 0.0;  // display seconds since start
  double refresh_hz = 0.0;
  double reconstruct_ms_mean = 0.0, reconstruct_ms_p99 = 0.0;
  double latency_ms_p50 = 0.0, latency_ms_p99 = 0.0;
  double store_fill = 0.0;  // stored / capacity
  uint64_t members = 0;
  struct Sampler {
    uint32_t id = 0;
    double samples_per_second = 0.0;
    double share = 0.0;  // its region's area over the image's
  };
  std::vector<Sampler> samplers;
};

class DashboardFeed {
 public:
  static constexpr size_t kMaxPeriods = 600;  // 20 minutes at the default 2 s period
  static constexpr size_t kMaxEvents = 200;
  static constexpr double kImageInterval = 0.25;  // seconds between images while asked
  static constexpr double kAskedFor = 5.0;        // seconds an image request keeps them coming

  // ---- Display thread.
  // Whether to make an image now: a page asked for one within kAskedFor seconds and the last
  // was made kImageInterval ago (wall-clock seconds).
  bool wants_image() const;
  // The image (linear RGB) and its tiling overlay, encoded here as sRGB PNG.
  void publish(const Image& image, const Image& tiling);
  void add_period(const DashboardPeriod& period);
  void add_event(double time, const std::string& text);

  // ---- Any thread (the server's).
  // The latest PNG (empty before the first), and notes that a page wants images.
  std::string image_png(bool tiling) const;
  // Periods and events after display time `since`, as JSON.
  std::string history_json(double since) const;

 private:
  static double clock_seconds();  // steady clock

  mutable std::mutex mutex_;
  mutable double asked_at_ = -1e30;
  double last_image_ = -1e30;
  std::string png_, tiling_png_;
  std::deque<DashboardPeriod> periods_;
  std::deque<std::pair<double, std::string>> events_;
};

// Linear-RGB image as sRGB PNG bytes.
std::string encode_png(const Image& image);

// The dashboard page: HTML with its script, served at "/" (no other asset).
extern const char* const kDashboardPage;

}  // namespace afr::service
