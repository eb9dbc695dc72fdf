// The reconstructor interface (sections 5 and 6.2): takes sample batches and tiling snapshots
// from any number of samplers and produces an image when asked. Two backends implement it:
// CpuReconstructor (the reference, multithreaded) and GlReconstructor (OpenGL 4.3); choose one
// with make_reconstructor() in backend.h.
//
// Order of calls and threads:
//   - add_batch() / set_tiling() (or the SampleSink calls) from any thread, at any time,
//     concurrently with reconstruct(); they copy what they need and keep no reference.
//   - reconstruct(), read_weights(), read_coverage(), set_mode() and destruction from one
//     thread, the reconstructing thread (for GlReconstructor the thread its context is used
//     on). Each reconstruct() first takes the samples added since the previous one.
//   - Construction may happen anywhere (GlReconstructor: on the reconstructing thread).
// Ownership: the reconstructor owns its sample store, tile field, coverage map and buffers; the
// caller owns the output image.
#pragma once

#include <afr/common/camera.h>
#include <afr/common/image.h>
#include <afr/common/samples.h>
#include <afr/display/coverage_map.h>
#include <afr/display/filter.h>
#include <afr/display/sample_store.h>
#include <afr/display/tile_field.h>

#include <cstdint>
#include <vector>

namespace afr {

struct ReconstructorConfig {
  // The sampling image: sample positions and tile rectangles are in its pixels. Outputs of
  // another size are the same image scaled.
  int image_width = 256;
  int image_height = 256;
  // N, the samples kept; 0 means 4 x image_width x image_height (section 5.2).
  size_t capacity = 0;
  ReconstructionMode mode = ReconstructionMode::kAdaptive;
  FilterLimits filter;
  SplatSizeRule splat;
  // CPU backend worker threads, including the calling one; 0 = the hardware's count.
  int threads = 0;
};

// What the last reconstruct() did.
struct FrameStats {
  uint64_t stored = 0;            // samples in the store
  uint64_t splatted = 0;          // samples that reached the image (CPU backend only)
  uint64_t behind_camera = 0;     // reprojected behind the camera (CPU backend only)
  uint64_t off_screen = 0;        // reprojected where their splat reaches no pixel (CPU only)
  uint64_t future = 0;            // stamped more than max_future ahead: skipped (CPU only)
  uint64_t hole_pixels = 0;       // no splat reached them: filled from wider support
  uint64_t empty_pixels = 0;      // no weight anywhere in the image: black
  uint64_t nonfinite_pixels = 0;  // NaN or infinite before the final guard (set to 0); 0
  float depth = 0.0f;             // seconds the store reaches back (the cap of e_t)
  float default_rate = 0.0f;      // measured samples per pixel per second, for unknown tiles
  double milliseconds = 0.0;      // wall time of the reconstruct() call
};

// Output sides are limited to this (the largest texture of common GPUs and of llvmpipe).
inline constexpr int kMaxOutputSide = 16384;
// N is limited to this (4 GiB of samples).
inline constexpr size_t kMaxCapacity = size_t(1) << 26;

class Reconstructor : public SampleSink {
 public:
  // Throws afr::Error when the image size or capacity is out of range.
  explicit Reconstructor(const ReconstructorConfig& config);
  ~Reconstructor() override;
  Reconstructor(const Reconstructor&) = delete;
  Reconstructor& operator=(const Reconstructor&) = delete;

  // ---- Ingest: any thread.
  void add_batch(const SampleBatch& batch) { store_.append(batch); }
  void set_tiling(const TilingSnapshot& snapshot) { field_.set_tiling(snapshot); }
  void on_batch(SampleBatch&& batch) override { store_.append(batch); }
  void on_tiling(TilingSnapshot&& snapshot) override { field_.set_tiling(snapshot); }

  // ---- The reconstructing thread.
  // Reconstructs the image seen by `camera` at display time `time` into *out (resized to
  // width x height; nullptr: keep it inside, e.g. for a window). The camera is only used by
  // the reprojecting mode. Throws afr::Error for sizes outside [1, kMaxOutputSide] or a time
  // that is not finite.
  void reconstruct(const Camera& camera, double time, int width, int height, Image* out);
  Image reconstruct(const Camera& camera, double time, int width, int height);

  // The last image's sum of filter weights per pixel (the sample density map of Figure 7),
  // and its coverage map (section 6.2), row 0 at the top.
  virtual void read_weights(std::vector<float>* out) = 0;
  virtual void read_coverage(std::vector<CoverageCell>* out) = 0;

  void set_mode(ReconstructionMode mode) { mode_ = mode; }
  ReconstructionMode mode() const { return mode_; }
  virtual const char* backend_name() const = 0;

  const ReconstructorConfig& config() const { return config_; }
  const FrameStats& frame_stats() const { return frame_; }
  IngestStats ingest_stats() const { return store_.stats(); }
  TileFieldStats tiling_stats() const { return field_.stats(); }
  size_t capacity() const { return store_.capacity(); }

 protected:
  // What both backends compute before splatting.
  struct FrameSetup {
    double time = 0.0;
    int width = 0;
    int height = 0;
    float scale_x = 1.0f;  // output pixels per sampling-image pixel
    float scale_y = 1.0f;
    bool field_changed = false;       // the tile index map was rebuilt
    std::vector<TileFilter> filters;  // one per field_.tiles() entry
  };

  // Implemented by the backends: *out is already width x height (or nullptr).
  virtual void do_reconstruct(const Camera& camera, double time, int width, int height,
                              Image* out) = 0;
  // Brings the tile field and the count of stored samples per pixel up to date and computes
  // the per-tile filters for this frame from the store's `delta` (its depth and measured
  // rate) and `fresh`, the samples it copied (oldest first). Fills frame_.stored, depth and
  // default_rate.
  void prepare_frame(double time, int width, int height, const SampleStore::Delta& delta,
                     const std::vector<StoredSample>& fresh, FrameSetup* setup);

  ReconstructorConfig config_;
  SampleStore store_;
  TileField field_;
  FrameStats frame_;

 private:
  // Keeps pixel_count_ equal to the number of stored samples whose sampling-image position
  // falls in each pixel, from the samples entering the ring and those they overwrite.
  void count_fresh_samples(const SampleStore::Delta& delta, const std::vector<StoredSample>& fresh);
  // Samples in the store inside `rect` (sampling-image pixels).
  uint64_t stored_in(const PixelRect& rect) const;

  ReconstructionMode mode_;
  // Reconstructing thread only. Per ring slot, the sampling-image pixel of the sample in it
  // (kNoPixel: empty or outside the image); per pixel, how many stored samples are in it; and
  // the summed-area table of those counts, (image_width + 1) x (image_height + 1).
  static constexpr uint32_t kNoPixel = ~uint32_t(0);
  std::vector<uint32_t> slot_pixel_;
  std::vector<uint32_t> pixel_count_;
  std::vector<uint64_t> count_table_;
};

}  // namespace afr
