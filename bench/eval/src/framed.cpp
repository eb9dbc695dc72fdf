#include <afr/eval/framed.h>

#include <afr/common/check.h>

#include <algorithm>
#include <cmath>
#include <thread>
#include <vector>

namespace afr::eval {

int64_t FrameSchedule::frame_shown_at(double t) const {
  const int64_t done = int64_t(std::floor((t - origin) / period + 1e-9)) - 1;
  const int64_t old_enough = int64_t(std::floor((t - latency - origin) / period + 1e-9));
  return std::min(done, old_enough);
}

void framed_resolution(double samples_per_frame, int width, int height, int* w, int* h) {
  const double aspect = double(width) / double(height);
  *h = std::clamp(int(std::floor(std::sqrt(samples_per_frame / aspect))), 1, height);
  *w = std::clamp(int(std::floor(*h * aspect + 1e-9)), 1, width);
}

Image trace_frame(Tracer& tracer, double time, int width, int height, int threads,
                  TraceStats* stats) {
  tracer.set_time(time);
  const Camera camera = tracer.camera();
  Image image(width, height);
  threads = std::clamp(threads, 1, height);
  std::vector<TraceStats> per_thread(static_cast<size_t>(threads));
  const auto work = [&](int t) {
    for (int y = t; y < height; y += threads) {
      for (int x = 0; x < width; ++x) {
        image.at(x, y) =
            tracer.trace(camera.ray(x + 0.5, y + 0.5, width, height), &per_thread[size_t(t)]).color;
      }
    }
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < threads; ++t) pool.emplace_back(work, t);
  work(0);
  for (std::thread& t : pool) t.join();
  for (const TraceStats& s : per_thread) *stats += s;
  return image;
}

Image upsample_bilinear(const Image& source, int width, int height) {
  AFR_CHECK(source.width > 0 && source.height > 0);
  Image out(width, height);
  const double sx = double(source.width) / width, sy = double(source.height) / height;
  for (int y = 0; y < height; ++y) {
    const double v = std::clamp((y + 0.5) * sy - 0.5, 0.0, double(source.height - 1));
    const int y0 = int(v), y1 = std::min(y0 + 1, source.height - 1);
    const float fy = float(v - y0);
    for (int x = 0; x < width; ++x) {
      const double u = std::clamp((x + 0.5) * sx - 0.5, 0.0, double(source.width - 1));
      const int x0 = int(u), x1 = std::min(x0 + 1, source.width - 1);
      const float fx = float(u - x0);
      const glm::vec3 top = glm::mix(source.at(x0, y0), source.at(x1, y0), fx);
      const glm::vec3 bottom = glm::mix(source.at(x0, y1), source.at(x1, y1), fx);
      out.at(x, y) = glm::mix(top, bottom, fy);
    }
  }
  return out;
}

}  // namespace afr::eval
