// What the nodes of a display wall send each other so that the wall reconstructs what one
// display of the whole size would (docs/wall.md, "Seams"). Routing by margin alone is not
// enough for that: a node lacks what lies beyond its received region, and the reconstruction
// carries that inward from image to image. Two things carry it, and each node sends its
// neighbours both after every image:
//   - its coverage (section 6.2's map) over the part of its cell that lies in a neighbour's
//     received region: the neighbour sizes the next image's splats there from it instead of
//     from its own, which lacks the samples beyond its margin;
//   - strays: the samples traced in its cell that the current view now projects into (or
//     near) a neighbour's received region, although the samplers did not send them there
//     (they route by where a sample was traced); each once.
// Plain logic over a reconstructor, no I/O: the display node sends and applies what it gives.
#pragma once

#include <afr/common/camera.h>
#include <afr/common/rect.h>
#include <afr/common/samples.h>
#include <afr/display/reconstructor.h>
#include <afr/display/service/metrics.h>
#include <afr/protocol/channels.h>
#include <afr/protocol/messages.h>

#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace afr::service {

// A neighbour of this node in the layout.
struct WallPeer {
  uint32_t node_id = 0;
  PixelRect cell;
  PixelRect received;  // what the samplers send it: its cell grown by the margin
  // The part of this node's cell within the coverage band of the peer's cell and inside
  // `received`: the coverage it is sent.
  PixelRect coverage_rect;
};

// What one image gives to send: per peer (the index in peers()), coverage and strays.
struct WallOutbox {
  struct Coverage {
    size_t peer = 0;
    PixelRect rect;  // output pixels of the whole image (= sampling pixels at scale 1)
    std::vector<CoverageCell> cells;
  };
  std::vector<Coverage> coverage;
  // strays[peer]: batches of one field set each (a batch's samples share their fields), cut
  // by count and time span to keep messages small.
  std::vector<std::vector<SampleBatch>> strays;
  size_t stray_samples() const;
};

class WallExchange {
 public:
  // Strays are sent once they project within this many pixels of a peer's received region:
  // one refresh ahead of when they can splat into it, for views that move less than this per
  // refresh (the peer receives them only for its next image).
  static constexpr int kDefaultLookahead = 16;
  // A node forwards to at most this many peers (its neighbours in the grid, diagonal ones
  // included): a per-sample byte marks which were sent a sample.
  static constexpr size_t kMaxPeers = 8;
  // Coverage is sent for this many pixels around the peer's cell (not the whole margin):
  // what sizes the splats that reach the peer's cell is the coverage where they land, at most
  // one splat's reach away, splat_guard_band() = 33 px for the default splat sizes. (Measured
  // in the seam test: the same images as with the whole margin, at a third of the traffic;
  // docs/wall.md, "Seams".) -1: the whole part of the cell the peer receives.
  static constexpr int kDefaultCoverageBand = 33;

  // This node is `node_id` of `layout`. Its peers are the nodes whose received regions reach
  // its cell, nearest first (at most kMaxPeers). Throws afr::Error when the layout does not
  // name node_id.
  WallExchange(const protocol::WallLayout& layout, uint32_t node_id,
               int lookahead = kDefaultLookahead, int coverage_band = kDefaultCoverageBand);

  const std::vector<WallPeer>& peers() const { return peers_; }
  const PixelRect& cell() const { return cell_; }
  uint32_t node_id() const { return node_id_; }

  // After reconstruct(camera, time, ...) of this node's cell at scale 1 (output size = cell
  // size; otherwise no coverage is given, as the peers' pixels would not match): fills *out
  // with what to send. `recon` is this node's reconstructor.
  void collect(Reconstructor& recon, const Camera& camera, double time, bool scale_one,
               WallOutbox* out);

 private:
  void find_strays(const Reconstructor::StoredSlots& stored, const Camera& camera, double time,
                   WallOutbox* out);

  int32_t width_ = 0, height_ = 0;  // the virtual display
  uint32_t node_id_ = 0;
  PixelRect cell_;
  int lookahead_ = kDefaultLookahead;
  std::vector<WallPeer> peers_;
  // Per ring slot: bit k set when peers_[k] was sent the sample in that slot.
  std::vector<uint8_t> sent_;
  uint64_t seen_end_ = 0;  // the ring's end at the last collect(): slots after it are new
};

// The coverage that peers sent, from the ingest thread (put) to the display thread (take).
// Holds at most kMaxPending messages (each at most 2 MiB; peers send strips of 512 kB); older
// ones are dropped (a newer image's map replaces them anyway).
class WallCoverageInbox {
 public:
  static constexpr size_t kMaxPending = 64;
  void put(protocol::WallCoverage&& coverage);
  // Moves everything pending into *out (oldest first).
  void take(std::vector<protocol::WallCoverage>* out);
  uint64_t dropped() const;

 private:
  mutable std::mutex mutex_;
  std::vector<protocol::WallCoverage> pending_;
  uint64_t dropped_ = 0;
};

// A display node's side of the exchange over the network: applies the peers' coverage before
// each image, and after it sends its own coverage and strays to each peer's sample channel
// (a SampleSender per peer, rebuilt when the layout changes). The display thread only.
class WallPeerLinks {
 public:
  // `security`: this node as a client of its peers' sample channels (the nodes of a wall share
  // the display's key pair). `lead_samples`: the lead's sample endpoint, which the layout
  // leaves empty (its own entry); "" on the lead itself.
  WallPeerLinks(protocol::Context& context, protocol::Security security, std::string lead_samples,
                int coverage_band = WallExchange::kDefaultCoverageBand,
                int lookahead = WallExchange::kDefaultLookahead);
  ~WallPeerLinks();

  // The current layout and this node's id in it; a layout of a new epoch rebuilds the
  // exchange and the links. A layout that does not name the node turns the exchange off.
  void set_layout(const protocol::WallLayout& layout, uint32_t node_id);
  bool active() const { return exchange_ != nullptr; }

  // Before reconstruct(): writes what arrived into the reconstructor. Returns the pixels that
  // replaced its own.
  uint64_t apply(WallCoverageInbox& inbox, Reconstructor& recon);
  // After reconstruct() at display time `time` with `camera`; scale_one: the image was the
  // cell at its own size (coverage in virtual-display pixels). Counts in `metrics`.
  void send(Reconstructor& recon, const Camera& camera, double time, bool scale_one,
            uint64_t applied, ServiceMetrics& metrics);

 private:
  protocol::Context& context_;
  protocol::Security security_;
  std::string lead_samples_;
  int coverage_band_;
  int lookahead_;
  uint64_t epoch_ = 0;
  bool have_epoch_ = false;
  std::unique_ptr<WallExchange> exchange_;
  std::vector<std::unique_ptr<protocol::SampleSender>> senders_;  // per peer
  ImageExtent bounds_ = protocol::kMaxImageExtent;
  WallOutbox outbox_;
  std::vector<protocol::WallCoverage> arrived_;
  std::vector<CoverageCell> cells_;
  protocol::WallCoverage message_;
  uint64_t retired_bytes_ = 0, retired_dropped_ = 0;  // of senders replaced
  uint64_t warned_drops_ = 0;
};

}  // namespace afr::service
