// The display wall's geometry (docs/wall.md): a grid of cells over the virtual display, one
// display node per cell, and the layout the lead display sends to samplers and followers.
// Plain logic, no I/O.
#pragma once

#include <afr/common/rect.h>
#include <afr/protocol/messages.h>

#include <cstdint>
#include <string>
#include <vector>

namespace afr::service {

struct WallGrid {
  int columns = 1;
  int rows = 1;
  // Pixels around each cell whose samples the node receives and reconstructs (not shown).
  // display_node sets it to the reconstructor's auto_viewport_margin() unless told otherwise
  // (docs/wall.md, "Margin").
  int margin = 0;

  bool is_wall() const { return columns * rows > 1; }
  // The cell at (column, row) of a width x height virtual display: columns split the width
  // as evenly as integers allow (the first cells are never wider than the last).
  PixelRect cell(int column, int row, int width, int height) const;
};

// "CxR" -> columns, rows; "C,R" -> column, row. Throw afr::Error naming the text.
WallGrid parse_wall_grid(const std::string& text);
void parse_wall_cell(const std::string& text, int* column, int* row);

// Checks a grid against an image (every cell at least 1 x 1, at most 32 x 32 cells, the margin
// in 0..kMaxWallMargin) and a cell against the grid. Throw afr::Error naming the problem.
void check_wall_grid(const WallGrid& grid, int width, int height);
void check_wall_cell(const WallGrid& grid, int column, int row);

}  // namespace afr::service
