#include <afr/display/service/wall.h>

#include <afr/common/error.h>

#include <fmt/format.h>

#include <cstdio>

namespace afr::service {

PixelRect WallGrid::cell(int column, int row, int width, int height) const {
  const auto split = [](int i, int n, int size) { return int32_t(int64_t(i) * size / n); };
  return PixelRect{split(column, columns, width), split(row, rows, height),
                   split(column + 1, columns, width), split(row + 1, rows, height)};
}

WallGrid parse_wall_grid(const std::string& text) {
  WallGrid g;
  char x = 0, extra = 0;
  if (std::sscanf(text.c_str(), "%d%c%d%c", &g.columns, &x, &g.rows, &extra) != 3 ||
      (x != 'x' && x != 'X')) {
    throw Error(fmt::format("--wall '{}': expected COLUMNSxROWS, e.g. 2x2", text));
  }
  return g;
}

void parse_wall_cell(const std::string& text, int* column, int* row) {
  char comma = 0, extra = 0;
  if (std::sscanf(text.c_str(), "%d%c%d%c", column, &comma, row, &extra) != 3 || comma != ',') {
    throw Error(fmt::format("--cell '{}': expected COLUMN,ROW, e.g. 1,0", text));
  }
}

void check_wall_grid(const WallGrid& g, int width, int height) {
  if (g.columns < 1 || g.rows < 1 || g.columns > 32 || g.rows > 32) {
    throw Error(fmt::format("--wall {}x{}: columns and rows must be in 1..32", g.columns, g.rows));
  }
  if (g.columns > width || g.rows > height) {
    throw Error(fmt::format("--wall {}x{}: more cells than pixels of the {}x{} display", g.columns,
                            g.rows, width, height));
  }
  if (g.margin < 0 || g.margin > protocol::kMaxWallMargin) {
    throw Error(fmt::format("--margin {}: must be in 0..{}", g.margin, protocol::kMaxWallMargin));
  }
}

void check_wall_cell(const WallGrid& g, int column, int row) {
  if (column < 0 || row < 0 || column >= g.columns || row >= g.rows) {
    throw Error(
        fmt::format("cell {},{} is outside the {}x{} wall", column, row, g.columns, g.rows));
  }
}

}  // namespace afr::service
