// The K-D tiling of section 4: a K-D tree over the sampler's owned region whose leaves are the
// current tiles (the "cut"). Splitting a tile halves it across its longer side; merging
// replaces two sibling leaves by their parent. The leaves always partition the region exactly.
// This class holds only the geometry; statistics live with the sampler. Optionally it also
// divides the region into cells, the nodes of one depth of the complete tree, so that the
// sampler can keep statistics per cell and sum a new tile's block from its cells.
#pragma once

#include <afr/common/rect.h>

#include <cstddef>
#include <cstdint>
#include <vector>

namespace afr {

class KdTiling {
 public:
  struct Node {
    PixelRect rect;
    int parent = -1;
    int child[2] = {-1, -1};  // both -1 for a leaf
    int depth = 0;
    int leaf_slot = -1;  // position in tiles() while a leaf, else -1
    uint64_t path = 0;   // position among the nodes of its depth, left to right: children 2p, 2p+1

    bool is_leaf() const { return child[0] == -1; }
  };

  // One tile covering `region` (non-empty). Tiles never get deeper than max_depth. With
  // cell_pixels > 0 the region is also divided into cells of about that many pixels (at least
  // cell_pixels / 2), which costs 20 bytes per cell and nothing per pixel.
  KdTiling(PixelRect region, int max_depth = 40, int cell_pixels = 0);

  const PixelRect& region() const { return node(root_).rect; }
  // Node ids of the current tiles, in no particular order.
  const std::vector<int>& tiles() const { return tiles_; }
  int tile_count() const { return int(tiles_.size()); }
  const Node& node(int id) const { return nodes_[id]; }
  // Node ids are below this bound (ids of merged-away nodes are reused).
  int node_capacity() const { return int(nodes_.size()); }
  int root() const { return root_; }

  // The tile containing pixel (x, y), which must lie in the region, and when `cell` is given
  // the pixel's cell (see cell_at) as well. O(depth).
  int tile_at(int32_t x, int32_t y, int* cell = nullptr) const;

  // A leaf can split if it is wider or taller than one pixel and above the depth bound.
  bool can_split(int leaf) const {
    const Node& n = nodes_[leaf];
    return n.is_leaf() && n.depth < max_depth_ && (n.rect.width() > 1 || n.rect.height() > 1);
  }
  // Splits a leaf across its longer side (x on ties) at the middle; returns the two new leaves.
  void split(int leaf, int* first, int* second);
  // An internal node whose two children are both leaves can merge back into one leaf.
  bool can_merge(int parent) const;
  // Merges the two leaf children of `parent`, which becomes a leaf again.
  void merge(int parent);
  // Internal nodes whose children are both leaves: the candidates for merge().
  const std::vector<int>& mergeable() const { return mergeable_; }

  // How a rectangle is split: across its longer side (x on ties) at the middle.
  static void split_rect(const PixelRect& r, PixelRect* first, PixelRect* second);

  // Cells: the nodes at depth cell_depth() of the complete tree that splitting grows, numbered
  // by their path. A node no deeper than that is exactly the cells
  // [first_cell(id), first_cell(id) + cells_in(id)). Without cells there is one, the region.
  int cell_count() const { return int(cell_rects_.size()); }
  int cell_depth() const { return cell_depth_; }
  const PixelRect& cell_rect(int cell) const { return cell_rects_[size_t(cell)]; }
  // The cell of pixel (x, y) of the region: the path of the splits from the root down to cell
  // depth that keep the pixel, computed rather than stored. O(cell_depth()).
  int cell_at(int32_t x, int32_t y) const { return descend(region(), 0, cell_depth_, x, y); }
  // The cell of pixel (x, y) of node `id`, which holds it: from the node down, or for a node
  // deeper than the cells its ancestor's path.
  int cell_of(int id, int32_t x, int32_t y) const {
    const Node& n = nodes_[id];
    if (n.depth >= cell_depth_) return int(n.path >> (n.depth - cell_depth_));
    return descend(n.rect, int(n.path), cell_depth_ - n.depth, x, y);
  }
  bool covers_cells(int id) const { return nodes_[id].depth <= cell_depth_; }
  int first_cell(int id) const { return int(nodes_[id].path << (cell_depth_ - nodes_[id].depth)); }
  int cells_in(int id) const { return 1 << (cell_depth_ - nodes_[id].depth); }

  // Checks the invariants (the leaves partition the region, links agree); for tests.
  bool is_valid() const;

 private:
  // The path `levels` splits below a node of rectangle r and path `path` that keep (x, y).
  static int descend(PixelRect r, int path, int levels, int32_t x, int32_t y) {
    for (int d = 0; d < levels; ++d) {
      int side;
      if (r.width() >= r.height()) {  // as split_rect
        const int32_t mid = r.x0 + r.width() / 2;
        side = x >= mid;
        (side ? r.x0 : r.x1) = mid;
      } else {
        const int32_t mid = r.y0 + r.height() / 2;
        side = y >= mid;
        (side ? r.y0 : r.y1) = mid;
      }
      path = 2 * path + side;
    }
    return path;
  }
  int allocate(const PixelRect& rect, int parent, int depth, uint64_t path);
  void build_cells(int cell_pixels);
  void set_cell_node(int id);
  void release(int id);
  void add_leaf(int id);
  void remove_leaf(int id);
  void update_mergeable(int id);

  std::vector<Node> nodes_;
  std::vector<int> free_;
  std::vector<int> tiles_;
  std::vector<int> mergeable_;
  std::vector<int> mergeable_slot_;  // per node: position in mergeable_, or -1
  int root_ = -1;
  int max_depth_;
  int cell_depth_ = 0;
  std::vector<PixelRect> cell_rects_;  // by cell
  // By cell: the leaf that covers it when that is no deeper than the cells, else the node at
  // cell depth that is the cell; tile_at descends from there.
  std::vector<int> cell_node_;  // empty without cells
};

}  // namespace afr
