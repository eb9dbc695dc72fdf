#include <afr/eval/report.h>

#include <afr/common/error.h>
#include <afr/common/log.h>

#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <fmt/format.h>

#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <optional>
#include <set>

namespace afr::eval {

namespace {

std::ofstream open_out(const std::filesystem::path& file) {
  if (file.has_parent_path()) std::filesystem::create_directories(file.parent_path());
  std::ofstream out(file);
  if (!out) throw Error(fmt::format("{}: cannot write", file.string()));
  return out;
}

// The methods present in the results, in table order.
std::vector<Method> methods_of(const std::vector<AnimationResult>& results) {
  std::set<Method> present;
  for (const AnimationResult& a : results) {
    for (const RunResult& r : a.runs) present.insert(r.method);
  }
  std::vector<Method> out;
  for (Method m : all_methods()) {
    if (present.count(m)) out.push_back(m);
  }
  return out;
}

// The rates of the rate-dependent runs of an animation, ascending.
std::vector<double> rates_of(const AnimationResult& a) {
  std::set<double> rates;
  for (const RunResult& r : a.runs) {
    if (method_uses_rate(r.method)) rates.insert(r.rate);
  }
  if (rates.empty()) {
    for (const RunResult& r : a.runs) rates.insert(r.rate);
  }
  return {rates.begin(), rates.end()};
}

// The runs of `method` at `rate` (any rate for the fixed-rate reference), seeds ascending.
std::vector<const RunResult*> find_runs(const AnimationResult& a, Method method, double rate) {
  std::vector<const RunResult*> out;
  for (const RunResult& r : a.runs) {
    if (r.method == method && (!method_uses_rate(method) || r.rate == rate)) out.push_back(&r);
  }
  return out;
}

// The first seed's run, or nullptr.
const RunResult* find_run(const AnimationResult& a, Method method, double rate) {
  const std::vector<const RunResult*> runs = find_runs(a, method, rate);
  return runs.empty() ? nullptr : runs.front();
}

std::optional<Cell> cell_of(const AnimationResult& a, Method method, double rate) {
  const std::vector<const RunResult*> runs = find_runs(a, method, rate);
  if (runs.empty()) return std::nullopt;
  Cell c;
  c.method = method;
  c.rate = runs.front()->rate;
  c.runs = int(runs.size());
  c.min = c.max = runs.front()->mean_rms;
  for (const RunResult* r : runs) {
    c.mean += r->mean_rms;
    c.min = std::min(c.min, r->mean_rms);
    c.max = std::max(c.max, r->mean_rms);
    c.wall_seconds += r->stats.sample_seconds + r->stats.reconstruct_seconds;
    c.primary_rays += double(r->stats.primary_rays);
    c.occlusion_rays += double(r->stats.occlusion_rays);
    c.charged_rays += r->stats.charged_rays;
  }
  const double n = double(runs.size());
  c.mean /= n;
  c.wall_seconds /= n;
  c.primary_rays /= n;
  c.occlusion_rays /= n;
  c.charged_rays /= n;
  return c;
}

// One row per method, one column per animation and rate; `text` makes a cell's text (empty
// cells show "-").
std::string table(const std::vector<AnimationResult>& results, const std::vector<Method>& rows,
                  const std::function<std::string(const AnimationResult&, Method, double)>& text) {
  std::string header = "| Method |", rule = "|---|";
  for (const AnimationResult& a : results) {
    for (double rate : rates_of(a)) {
      header += fmt::format(" {} {} |", a.spec.name, rate_label(rate));
      rule += "---:|";
    }
  }
  std::string out = header + "\n" + rule + "\n";
  for (Method m : rows) {
    out += fmt::format("| {} |", method_label(m));
    for (const AnimationResult& a : results) {
      for (double rate : rates_of(a)) {
        const std::string cell = text(a, m, rate);
        out += " " + (cell.empty() ? std::string("-") : cell) + " |";
      }
    }
    out += "\n";
  }
  return out;
}

std::string safe(std::string s) {
  for (char& c : s) {
    if (c == ' ' || c == '/' || c == ',') c = '_';
  }
  return s;
}

const char* find_font() {
  static const char* const kFonts[] = {
      "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
      "/usr/share/fonts/truetype/dejavu/DejaVuSansCondensed.ttf",
      "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
  };
  for (const char* f : kFonts) {
    std::error_code ec;
    if (std::filesystem::is_regular_file(f, ec)) return f;
  }
  return nullptr;
}

}  // namespace

std::string rate_label(double rate) {
  if (rate >= 1e6) return fmt::format("{:.3g}M", rate / 1e6);
  return fmt::format("{:.3g}K", rate / 1e3);
}

std::vector<Cell> cells_of(const AnimationResult& animation) {
  std::vector<Cell> out;
  for (Method m : all_methods()) {
    if (!method_uses_rate(m)) {
      if (std::optional<Cell> c = cell_of(animation, m, 0.0)) out.push_back(*c);
      continue;
    }
    for (double rate : rates_of(animation)) {
      if (std::optional<Cell> c = cell_of(animation, m, rate)) out.push_back(*c);
    }
  }
  return out;
}

Comparison compare(const Cell& a, const Cell& b) {
  if (a.max < b.min) return Comparison::kLower;
  if (a.min > b.max) return Comparison::kHigher;
  return Comparison::kWithinSpread;
}

std::string rms_table_markdown(const std::vector<AnimationResult>& results) {
  return table(results, methods_of(results),
               [](const AnimationResult& a, Method m, double rate) -> std::string {
                 const std::optional<Cell> c = cell_of(a, m, rate);
                 if (!c) return "";
                 if (c->runs == 1) return fmt::format("{:.1f}", c->mean);
                 return fmt::format("{:.1f} ({:.1f}-{:.1f})", c->mean, c->min, c->max);
               });
}

std::string wall_table_markdown(const std::vector<AnimationResult>& results) {
  return table(results, methods_of(results),
               [](const AnimationResult& a, Method m, double rate) -> std::string {
                 const std::optional<Cell> c = cell_of(a, m, rate);
                 return c ? fmt::format("{:.1f}", c->wall_seconds) : "";
               });
}

std::string comparison_markdown(const std::vector<AnimationResult>& results, Method method) {
  std::vector<Method> rows;
  for (Method m : methods_of(results)) {
    if (m != method) rows.push_back(m);
  }
  return table(results, rows, [&](const AnimationResult& a, Method m, double rate) -> std::string {
    const std::optional<Cell> mine = cell_of(a, method, rate), theirs = cell_of(a, m, rate);
    if (!mine || !theirs) return "";
    static constexpr const char* kWords[] = {"lower", "higher", "within spread"};
    const Comparison c = compare(*mine, *theirs);
    const std::string words = kWords[int(c)];
    return fmt::format("{} ({:.1f} vs {:.1f})",
                       c == Comparison::kWithinSpread ? words : "**" + words + "**", mine->mean,
                       theirs->mean);
  });
}

void write_summary_csv(const std::vector<AnimationResult>& results,
                       const std::filesystem::path& file) {
  std::ofstream out = open_out(file);
  out << "animation,method,rate,seed,mean_rms,frames,primary_rays,occlusion_rays,charged_rays,"
         "virtual_seconds,sample_wall_s,reconstruct_wall_s,frame_width,frame_height,"
         "frame_period_s,frames_traced\n";
  for (const AnimationResult& a : results) {
    for (const RunResult& r : a.runs) {
      out << fmt::format(
          "{},{},{},{},{:.4f},{},{},{},{:.0f},{:.4f},{:.3f},{:.3f},{},{},{:.6f},{}\n", a.spec.name,
          method_name(r.method), r.rate, r.seed, r.mean_rms, r.rms.size(), r.stats.primary_rays,
          r.stats.occlusion_rays, r.stats.charged_rays, r.stats.virtual_seconds,
          r.stats.sample_seconds, r.stats.reconstruct_seconds, r.stats.frame_width,
          r.stats.frame_height, r.stats.frame_period, r.stats.frames_traced);
    }
  }
}

void write_cells_csv(const std::vector<AnimationResult>& results,
                     const std::filesystem::path& file) {
  std::ofstream out = open_out(file);
  out << "animation,method,rate,runs,mean_rms,min_rms,max_rms,wall_s,primary_rays,"
         "occlusion_rays,charged_rays\n";
  for (const AnimationResult& a : results) {
    for (const Cell& c : cells_of(a)) {
      out << fmt::format("{},{},{},{},{:.4f},{:.4f},{:.4f},{:.3f},{:.0f},{:.0f},{:.0f}\n",
                         a.spec.name, method_name(c.method), c.rate, c.runs, c.mean, c.min, c.max,
                         c.wall_seconds, c.primary_rays, c.occlusion_rays, c.charged_rays);
    }
  }
}

void write_frames_csv(const std::vector<AnimationResult>& results,
                      const std::filesystem::path& file) {
  std::ofstream out = open_out(file);
  out << "animation,method,rate,seed,frame,time,input_time,newest_sample,rms\n";
  for (const AnimationResult& a : results) {
    for (const RunResult& r : a.runs) {
      for (size_t j = 0; j < r.rms.size(); ++j) {
        out << fmt::format("{},{},{},{},{},{:.6f},{:.6f},{:.6f},{:.4f}\n", a.spec.name,
                           method_name(r.method), r.rate, r.seed, j, r.frame_times[j],
                           r.inputs[j].input_time, r.inputs[j].newest_sample, r.rms[j]);
      }
    }
  }
}

bool run_gnuplot(const std::filesystem::path& script) {
  static const bool available = std::system("command -v gnuplot > /dev/null 2>&1") == 0;
  if (!available) {
    spdlog::warn("gnuplot not found (Debian package gnuplot-nox): {} not drawn", script.string());
    return false;
  }
  const std::string command = fmt::format("gnuplot '{}' 2>&1", script.string());
  if (std::system(command.c_str()) != 0) {
    spdlog::warn("gnuplot failed on {}", script.string());
    return false;
  }
  return true;
}

std::vector<std::filesystem::path> write_frame_plots(const std::vector<AnimationResult>& results,
                                                     const std::filesystem::path& out_folder) {
  // Scripts name their files absolutely, so they run from anywhere.
  const std::filesystem::path folder = std::filesystem::absolute(out_folder);
  std::vector<std::filesystem::path> pngs;
  std::filesystem::create_directories(folder);
  for (const AnimationResult& a : results) {
    for (double rate : rates_of(a)) {
      // Per method, the mean over its seeds of each frame's RMS.
      std::vector<Method> methods;
      std::vector<std::vector<double>> curves;
      for (Method m : all_methods()) {
        const std::vector<const RunResult*> seeds = find_runs(a, m, rate);
        if (seeds.empty()) continue;
        std::vector<double> mean(a.frame_times.size(), 0.0);
        for (const RunResult* r : seeds) {
          for (size_t j = 0; j < mean.size(); ++j) mean[j] += r->rms[j] / double(seeds.size());
        }
        methods.push_back(m);
        curves.push_back(std::move(mean));
      }
      if (methods.empty()) continue;
      const std::string stem = fmt::format("{}-{}", safe(a.spec.name), rate_label(rate));
      const std::filesystem::path dat = folder / ("frames-" + stem + ".dat");
      {
        std::ofstream out = open_out(dat);
        out << "# time";
        for (Method m : methods) out << ' ' << method_name(m);
        out << '\n';
        for (size_t j = 0; j < a.frame_times.size(); ++j) {
          out << fmt::format("{:.6f}", a.frame_times[j]);
          for (const std::vector<double>& curve : curves) out << fmt::format(" {:.4f}", curve[j]);
          out << '\n';
        }
      }
      const std::filesystem::path png = folder / ("rms-" + stem + ".png");
      const std::filesystem::path gp = folder / ("rms-" + stem + ".gp");
      {
        std::ofstream out = open_out(gp);
        out << "set terminal pngcairo noenhanced size 900,420 font 'DejaVu Sans,10'\n"
            << fmt::format("set output '{}'\n", png.string())
            << fmt::format(
                   "set title '{}, {} rays/s, {} frames at 60 Hz, each the mean over the seeds'\n",
                   a.spec.name, rate_label(rate), a.frame_times.size())
            << "set xlabel 'display time (s)'\nset ylabel 'RMS error (0-255)'\n"
            << "set key outside right top\nset grid\nset yrange [0:*]\n"
            << "plot";
        for (size_t c = 0; c < methods.size(); ++c) {
          out << fmt::format("{} '{}' using 1:{} with lines lw 1.5 title '{}'", c ? "," : "",
                             dat.string(), c + 2, method_label(methods[c]));
        }
        out << '\n';
      }
      if (run_gnuplot(gp)) pngs.push_back(png);
    }
  }
  return pngs;
}

void draw_label(Image* image, int x, int y, const std::string& text, int size) {
  static const char* font = find_font();
  if (font == nullptr) return;
  OIIO::ImageSpec spec(image->width, image->height, 3, OIIO::TypeDesc::FLOAT);
  OIIO::ImageBuf buf(spec, image->pixels.data());
  const float white[3] = {1.0f, 1.0f, 1.0f};
  OIIO::ImageBufAlgo::render_text(buf, x, y, text, size, font, white);
}

std::vector<std::filesystem::path> write_strips(const std::vector<AnimationResult>& results,
                                                const std::filesystem::path& folder) {
  constexpr int kBand = 20, kGap = 2;
  std::vector<std::filesystem::path> files;
  for (const AnimationResult& a : results) {
    if (a.ideal_strip_images.empty()) continue;
    for (double rate : rates_of(a)) {
      std::vector<const RunResult*> runs;
      for (Method m : all_methods()) {
        if (const RunResult* r = find_run(a, m, rate)) runs.push_back(r);
      }
      const Image& first = a.ideal_strip_images.begin()->second;
      const int w = first.width, h = first.height;
      const int columns = 1 + int(runs.size()), rows = int(a.ideal_strip_images.size());
      Image strip(columns * (w + kGap) - kGap, kBand + rows * (h + kGap) - kGap, glm::vec3(0.02f));
      int row = 0;
      for (const auto& [frame, ideal] : a.ideal_strip_images) {
        for (int c = 0; c < columns; ++c) {
          const Image* img = c == 0 ? &ideal : nullptr;
          if (c > 0) {
            const auto it = runs[size_t(c - 1)]->strip_images.find(frame);
            if (it != runs[size_t(c - 1)]->strip_images.end()) img = &it->second;
          }
          if (img == nullptr || img->width != w || img->height != h) continue;
          const int x0 = c * (w + kGap), y0 = kBand + row * (h + kGap);
          for (int y = 0; y < h; ++y) {
            for (int x = 0; x < w; ++x) strip.at(x0 + x, y0 + y) = img->at(x, y);
          }
          if (c == 0) {
            draw_label(&strip, x0 + 4, y0 + h - 6,
                       fmt::format("t = {:.3f} s", a.frame_times[size_t(frame)]), 12);
          } else {
            draw_label(&strip, x0 + 4, y0 + h - 6,
                       fmt::format("RMS {:.1f}", runs[size_t(c - 1)]->rms[size_t(frame)]), 12);
          }
        }
        ++row;
      }
      for (int c = 0; c < columns; ++c) {
        draw_label(
            &strip, c * (w + kGap) + 4, kBand - 6,
            c == 0 ? std::string("Ideal") : std::string(method_label(runs[size_t(c - 1)]->method)),
            12);
      }
      const std::filesystem::path file =
          folder / fmt::format("strip-{}-{}.png", safe(a.spec.name), rate_label(rate));
      std::filesystem::create_directories(folder);
      write_image(strip, file);
      files.push_back(file);
    }
  }
  return files;
}

}  // namespace afr::eval
