#include <afr/sampler/tiling.h>

#include <afr/common/check.h>

#include <algorithm>
#include <cstddef>

namespace afr {

KdTiling::KdTiling(PixelRect region, int max_depth, int cell_pixels) : max_depth_(max_depth) {
  AFR_CHECK(!region.empty());
  root_ = allocate(region, -1, 0, 0);
  add_leaf(root_);
  build_cells(cell_pixels);
}

void KdTiling::split_rect(const PixelRect& r, PixelRect* first, PixelRect* second) {
  *first = *second = r;
  if (r.width() >= r.height()) {
    first->x1 = second->x0 = r.x0 + r.width() / 2;
  } else {
    first->y1 = second->y0 = r.y0 + r.height() / 2;
  }
}

// The deepest level whose nodes all hold at least cell_pixels / 2 pixels (so all of them can
// split down to it), at most the tree's depth bound.
void KdTiling::build_cells(int cell_pixels) {
  const PixelRect region = this->region();
  cell_depth_ = 0;
  cell_rects_.assign(1, region);
  if (cell_pixels <= 0) return;
  while (cell_depth_ < std::min(max_depth_, 30)) {
    std::vector<PixelRect> next(cell_rects_.size() * 2);
    bool ok = true;
    for (size_t k = 0; k < cell_rects_.size() && ok; ++k) {
      split_rect(cell_rects_[k], &next[2 * k], &next[2 * k + 1]);
      ok = 2 * next[2 * k].area() >= cell_pixels && 2 * next[2 * k + 1].area() >= cell_pixels &&
           !next[2 * k].empty() && !next[2 * k + 1].empty();
    }
    if (!ok) break;
    cell_rects_ = std::move(next);
    ++cell_depth_;
  }
  cell_node_.assign(cell_rects_.size(), root_);
}

int KdTiling::allocate(const PixelRect& rect, int parent, int depth, uint64_t path) {
  int id;
  if (!free_.empty()) {
    id = free_.back();
    free_.pop_back();
  } else {
    id = int(nodes_.size());
    nodes_.emplace_back();
    mergeable_slot_.push_back(-1);
  }
  nodes_[id] = Node{rect, parent, {-1, -1}, depth, -1, path};
  return id;
}

void KdTiling::release(int id) { free_.push_back(id); }

void KdTiling::add_leaf(int id) {
  nodes_[id].leaf_slot = int(tiles_.size());
  tiles_.push_back(id);
}

void KdTiling::remove_leaf(int id) {
  const int slot = nodes_[id].leaf_slot;
  const int last = tiles_.back();
  tiles_[slot] = last;
  nodes_[last].leaf_slot = slot;
  tiles_.pop_back();
  nodes_[id].leaf_slot = -1;
}

// Keeps mergeable_ equal to the set of internal nodes whose children are both leaves.
void KdTiling::update_mergeable(int id) {
  if (id == -1) return;
  const bool should = can_merge(id);
  int& slot = mergeable_slot_[id];
  if (should && slot == -1) {
    slot = int(mergeable_.size());
    mergeable_.push_back(id);
  } else if (!should && slot != -1) {
    const int last = mergeable_.back();
    mergeable_[slot] = last;
    mergeable_slot_[last] = slot;
    mergeable_.pop_back();
    slot = -1;
  }
}

// Keeps cell_node_ pointing, for every cell under node `id` (no deeper than the cells), to `id`.
void KdTiling::set_cell_node(int id) {
  if (!covers_cells(id) || cell_node_.empty()) return;
  const int first = first_cell(id), n = cells_in(id);
  for (int c = first; c < first + n; ++c) cell_node_[size_t(c)] = id;
}

int KdTiling::tile_at(int32_t x, int32_t y, int* cell) const {
  AFR_DCHECK(region().contains(x, y));
  // From the node at the cut or at cell depth that holds the pixel's cell, when there are
  // cells; from the root otherwise.
  const int c = cell_at(x, y);
  if (cell) *cell = c;
  int id = cell_node_.empty() ? root_ : cell_node_[size_t(c)];
  while (!nodes_[id].is_leaf()) {
    const Node& n = nodes_[id];
    const int c = nodes_[n.child[0]].rect.contains(x, y) ? 0 : 1;
    id = n.child[c];
  }
  return id;
}

void KdTiling::split(int leaf, int* first, int* second) {
  AFR_CHECK(can_split(leaf));
  PixelRect a, b;
  split_rect(nodes_[leaf].rect, &a, &b);
  const int depth = nodes_[leaf].depth + 1;
  const uint64_t path = nodes_[leaf].path;
  const int ia = allocate(a, leaf, depth, 2 * path);
  const int ib = allocate(b, leaf, depth, 2 * path + 1);  // may reallocate nodes_: index again
  remove_leaf(leaf);
  nodes_[leaf].child[0] = ia;
  nodes_[leaf].child[1] = ib;
  add_leaf(ia);
  add_leaf(ib);
  set_cell_node(ia);
  set_cell_node(ib);
  update_mergeable(leaf);
  update_mergeable(nodes_[leaf].parent);
  if (first) *first = ia;
  if (second) *second = ib;
}

bool KdTiling::can_merge(int parent) const {
  const Node& n = nodes_[parent];
  return !n.is_leaf() && nodes_[n.child[0]].is_leaf() && nodes_[n.child[1]].is_leaf();
}

void KdTiling::merge(int parent) {
  AFR_CHECK(can_merge(parent));
  for (int c : nodes_[parent].child) {
    remove_leaf(c);
    release(c);
  }
  nodes_[parent].child[0] = nodes_[parent].child[1] = -1;
  add_leaf(parent);
  set_cell_node(parent);
  update_mergeable(parent);
  update_mergeable(nodes_[parent].parent);
}

bool KdTiling::is_valid() const {
  int64_t area = 0;
  for (std::size_t s = 0; s < tiles_.size(); ++s) {
    const Node& n = nodes_[tiles_[s]];
    if (!n.is_leaf() || n.leaf_slot != int(s) || n.rect.empty()) return false;
    if (!region().contains(n.rect.x0, n.rect.y0) ||
        !region().contains(n.rect.x1 - 1, n.rect.y1 - 1)) {
      return false;
    }
    area += n.rect.area();
  }
  if (area != region().area()) return false;
  // Walk the tree: children split their parent exactly, every reachable leaf is listed.
  std::vector<int> stack = {root_};
  std::size_t leaves = 0;
  while (!stack.empty()) {
    const int id = stack.back();
    stack.pop_back();
    const Node& n = nodes_[id];
    if (n.is_leaf()) {
      ++leaves;
      if (n.leaf_slot < 0 || tiles_[n.leaf_slot] != id) return false;
      continue;
    }
    const Node& a = nodes_[n.child[0]];
    const Node& b = nodes_[n.child[1]];
    if (a.parent != id || b.parent != id) return false;
    if (a.rect.area() + b.rect.area() != n.rect.area()) return false;
    const bool across_x = a.rect.x1 == b.rect.x0 && a.rect.y0 == b.rect.y0 &&
                          a.rect.y1 == b.rect.y1 && a.rect.x0 == n.rect.x0 &&
                          b.rect.x1 == n.rect.x1;
    const bool across_y = a.rect.y1 == b.rect.y0 && a.rect.x0 == b.rect.x0 &&
                          a.rect.x1 == b.rect.x1 && a.rect.y0 == n.rect.y0 &&
                          b.rect.y1 == n.rect.y1;
    if (!across_x && !across_y) return false;
    if ((mergeable_slot_[id] != -1) != can_merge(id)) return false;
    stack.push_back(n.child[0]);
    stack.push_back(n.child[1]);
  }
  return leaves == tiles_.size();
}

}  // namespace afr
