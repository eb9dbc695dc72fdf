#include <afr/sampler/sampler_config.h>

#include <afr/common/error.h>

#include <fmt/format.h>

#include <cmath>

namespace afr {

PixelRect SamplerConfig::owned_region() const { return region.empty() ? image.rect() : region; }

void SamplerConfig::validate() const {
  const auto fail = [](const std::string& what) { throw Error("sampler config: " + what); };
  if (image.width < 1 || image.height < 1 || image.width > (1 << 30) || image.height > (1 << 30)) {
    fail(fmt::format("image size {}x{} is outside 1..2^30", image.width, image.height));
  }
  const PixelRect o = owned_region();
  if (o.empty() || o.x0 < 0 || o.y0 < 0 || o.x1 > image.width || o.y1 > image.height) {
    fail(fmt::format("region [{},{})x[{},{}) is empty or outside the {}x{} image", o.x0, o.x1, o.y0,
                     o.y1, image.width, image.height));
  }
  if (b < 1 || b > 64) fail(fmt::format("b = {} is outside 1..64", b));
  if (r < 0 || r > 64) fail(fmt::format("r = {} is outside 0..64", r));
  if (chunk < 1 || chunk > 1000000) fail(fmt::format("chunk = {} is outside 1..10^6", chunk));
  if (!(kappa >= 0.0 && kappa <= 1.0)) fail(fmt::format("kappa = {} is outside [0, 1]", kappa));
  if (!(lambda >= 0.0 && lambda <= 1.0 && kappa + lambda <= 1.0)) {
    fail(fmt::format("lambda = {} must be in [0, 1] with kappa + lambda <= 1", lambda));
  }
  if (!(m > 0.0 && m < 1e6)) fail(fmt::format("m = {} is outside (0, 10^6)", m));
  if (!(i > 0.0 && i < 1e6)) fail(fmt::format("i = {} is outside (0, 10^6)", i));
  if (min_tiles < 1 || max_tiles < min_tiles) {
    fail(fmt::format("tile bounds {}..{} are not 1 <= min <= max", min_tiles, max_tiles));
  }
  if (max_tiling_ops < 1) fail("max_tiling_ops must be at least 1");
  if (!(refresh_interval > 0.0 && refresh_interval <= 60.0)) {
    fail(fmt::format("refresh interval {} s is outside (0, 60]", refresh_interval));
  }
  if (!(animation_step >= 0.0 && animation_step <= 1.0)) {
    fail(fmt::format("animation step {} s is outside [0, 1]", animation_step));
  }
  if (fill_step < 1) fail(fmt::format("fill step {} is below 1", fill_step));
  if (batch_size < 1 || batch_size > 65536) {
    fail(fmt::format("batch size {} is outside 1..65536", batch_size));
  }
}

}  // namespace afr
