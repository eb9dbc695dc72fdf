#include <afr/display/service/wall_exchange.h>

#include <afr/common/error.h>
#include <afr/display/reprojection.h>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>

namespace afr::service {

namespace {

// Squared distance between the centers of two rectangles, in doubled pixels (integers).
int64_t center_distance2(const PixelRect& a, const PixelRect& b) {
  const int64_t dx = int64_t(a.x0) + a.x1 - b.x0 - b.x1, dy = int64_t(a.y0) + a.y1 - b.y0 - b.y1;
  return dx * dx + dy * dy;
}

// Strays of one peer travel in batches of one field set whose times span at most this many
// seconds, so that the batch encoding's 15-bit time ticks are at most 2^-17 s (7.6 us; docs/
// protocol.md, "Sample batch"). Strays are old samples of seconds of the store, so a shorter
// span would cut an image's strays into dozens of small messages.
constexpr double kMaxStrayBatchSpan = 0.25;
// Messages to peers stay small, so that what waits in the queues below stays a few MB per
// peer: stray batches of at most 8192 samples (350 kB), coverage strips of at most 2^16
// pixels (512 kB).
constexpr size_t kMaxStrayBatch = 8192;
constexpr uint32_t kMaxCoverageStrip = 1u << 16;

// The sample channel's options with a longer queue of the sender's own (64 messages, at most
// 32 MB per peer): an image's coverage and strays go out as a burst of a few messages per
// peer, which a busy peer takes only between its own images.
protocol::ChannelOptions peer_channel() {
  protocol::ChannelOptions o = protocol::ChannelOptions::samples();
  o.sender_queue = 64;
  return o;
}

}  // namespace

size_t WallOutbox::stray_samples() const {
  size_t n = 0;
  for (const auto& batches : strays) {
    for (const SampleBatch& b : batches) n += b.samples.size();
  }
  return n;
}

WallExchange::WallExchange(const protocol::WallLayout& layout, uint32_t node_id, int lookahead,
                           int coverage_band)
    : width_(layout.image.width),
      height_(layout.image.height),
      node_id_(node_id),
      lookahead_(std::max(lookahead, 0)) {
  const auto self = std::find_if(layout.nodes.begin(), layout.nodes.end(),
                                 [&](const protocol::WallNode& n) { return n.node_id == node_id; });
  if (self == layout.nodes.end()) {
    throw Error(fmt::format("wall exchange: node {} is not in the layout", node_id));
  }
  cell_ = self->cell;
  for (const protocol::WallNode& n : layout.nodes) {
    if (n.node_id == node_id) continue;
    WallPeer p;
    p.node_id = n.node_id;
    p.cell = n.cell;
    p.received = protocol::wall_receive_rect(layout, n);
    p.coverage_rect = intersect(cell_, p.received);
    if (coverage_band >= 0) {
      const PixelRect& c = n.cell;
      p.coverage_rect =
          intersect(p.coverage_rect, PixelRect{c.x0 - coverage_band, c.y0 - coverage_band,
                                               c.x1 + coverage_band, c.y1 + coverage_band});
    }
    if (!p.coverage_rect.empty()) peers_.push_back(p);
  }
  std::stable_sort(peers_.begin(), peers_.end(), [&](const WallPeer& a, const WallPeer& b) {
    return center_distance2(a.cell, cell_) < center_distance2(b.cell, cell_);
  });
  if (peers_.size() > kMaxPeers) peers_.resize(kMaxPeers);
}

void WallExchange::collect(Reconstructor& recon, const Camera& camera, double time, bool scale_one,
                           WallOutbox* out) {
  out->coverage.clear();
  out->strays.assign(peers_.size(), {});
  if (peers_.empty()) return;
  if (scale_one) {
    for (size_t k = 0; k < peers_.size(); ++k) {
      WallOutbox::Coverage c;
      c.peer = k;
      c.rect = peers_[k].coverage_rect;
      if (recon.read_coverage(c.rect, &c.cells)) out->coverage.push_back(std::move(c));
    }
  }
  find_strays(recon.stored_samples(), camera, time, out);
}

void WallExchange::find_strays(const Reconstructor::StoredSlots& stored, const Camera& camera,
                               double time, WallOutbox* out) {
  if (stored.size == 0) return;
  if (sent_.size() != stored.size) {
    sent_.assign(stored.size, 0);
    seen_end_ = stored.end - stored.stored;
  }
  const Projector projector(camera, width_, height_);
  const float lo_x = float(cell_.x0), hi_x = float(cell_.x1);
  const float lo_y = float(cell_.y0), hi_y = float(cell_.y1);
  const float look = float(lookahead_);
  for (uint64_t q = stored.end - stored.stored; q < stored.end; ++q) {
    const size_t slot = size_t(q % stored.size);
    if (q >= seen_end_) sent_[slot] = 0;  // a new sample in this slot
    const StoredSample& s = stored.slots[slot];
    // Each sample has one owner, the node whose cell it was traced in.
    if (!(s.flags & kStoredHasPosition) ||
        !(s.x >= lo_x && s.x < hi_x && s.y >= lo_y && s.y < hi_y)) {
      continue;
    }
    float x = 0.0f, y = 0.0f;
    if (!projector.project(s, float(time - s.time), &x, &y)) continue;
    for (size_t k = 0; k < peers_.size(); ++k) {
      const uint8_t bit = uint8_t(1u << k);
      if (sent_[slot] & bit) continue;
      const PixelRect& r = peers_[k].received;
      if (s.x >= float(r.x0) && s.x < float(r.x1) && s.y >= float(r.y0) && s.y < float(r.y1)) {
        continue;  // the samplers sent it there
      }
      if (!(x >= float(r.x0) - look && x < float(r.x1) + look && y >= float(r.y0) - look &&
            y < float(r.y1) + look)) {
        continue;
      }
      sent_[slot] |= bit;
      const uint32_t fields = stored_fields(s);
      std::vector<SampleBatch>& batches = out->strays[k];
      SampleBatch* b = nullptr;
      for (auto it = batches.rbegin(); it != batches.rend(); ++it) {
        if (it->fields == fields) {
          b = &*it;
          break;
        }
      }
      if (b == nullptr || b->samples.size() >= kMaxStrayBatch ||
          std::abs(s.time - b->samples.front().time) > kMaxStrayBatchSpan) {
        batches.emplace_back();
        b = &batches.back();
        b->sampler_id = protocol::kWallPeerSamplerId;
        b->fields = fields;
      }
      b->samples.push_back(restored_sample(s));
    }
  }
  seen_end_ = stored.end;
}

// ---------------------------------------------------------------------------------------------
// WallCoverageInbox

void WallCoverageInbox::put(protocol::WallCoverage&& coverage) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (pending_.size() >= kMaxPending) {
    pending_.erase(pending_.begin());
    ++dropped_;
  }
  pending_.push_back(std::move(coverage));
}

void WallCoverageInbox::take(std::vector<protocol::WallCoverage>* out) {
  out->clear();
  std::lock_guard<std::mutex> lock(mutex_);
  out->swap(pending_);
}

uint64_t WallCoverageInbox::dropped() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return dropped_;
}

// ---------------------------------------------------------------------------------------------
// WallPeerLinks

WallPeerLinks::WallPeerLinks(protocol::Context& context, protocol::Security security,
                             std::string lead_samples, int coverage_band, int lookahead)
    : context_(context),
      security_(std::move(security)),
      lead_samples_(std::move(lead_samples)),
      coverage_band_(coverage_band),
      lookahead_(lookahead) {}

WallPeerLinks::~WallPeerLinks() = default;

void WallPeerLinks::set_layout(const protocol::WallLayout& layout, uint32_t node_id) {
  if (have_epoch_ && layout.epoch == epoch_) return;
  have_epoch_ = true;
  epoch_ = layout.epoch;
  for (const auto& s : senders_) {
    if (s == nullptr) continue;
    retired_bytes_ += s->counters().bytes_sent;
    retired_dropped_ += s->counters().batches_dropped + s->counters().coverage_dropped;
  }
  senders_.clear();
  exchange_.reset();
  const bool named = std::any_of(layout.nodes.begin(), layout.nodes.end(),
                                 [&](const protocol::WallNode& n) { return n.node_id == node_id; });
  if (layout.nodes.size() < 2 || !named) return;
  exchange_ = std::make_unique<WallExchange>(layout, node_id, lookahead_, coverage_band_);
  bounds_ = layout.image;
  for (const WallPeer& p : exchange_->peers()) {
    const auto node =
        std::find_if(layout.nodes.begin(), layout.nodes.end(),
                     [&](const protocol::WallNode& n) { return n.node_id == p.node_id; });
    const std::string endpoint =
        node->samples_endpoint.empty() ? lead_samples_ : node->samples_endpoint;
    if (endpoint.empty()) {
      senders_.push_back(nullptr);
      continue;
    }
    try {
      senders_.push_back(
          std::make_unique<protocol::SampleSender>(context_, endpoint, security_, peer_channel()));
    } catch (const std::exception& e) {
      spdlog::warn("wall exchange: no link to node {} at {}: {}", p.node_id, endpoint, e.what());
      senders_.push_back(nullptr);
    }
  }
  spdlog::info("wall exchange: epoch {}, {} peers of node {}", layout.epoch,
               exchange_->peers().size(), node_id);
}

uint64_t WallPeerLinks::apply(WallCoverageInbox& inbox, Reconstructor& recon) {
  for (const auto& s : senders_) {
    if (s != nullptr) s->pump();  // what the peers' queues did not take after the last image
  }
  inbox.take(&arrived_);
  uint64_t applied = 0;
  for (const protocol::WallCoverage& c : arrived_) {
    cells_.resize(c.cells.size() / 2);
    static_assert(sizeof(CoverageCell) == 2 * sizeof(float));
    std::copy_n(c.cells.data(), cells_.size() * 2, &cells_.data()->count);
    // This node's own cell is its to compute: a rectangle there (from a peer still on an older
    // layout) is ignored. Elsewhere the newest arrival wins.
    if (exchange_ == nullptr || !intersect(c.rect, exchange_->cell()).empty()) continue;
    applied += recon.write_coverage(c.rect, cells_);
  }
  return applied;
}

void WallPeerLinks::send(Reconstructor& recon, const Camera& camera, double time, bool scale_one,
                         uint64_t applied, ServiceMetrics& metrics) {
  if (exchange_ == nullptr) return;
  exchange_->collect(recon, camera, time, scale_one, &outbox_);
  const std::vector<WallPeer>& peers = exchange_->peers();
  const uint32_t self = exchange_->node_id();
  uint64_t coverage_out = 0, cells_out = 0, strays_out = 0;
  for (const WallOutbox::Coverage& c : outbox_.coverage) {
    protocol::SampleSender* sender = senders_[c.peer].get();
    if (sender == nullptr) continue;
    // In strips of at most kMaxCoverageStrip pixels (a row is at most 32768 < 2^16).
    const int32_t rows =
        std::max<int32_t>(1, int32_t(kMaxCoverageStrip / uint32_t(std::max(c.rect.width(), 1))));
    for (int32_t y0 = c.rect.y0; y0 < c.rect.y1; y0 += rows) {
      const int32_t y1 = std::min(c.rect.y1, y0 + rows);
      message_.node_id = self;
      message_.time = time;
      message_.rect = PixelRect{c.rect.x0, y0, c.rect.x1, y1};
      const size_t first = size_t(y0 - c.rect.y0) * size_t(c.rect.width());
      const size_t n = size_t(y1 - y0) * size_t(c.rect.width());
      message_.cells.resize(2 * n);
      std::copy_n(&c.cells[first].count, 2 * n, message_.cells.data());
      if (protocol::Status st = sender->send(message_, bounds_); !st) {
        spdlog::error("wall exchange: coverage for node {}: {}", peers[c.peer].node_id,
                      st.message());
        continue;
      }
      ++coverage_out;
      cells_out += n;
    }
  }
  for (size_t k = 0; k < peers.size(); ++k) {
    protocol::SampleSender* sender = senders_[k].get();
    if (sender == nullptr) continue;
    for (const SampleBatch& b : outbox_.strays[k]) {
      if (protocol::Status st = sender->send(b, bounds_); !st) {
        spdlog::error("wall exchange: strays for node {}: {}", peers[k].node_id, st.message());
        continue;
      }
      strays_out += b.samples.size();
    }
  }
  uint64_t bytes = retired_bytes_, dropped = retired_dropped_;
  for (size_t k = 0; k < senders_.size(); ++k) {
    protocol::SampleSender* s = senders_[k].get();
    if (s == nullptr) continue;
    s->pump();
    bytes += s->counters().bytes_sent;
    const uint64_t d = s->counters().batches_dropped + s->counters().coverage_dropped;
    dropped += d;
    if (d > 0 && d >= 2 * warned_drops_) {  // at 1, 2, 4, 8, ... drops
      warned_drops_ = d;
      spdlog::warn("wall exchange: node {} takes messages slower than they come: {} dropped",
                   peers[k].node_id, d);
    }
  }
  metrics.on_wall_exchanged(applied, coverage_out, cells_out, strays_out, bytes, dropped);
}

}  // namespace afr::service
