// Pictures of what the display knows besides the image: the tiling colored by owning sampler
// (the paper's Figure 3, with the coordinator's regions), and the sample density (Figure 7,
// the reconstructor's filter weights). OverlaySink sits between the ingest thread and the
// reconstructor and keeps each sampler's latest tiling for them.
#pragma once

#include <afr/common/image.h>
#include <afr/common/samples.h>
#include <afr/display/reconstructor.h>

#include <cstdint>
#include <filesystem>
#include <map>
#include <mutex>
#include <utility>
#include <vector>

namespace afr::service {

// Forwards everything to the reconstructor; remembers the newest tiling of every sampler.
class OverlaySink final : public SampleSink {
 public:
  explicit OverlaySink(Reconstructor& reconstructor) : reconstructor_(reconstructor) {}
  void on_batch(SampleBatch&& batch) override { reconstructor_.add_batch(batch); }
  void on_tiling(TilingSnapshot&& snapshot) override;
  void on_sampler_gone(uint32_t sampler_id) override;
  std::map<uint32_t, TilingSnapshot> tilings() const;

 private:
  Reconstructor& reconstructor_;
  mutable std::mutex mutex_;
  std::map<uint32_t, TilingSnapshot> tilings_;
};

// A distinct color per sampler id.
glm::vec3 sampler_color(uint32_t sampler_id);

// The image dimmed, each region tinted with its sampler's color and every tile outlined in it.
Image tiling_overlay(const Image& image, const std::map<uint32_t, TilingSnapshot>& tilings,
                     const std::vector<std::pair<uint32_t, PixelRect>>& regions);
// The tiles' gradients as the paper's Figure 4: G_x red, G_y green, G_t blue (black where no
// tile lies), each full at the value 95% of the tiled area lies at or below (its largest where
// that is 0), the steeper 5% saturated; those values in *full when asked (the HUD's legend).
Image gradient_overlay(const std::map<uint32_t, TilingSnapshot>& tilings, int width, int height,
                       glm::vec3* full = nullptr);
// Filter weight per pixel on a log scale, as grey (white: the densest pixel).
Image density_overlay(const std::vector<float>& weights, int width, int height);

// Writes STEM.png (the image), STEM_tiling.png and STEM_density.png. The image must be the
// reconstructor's last output (its weights are read for the density).
void write_images(Reconstructor& reconstructor, const Image& image, const OverlaySink& sink,
                  const std::vector<std::pair<uint32_t, PixelRect>>& regions,
                  const std::filesystem::path& stem);

}  // namespace afr::service
