// The CPU reconstructor: the reference backend, and the fast one where the only OpenGL is a
// software rasteriser. A multithreaded scatter: samples are reprojected in parallel chunks,
// sorted by the horizontal band of rows they land in, and splatted band by band in three
// rounds so that no two threads ever write the same pixel (no locks, no atomics). The order of
// the per-pixel sums does not depend on the thread count, so images are identical for 1 or 64
// threads. Nothing is allocated per sample.
#pragma once

#include <afr/display/reconstructor.h>

#include <memory>

namespace afr {

class CpuReconstructor final : public Reconstructor {
 public:
  explicit CpuReconstructor(const ReconstructorConfig& config);
  ~CpuReconstructor() override;

  const char* backend_name() const override { return "cpu"; }
  void read_weights(std::vector<float>* out) override;
  void read_coverage(std::vector<CoverageCell>* out) override;
  bool read_coverage(const PixelRect& rect, std::vector<CoverageCell>* out) override;
  size_t write_coverage(const PixelRect& rect, const std::vector<CoverageCell>& cells) override;
  StoredSlots stored_samples() override;
  int threads() const;

 protected:
  void do_reconstruct(const Camera& camera, double time, int width, int height,
                      Image* out) override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace afr
