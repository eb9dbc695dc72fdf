// The CPU reconstructor: the reference backend, and the fast one where the only OpenGL is a
// software rasteriser. A multithreaded scatter: samples are turned into splats in parallel
// chunks, binned by horizontal band of the image, and each band is accumulated by one thread,
// so no two threads write the same pixel. The per-pixel sums come out in sample order
// whatever the thread count, so images are identical for 1 or 64 threads.
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
  int threads() const;

 protected:
  void do_reconstruct(const Camera& camera, double time, int width, int height,
                      Image* out) override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace afr
