// The K-D tiling of section 4: a K-D tree over the sampler's owned region whose leaves are the
// current tiles (the "cut"). Splitting a tile halves it across its longer side; merging
// replaces two sibling leaves by their parent. The leaves always partition the region exactly.
// This class holds only the geometry; statistics live with the sampler.
#pragma once

#include <afr/common/rect.h>

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

    bool is_leaf() const { return child[0] == -1; }
  };

  // One tile covering `region` (non-empty). Tiles never get deeper than max_depth.
  KdTiling(PixelRect region, int max_depth = 40);

  const PixelRect& region() const { return node(root_).rect; }
  // Node ids of the current tiles, in no particular order.
  const std::vector<int>& tiles() const { return tiles_; }
  int tile_count() const { return int(tiles_.size()); }
  const Node& node(int id) const { return nodes_[id]; }
  // Node ids are below this bound (ids of merged-away nodes are reused).
  int node_capacity() const { return int(nodes_.size()); }
  int root() const { return root_; }

  // The tile containing pixel (x, y), which must lie in the region. O(depth).
  int tile_at(int32_t x, int32_t y) const;

  // A leaf can split if it is wider or taller than one pixel and above the depth bound.
  bool can_split(int leaf) const;
  // Splits a leaf across its longer side (x on ties) at the middle; returns the two new leaves.
  void split(int leaf, int* first, int* second);
  // An internal node whose two children are both leaves can merge back into one leaf.
  bool can_merge(int parent) const;
  // Merges the two leaf children of `parent`, which becomes a leaf again.
  void merge(int parent);
  // Internal nodes whose children are both leaves: the candidates for merge().
  const std::vector<int>& mergeable() const { return mergeable_; }

  // Checks the invariants (the leaves partition the region, links agree); for tests.
  bool is_valid() const;

 private:
  int allocate(const PixelRect& rect, int parent, int depth);
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
};

}  // namespace afr
