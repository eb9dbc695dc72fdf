#include <afr/display/service/overlays.h>

#include <algorithm>
#include <array>
#include <cmath>

namespace afr::service {

void OverlaySink::on_tiling(TilingSnapshot&& snapshot) {
  reconstructor_.set_tiling(snapshot);
  std::lock_guard<std::mutex> lock(mutex_);
  tilings_[snapshot.sampler_id] = std::move(snapshot);
}

void OverlaySink::on_sampler_gone(uint32_t sampler_id) {
  reconstructor_.on_sampler_gone(sampler_id);
  std::lock_guard<std::mutex> lock(mutex_);
  tilings_.erase(sampler_id);
}

std::map<uint32_t, TilingSnapshot> OverlaySink::tilings() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return tilings_;
}

glm::vec3 sampler_color(uint32_t id) {
  static constexpr glm::vec3 kColors[] = {
      {0.9f, 0.2f, 0.2f}, {0.2f, 0.8f, 0.2f},   {0.25f, 0.4f, 1.0f}, {0.95f, 0.8f, 0.1f},
      {0.8f, 0.3f, 0.9f}, {0.1f, 0.85f, 0.85f}, {1.0f, 0.55f, 0.1f}, {0.6f, 0.6f, 0.6f}};
  return kColors[id % (sizeof(kColors) / sizeof(kColors[0]))];
}

Image tiling_overlay(const Image& image, const std::map<uint32_t, TilingSnapshot>& tilings,
                     const std::vector<std::pair<uint32_t, PixelRect>>& regions) {
  Image out = image;
  const int w = out.width, h = out.height;
  for (glm::vec3& p : out.pixels) p *= 0.5f;
  auto clip = [&](PixelRect r) {
    r.x0 = std::clamp(r.x0, 0, w);
    r.x1 = std::clamp(r.x1, 0, w);
    r.y0 = std::clamp(r.y0, 0, h);
    r.y1 = std::clamp(r.y1, 0, h);
    return r;
  };
  for (const auto& [id, region] : regions) {
    const PixelRect r = clip(region);
    const glm::vec3 c = sampler_color(id);
    for (int y = r.y0; y < r.y1; ++y) {
      for (int x = r.x0; x < r.x1; ++x) out.at(x, y) += 0.25f * c;
    }
  }
  for (const auto& [id, snap] : tilings) {
    const glm::vec3 c = sampler_color(id);
    for (const TileInfo& t : snap.tiles) {
      const PixelRect r = clip(t.rect);
      if (r.empty()) continue;
      for (int x = r.x0; x < r.x1; ++x) {
        out.at(x, r.y0) = c;
        out.at(x, r.y1 - 1) = c;
      }
      for (int y = r.y0; y < r.y1; ++y) {
        out.at(r.x0, y) = c;
        out.at(r.x1 - 1, y) = c;
      }
    }
  }
  return out;
}

Image gradient_overlay(const std::map<uint32_t, TilingSnapshot>& tilings, int width, int height,
                       glm::vec3* full) {
  Image out(width, height);
  // Per channel, the value that 95% of the tiled area lies at or below (weighted by the tiles'
  // visible areas): a few steep tiles saturate instead of darkening all the others.
  std::array<std::vector<std::pair<float, int64_t>>, 3> values;
  int64_t total = 0;
  for (const auto& [id, snap] : tilings) {
    for (const TileInfo& t : snap.tiles) {
      const PixelRect r = intersect(t.rect, PixelRect{0, 0, width, height});
      if (r.empty()) continue;
      total += r.area();
      const glm::vec3 g(t.G_x, t.G_y, t.G_t);
      for (int c = 0; c < 3; ++c) {
        values[size_t(c)].emplace_back(std::isfinite(g[c]) ? std::abs(g[c]) : 0.0f, r.area());
      }
    }
  }
  glm::vec3 scale(0.0f);
  for (int c = 0; c < 3; ++c) {
    std::vector<std::pair<float, int64_t>>& v = values[size_t(c)];
    std::sort(v.begin(), v.end());
    int64_t below = 0;
    for (const auto& [value, area] : v) {
      below += area;
      scale[c] = value;
      if (double(below) >= 0.95 * double(total)) break;
    }
    if (!(scale[c] > 0.0f) && !v.empty()) scale[c] = v.back().first;  // mostly flat
  }
  if (full != nullptr) *full = scale;
  for (const auto& [id, snap] : tilings) {
    for (const TileInfo& t : snap.tiles) {
      glm::vec3 color(0.0f);
      const glm::vec3 g(t.G_x, t.G_y, t.G_t);
      for (int c = 0; c < 3; ++c) {
        color[c] = scale[c] > 0.0f && std::isfinite(g[c])
                       ? std::min(std::abs(g[c]) / scale[c], 1.0f)
                       : 0.0f;
      }
      const int x0 = std::clamp(t.rect.x0, 0, width), x1 = std::clamp(t.rect.x1, 0, width);
      const int y0 = std::clamp(t.rect.y0, 0, height), y1 = std::clamp(t.rect.y1, 0, height);
      for (int y = y0; y < y1; ++y) {
        for (int x = x0; x < x1; ++x) out.at(x, y) = color;
      }
    }
  }
  return out;
}

Image density_overlay(const std::vector<float>& weights, int width, int height) {
  Image out(width, height);
  if (weights.size() != size_t(width) * size_t(height)) return out;
  float max_w = 0.0f;
  for (float v : weights) max_w = std::max(max_w, std::isfinite(v) ? v : 0.0f);
  if (!(max_w > 0.0f)) return out;
  const float scale = 1.0f / std::log1p(max_w);
  for (size_t i = 0; i < weights.size(); ++i) {
    const float v = std::isfinite(weights[i]) ? std::max(0.0f, weights[i]) : 0.0f;
    out.pixels[i] = glm::vec3(std::log1p(v) * scale);
  }
  return out;
}

void write_images(Reconstructor& reconstructor, const Image& image, const OverlaySink& sink,
                  const std::vector<std::pair<uint32_t, PixelRect>>& regions,
                  const std::filesystem::path& stem) {
  write_image(image, stem.string() + ".png");
  write_image(tiling_overlay(image, sink.tilings(), regions), stem.string() + "_tiling.png");
  std::vector<float> weights;
  reconstructor.read_weights(&weights);
  write_image(density_overlay(weights, image.width, image.height), stem.string() + "_density.png");
}

}  // namespace afr::service
