#include <afr/display/service/dashboard.h>

#include <nlohmann/json.hpp>

// PNG encoding (Debian's libstb-dev); its functions are static, used here only.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#pragma GCC diagnostic ignored "-Wsign-compare"
#define STB_IMAGE_WRITE_STATIC
#define STB_IMAGE_WRITE_IMPLEMENTATION
#include <stb/stb_image_write.h>
#pragma GCC diagnostic pop

#include <algorithm>
#include <chrono>

namespace afr::service {

std::string encode_png(const Image& image) {
  if (image.width < 1 || image.height < 1) return {};
  std::vector<uint8_t> rgb(size_t(image.width) * size_t(image.height) * 3);
  for (size_t i = 0; i < image.pixels.size(); ++i) {
    for (int c = 0; c < 3; ++c) rgb[3 * i + size_t(c)] = linear_to_srgb8(image.pixels[i][c]);
  }
  std::string png;
  stbi_write_png_to_func(
      [](void* context, void* data, int size) {
        static_cast<std::string*>(context)->append(static_cast<const char*>(data), size_t(size));
      },
      &png, image.width, image.height, 3, rgb.data(), image.width * 3);
  return png;
}

double DashboardFeed::clock_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

bool DashboardFeed::wants_image() const {
  const double now = clock_seconds();
  std::lock_guard<std::mutex> lock(mutex_);
  return now - asked_at_ <= kAskedFor && now - last_image_ >= kImageInterval;
}

namespace {

// At most kMaxSide pixels a side for the page: box-filtered by a whole factor.
constexpr int kMaxSide = 1024;

Image for_the_page(const Image& image) {
  const int f = (std::max(image.width, image.height) + kMaxSide - 1) / kMaxSide;
  if (f <= 1) return image;
  Image out(std::max(1, image.width / f), std::max(1, image.height / f));
  for (int y = 0; y < out.height; ++y) {
    for (int x = 0; x < out.width; ++x) {
      glm::vec3 sum(0.0f);
      for (int j = 0; j < f; ++j) {
        for (int i = 0; i < f; ++i) sum += image.at(x * f + i, y * f + j);
      }
      out.at(x, y) = sum / float(f * f);
    }
  }
  return out;
}

}  // namespace

void DashboardFeed::publish(const Image& image, const Image& tiling) {
  // Encoded outside the lock: a page's request never waits for it.
  std::string png = encode_png(for_the_page(image)), tiling_png = encode_png(for_the_page(tiling));
  std::lock_guard<std::mutex> lock(mutex_);
  png_ = std::move(png);
  tiling_png_ = std::move(tiling_png);
  last_image_ = clock_seconds();
}

void DashboardFeed::add_period(const DashboardPeriod& period) {
  std::lock_guard<std::mutex> lock(mutex_);
  periods_.push_back(period);
  while (periods_.size() > kMaxPeriods) periods_.pop_front();
}

void DashboardFeed::add_event(double time, const std::string& text) {
  std::lock_guard<std::mutex> lock(mutex_);
  events_.emplace_back(time, text);
  while (events_.size() > kMaxEvents) events_.pop_front();
}

std::string DashboardFeed::image_png(bool tiling) const {
  std::lock_guard<std::mutex> lock(mutex_);
  asked_at_ = clock_seconds();
  return tiling ? tiling_png_ : png_;
}

std::string DashboardFeed::history_json(double since) const {
  nlohmann::json j;
  j["periods"] = nlohmann::json::array();
  j["events"] = nlohmann::json::array();
  std::lock_guard<std::mutex> lock(mutex_);
  for (const DashboardPeriod& p : periods_) {
    if (!(p.time > since)) continue;
    nlohmann::json samplers = nlohmann::json::array();
    for (const DashboardPeriod::Sampler& s : p.samplers) {
      samplers.push_back({{"id", s.id}, {"rate", s.samples_per_second}, {"share", s.share}});
    }
    j["periods"].push_back({{"t", p.time},
                            {"refresh_hz", p.refresh_hz},
                            {"reconstruct_ms_mean", p.reconstruct_ms_mean},
                            {"reconstruct_ms_p99", p.reconstruct_ms_p99},
                            {"latency_ms_p50", p.latency_ms_p50},
                            {"latency_ms_p99", p.latency_ms_p99},
                            {"store_fill", p.store_fill},
                            {"members", p.members},
                            {"samplers", samplers}});
  }
  for (const auto& [t, text] : events_) {
    if (t > since) j["events"].push_back({{"t", t}, {"text", text}});
  }
  return j.dump();
}

}  // namespace afr::service
