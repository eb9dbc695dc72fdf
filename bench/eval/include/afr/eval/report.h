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

// Table 1: one row per method, one column per animation and rate, mean RMS (0-255). The
// full-res 60 Hz reference has one value per animation, shown in each of its rate columns.
std::string rms_table_markdown(const std::vector<AnimationResult>& results);
// Wall seconds of every run (sampling + reconstruction), same layout.
std::string wall_table_markdown(const std::vector<AnimationResult>& results);

void write_summary_csv(const std::vector<AnimationResult>& results,
                       const std::filesystem::path& file);
void write_frames_csv(const std::vector<AnimationResult>& results,
                      const std::filesystem::path& file);

// Per animation and rate: frames-<animation>-<rate>.dat (time and one RMS column per method),
// a gnuplot script and, when gnuplot runs, rms-<animation>-<rate>.png. Returns the PNGs made.
std::vector<std::filesystem::path> write_frame_plots(const std::vector<AnimationResult>& results,
                                                     const std::filesystem::path& folder);

// Per animation and rate: strip-<animation>-<rate>.png, rows = strip frames, columns = the
// ideal frame and each method, labelled when a TrueType font is found. Returns the files.
std::vector<std::filesystem::path> write_strips(const std::vector<AnimationResult>& results,
                                                const std::filesystem::path& folder);

// Runs gnuplot on a script; false (and a warning) when gnuplot is missing or fails.
bool run_gnuplot(const std::filesystem::path& script);

// Draws `text` in white on a dark band at the top-left of `image` at (x, y) (pixels; y is
// the baseline). Does nothing when no font is found.
void draw_label(Image* image, int x, int y, const std::string& text, int size = 13);

}  // namespace afr::eval
