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
// Viewports (a display wall): a reconstructor may draw one rectangle of the sampling image.
// It reconstructs the viewport grown by a margin, as a reconstruction of the whole image would
// there, and shows the viewport; it needs only the samples and tiles of received_region().
#pragma once

#include <afr/common/camera.h>
#include <afr/common/image.h>
#include <afr/common/samples.h>
#include <afr/display/coverage_map.h>
#include <afr/display/filter.h>
#include <afr/display/sample_store.h>
#include <afr/display/tile_field.h>

#include <cstdint>
#include <functional>
#include <vector>

namespace afr {

struct ReconstructorConfig {
  // The sampling image: sample positions and tile rectangles are in its pixels. Outputs of
  // another size are the same image scaled.
  ImageExtent image{256, 256};
  // The rectangle of the sampling image that reconstruct() shows, scaled to its output size;
  // empty (the default) means the whole image. Must lie inside the image.
  PixelRect viewport;
  // Sampling-image pixels around the viewport that are reconstructed too, but not shown:
  // samples there splat into the viewport, and the coverage map and hole filling there are
  // what the viewport's border pixels read, so the viewport's border matches a
  // reconstruction of the whole image. Clipped to the image. -1 means
  // auto_viewport_margin(splat), 3 splat guard bands (99 px for the default splat sizes) at
  // output scales of 1 or more; at a scale s < 1 use 3 (max_radius + 1) / s. What a margin
  // must cover: one splat's reach, plus how far the coverage map carries the missing samples
  // beyond it inward from one image to the next (up to a splat's reach per image where
  // splats are at their largest), plus how far stored samples reproject while the camera
  // moves (docs/reconstruction.md, "Viewports").
  int viewport_margin = -1;
  // N, the samples kept; 0 means 4 x the pixels of received_region() (section 5.2): with the
  // default viewport, 4 x image.width x image.height.
  size_t capacity = 0;
  ReconstructionMode mode = ReconstructionMode::kAdaptive;
  FilterLimits filter;
  SplatSizeRule splat;
  // CPU backend worker threads, including the calling one; 0 = the hardware's count.
  int threads = 0;
};

// GPU time of one image's passes, milliseconds, from GL_TIME_ELAPSED queries read without
// waiting (a GPU backend; the CPU backend leaves them empty).
struct GpuTimes {
  uint64_t image = 0;  // the reconstruct() call they time (1 = the first); 0: none yet
  // False where the driver's timer queries measure nothing (a software rasteriser runs the
  // work when it is waited for): then only `image` is set.
  bool timed = false;
  double upload = 0.0;    // new samples from the staging ring into the sample ring
  double bin = 0.0;       // gather: splats prepared and binned to screen tiles
  double splat = 0.0;     // splats (or newest samples) into the accumulation and coverage
  double fill = 0.0;      // hole pyramid and normalisation
  double readback = 0.0;  // the image into a mapped buffer, when read back
  // The whole image: from the moment the GPU had finished everything before it to its last
  // command (GL_TIMESTAMP). A pass's time can include the tail of the image before it (its
  // timer starts when the GPU reaches it, not when the work before it is done), so this, not
  // the passes' sum, bounds the image's GPU cost; it also holds any time the GPU waited for
  // the CPU to send the image's commands (a CPU-bound display shows it in the first pass).
  double image_ms = 0.0;
  double total() const { return image_ms; }
};

// Where a GPU backend's reconstruct() call spends its wall time, milliseconds, by phase: what
// bounds the rate when the CPU, not the GPU, is the slower side.
struct CallTimes {
  double wait = 0.0;     // for the image slot kInFlight images back, and for a read-back
  double copy = 0.0;     // the new samples out of the store
  double prepare = 0.0;  // the base class's share: sample counts, tile field, filters
  double upload = 0.0;   // the new samples into the staging ring and their copy commands
  double passes = 0.0;   // the index map, the filters and every pass's commands
};

// Where a CPU backend's reconstruct() call went, wall milliseconds (all zero on a GPU backend).
struct CpuPhaseTimes {
  double prepare = 0.0;    // new samples into the reconstructor's copy, tile field, filters
  double shape = 0.0;      // each pixel's splat shape from the coverage map; sums cleared
  double reproject = 0.0;  // every stored sample projected into its bin (band, column block)
  double splat = 0.0;      // the Gaussian splats into the sums and the coverage
  double fill = 0.0;       // each pixel's weighted mean, holes filled
};

// What the last reconstruct() did.
struct FrameStats {
  uint64_t stored = 0;         // samples in the store
  uint64_t splatted = 0;       // samples that reached the image (CPU backend only)
  uint64_t behind_camera = 0;  // reprojected behind the camera (CPU backend only)
  uint64_t off_screen = 0;     // reprojected where their splat reaches no pixel (CPU only)
  uint64_t future = 0;         // stamped more than max_future ahead: skipped (CPU only)
  // The pixel counts are of this image, except on a GPU backend that was not asked for the
  // image: then of the latest image the GPU had finished (read without waiting for it).
  uint64_t hole_pixels = 0;       // no splat reached them: filled from wider support
  uint64_t empty_pixels = 0;      // no weight anywhere in the image: black
  uint64_t nonfinite_pixels = 0;  // NaN or infinite before the final guard (set to 0); 0
  float depth = 0.0f;             // seconds the store reaches back (the cap of e_t)
  float default_rate = 0.0f;      // measured samples per pixel per second, for unknown tiles
  double milliseconds = 0.0;      // wall time of the reconstruct() call
  GpuTimes gpu;                   // GPU backend: the latest image the GPU has finished
  CallTimes call;                 // GPU backend: this call's phases
  CpuPhaseTimes cpu;              // CPU backend: this call's phases
};

// One tile of the last image as the filter saw it (Reconstructor::tile_states()).
struct TileState {
  PixelRect rect;         // the tile, sampling-image pixels
  PixelRect counted;      // the part of it inside received_region(): where R_l is measured
  uint64_t stored = 0;    // samples the store holds in `counted`
  float rate = 0.0f;      // R_l: stored / (counted area x depth), or the fallback (filter.h)
  FilterExtents extents;  // e_x, e_y (sampling-image pixels), e_t (seconds)
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
  void on_sampler_gone(uint32_t sampler_id) override { field_.forget(sampler_id); }

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
  // The last image's coverage over `rect`, in output pixels of the whole image (as
  // write_coverage takes it), row-major. False, with *out empty, unless rect lies inside the
  // pixels the last image computed (frame_grid(), at a whole-pixel origin).
  virtual bool read_coverage(const PixelRect& rect, std::vector<CoverageCell>* out) = 0;
  // A display wall's nodes keep their coverage maps equal (docs/wall.md, "Seams"): `cells`
  // (row-major, rect.area() of them) is the coverage another reconstructor of the same image
  // at the same output scale read from its last image (read_coverage of its viewport), and
  // `rect` where it lies, in output pixels of the whole image. Where it overlaps the pixels
  // this reconstructor computed last (frame_grid()), it replaces this one's coverage, which
  // the next reconstruct() sizes its splats from. Returns the pixels replaced: 0 before the
  // first image, after the grid moved, or when the grid's origin is not a whole pixel. Throws
  // afr::Error when cells.size() != rect.area().
  virtual size_t write_coverage(const PixelRect& rect, const std::vector<CoverageCell>& cells) = 0;

  // The samples the last reconstruct() held, as ring slots: the sample with sequence number q
  // (SampleStore's) is slots[q % size] for q in [end - stored, end). The CPU backend's own
  // copy; the GL backend reads its ring back from the GPU at the first call and keeps a copy
  // from then on. Valid until the next reconstruct(). A display wall node finds the samples
  // it forwards to its peers here (WallExchange).
  struct StoredSlots {
    const StoredSample* slots = nullptr;
    size_t size = 0;
    uint64_t end = 0;
    size_t stored = 0;
  };
  virtual StoredSlots stored_samples() = 0;

  // Waits until every image asked for is complete (a GPU backend returns from reconstruct()
  // before the GPU has drawn the image, unless it was read back); then frame_stats().gpu times
  // the last one.
  virtual void finish() {}

  void set_mode(ReconstructionMode mode) { mode_ = mode; }
  ReconstructionMode mode() const { return mode_; }
  virtual const char* backend_name() const = 0;

  // The config with the viewport, margin and capacity resolved.
  const ReconstructorConfig& config() const { return config_; }
  const PixelRect& viewport() const { return config_.viewport; }
  // The viewport grown by the margin, clipped to the image: where the samples and tiles this
  // reconstructor uses lie (what a display wall node must be sent), and where R_l is counted.
  const PixelRect& received_region() const { return received_; }
  // The pixels the last reconstruct() computed (viewport, margin, alignment) placed in the
  // sampling image.
  const PixelGrid& frame_grid() const { return field_.grid(); }
  // The tiles of the last image: index 0 is the entry of pixels no tile covers. The
  // reconstructing thread only.
  const std::vector<TileState>& tile_states() const { return tile_states_; }
  const FrameStats& frame_stats() const { return frame_; }
  IngestStats ingest_stats() const { return store_.stats(); }
  TileFieldStats tiling_stats() const { return field_.stats(); }
  size_t capacity() const { return store_.capacity(); }

 protected:
  // What both backends compute before splatting.
  struct FrameSetup {
    double time = 0.0;
    int width = 0;  // the output: the viewport scaled
    int height = 0;
    float scale_x = 1.0f;  // output pixels per sampling-image pixel
    float scale_y = 1.0f;
    // The pixels reconstructed (the viewport with its margin), and the output's first pixel
    // in them: output pixel (u, v) is grid pixel (u + view_x, v + view_y).
    PixelGrid grid;
    int view_x = 0;
    int view_y = 0;
    // Output pixels of the whole image at this scale, for the projection (Projector's size).
    double scaled_width = 0.0;
    double scaled_height = 0.0;
    bool field_changed = false;       // the tile index map was rebuilt
    std::vector<TileFilter> filters;  // one per field_.tiles() entry
    // Per field_.tiles() entry: the widest splat its stored density calls for (output pixels;
    // the largest float where it stores no sample): splat_density_cap.
    std::vector<float> radius_caps;
  };

  // write_coverage's check of its arguments: throws afr::Error unless cells.size() equals
  // rect.area().
  static void check_coverage_size(const PixelRect& rect, const std::vector<CoverageCell>& cells);

  // Implemented by the backends: *out is already width x height (or nullptr).
  virtual void do_reconstruct(const Camera& camera, double time, int width, int height,
                              Image* out) = 0;
  // Places the frame's pixels, brings the tile field and the stored-sample count per tile up
  // to date and computes the per-tile filters for this frame from the store's `delta` (its
  // depth) and `fresh`, the samples it copied (oldest first). Fills frame_.stored, depth and
  // default_rate, and tile_states(). `meanwhile`, when given, runs on this thread while the
  // stored-sample counts are brought up to date on another (it must not touch them).
  void prepare_frame(double time, int width, int height, const SampleStore::Delta& delta,
                     const std::vector<StoredSample>& fresh, FrameSetup* setup,
                     const std::function<void()>& meanwhile = {});

  ReconstructorConfig config_;
  PixelRect received_;
  SampleStore store_;
  TileField field_;
  FrameStats frame_;

 private:
  // The grid of an output of width x height: the viewport scaled, grown by the margin (at
  // most kMaxGridMargin output pixels) and clipped to the image; where it does not reach the
  // image's edge its origin is aligned to kGridAlign output pixels, the blocks of the hole
  // pyramid's first levels, so that holes near the viewport fill as in the whole image.
  void place_grid(int width, int height, FrameSetup* setup) const;

  ReconstructionMode mode_;
  // Reconstructing thread only.
  TileSampleCounts counts_;
  int count_threads_ = 1;  // threads a large count update may use (config threads, 0 = all)
  std::vector<TileState> tile_states_;
};

// The part of `rect` (output pixels of the whole image) inside `grid`, in the grid's pixels;
// empty when they do not overlap or the grid's origin is not a whole output pixel.
PixelRect grid_part(const PixelGrid& grid, const PixelRect& rect);

// The margin ReconstructorConfig::viewport_margin = -1 stands for.
inline int auto_viewport_margin(const SplatSizeRule& rule) { return 3 * splat_guard_band(rule); }

}  // namespace afr
