// The display wall's routing: which samples and tiles a node needs (docs/wall.md).
#include <afr/protocol/messages.h>

#include <algorithm>

namespace afr::protocol {

PixelRect wall_receive_rect(const WallLayout& layout, const WallNode& node) {
  return PixelRect{std::max(0, node.cell.x0 - layout.margin),
                   std::max(0, node.cell.y0 - layout.margin),
                   std::min(layout.image.width, node.cell.x1 + layout.margin),
                   std::min(layout.image.height, node.cell.y1 + layout.margin)};
}

void select_samples(const SampleBatch& batch, const PixelRect& rect, SampleBatch* out) {
  out->sampler_id = batch.sampler_id;
  out->token = batch.token;
  out->sequence = batch.sequence;
  out->fields = batch.fields;
  out->samples.clear();
  const float x0 = float(rect.x0), x1 = float(rect.x1), y0 = float(rect.y0), y1 = float(rect.y1);
  for (const Sample& s : batch.samples) {
    if (s.x >= x0 && s.x < x1 && s.y >= y0 && s.y < y1) out->samples.push_back(s);
  }
}

void select_tiles(const TilingSnapshot& snapshot, const PixelRect& rect, TilingSnapshot* out) {
  out->sampler_id = snapshot.sampler_id;
  out->token = snapshot.token;
  out->time = snapshot.time;
  out->region = snapshot.region;
  out->tiles.clear();
  for (const TileInfo& t : snapshot.tiles) {
    if (t.rect.x0 < rect.x1 && rect.x0 < t.rect.x1 && t.rect.y0 < rect.y1 && rect.y0 < t.rect.y1) {
      out->tiles.push_back(t);
    }
  }
}

}  // namespace afr::protocol
