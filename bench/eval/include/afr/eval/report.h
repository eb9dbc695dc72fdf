// What the evaluation writes: the Table-1-like summary (Markdown and CSV), per-frame RMS (CSV
// and Figure-8-like plots drawn by gnuplot when it is installed), image strips of the ideal
// frame and every method at chosen frames (like Figures 1 and 6) and the wall time of every
// run.
#pragma once

#include <afr/eval/evaluation.h>

#include <filesystem>
#include <string>
#include <vector>

namespace afr::eval {

// "100K", "400K", "1.6M", "3.9M".
std::string rate_label(double rate);

// The runs of one (method, rate) of an animation over its seeds: one table cell.
struct Cell {
  Method method = Method::kAdaptive;
  double rate = 0.0;
  int runs = 0;
  double mean = 0.0;  // of the runs' mean RMS
  double min = 0.0;
  double max = 0.0;
  // Means over the runs.
  double wall_seconds = 0.0;  // sampling + reconstruction
  double primary_rays = 0.0;
  double occlusion_rays = 0.0;
  double charged_rays = 0.0;
};

// The cells of an animation, in table order (methods, then rates).
std::vector<Cell> cells_of(const AnimationResult& animation);

// A difference counts only beyond the spread: `a` is lower when its highest run is below the
// lowest run of `b` (the ranges over seeds do not overlap), higher in the mirror case, and
// within the spread otherwise. With one run each, every difference counts.
enum class Comparison { kLower, kHigher, kWithinSpread };
Comparison compare(const Cell& a, const Cell& b);

// Table 1: one row per method, one column per animation and rate, mean RMS (0-255) over the
// seeds with the lowest and highest run, "15.5 (15.2-15.9)". The full-res 60 Hz reference has
// one value per animation, shown in each of its rate columns.
std::string rms_table_markdown(const std::vector<AnimationResult>& results);
// Wall seconds of a run (sampling + reconstruction, mean over the seeds), same layout.
std::string wall_table_markdown(const std::vector<AnimationResult>& results);
// `method` against every other method, same layout: "lower", "higher" or "within spread"
// (compare()) with both means.
std::string comparison_markdown(const std::vector<AnimationResult>& results,
                                Method method = Method::kAdaptive);

// One line per run (with its seed).
void write_summary_csv(const std::vector<AnimationResult>& results,
                       const std::filesystem::path& file);
// One line per cell: animation, method, rate, runs, mean, min and max RMS, mean wall seconds
// and rays.
void write_cells_csv(const std::vector<AnimationResult>& results,
                     const std::filesystem::path& file);
void write_frames_csv(const std::vector<AnimationResult>& results,
                      const std::filesystem::path& file);

// Per animation and rate: frames-<animation>-<rate>.dat (time and one RMS column per method,
// each frame's mean over the seeds), a gnuplot script and, when gnuplot runs,
// rms-<animation>-<rate>.png. Returns the PNGs made.
std::vector<std::filesystem::path> write_frame_plots(const std::vector<AnimationResult>& results,
                                                     const std::filesystem::path& folder);

// Per animation and rate: strip-<animation>-<rate>.png, rows = strip frames, columns = the
// ideal frame and each method (its first seed's run), labelled when a TrueType font is found.
// Returns the files.
std::vector<std::filesystem::path> write_strips(const std::vector<AnimationResult>& results,
                                                const std::filesystem::path& folder);

// Runs gnuplot on a script; false (and a warning) when gnuplot is missing or fails.
bool run_gnuplot(const std::filesystem::path& script);

// Draws `text` in white on a dark band at the top-left of `image` at (x, y) (pixels; y is
// the baseline). Does nothing when no font is found.
void draw_label(Image* image, int x, int y, const std::string& text, int size = 13);

}  // namespace afr::eval
