// The part a display node plays in the service, as its frame loop (DisplayApp) sees it. Two
// roles implement it: the lead (or only) display, DisplayService, which owns the clock, the
// scene, the camera and the coordinator; and a follower of a wall's lead, WallFollower, which
// learns all of these from the lead. The frame loop asks the role for the time and camera of
// each image, reports into its metrics, and runs the wall exchange on its layout.
#pragma once

#include <afr/common/camera.h>
#include <afr/common/rect.h>
#include <afr/protocol/messages.h>

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace afr::service {

class ServiceMetrics;
class SnapshotQueue;
class WallCoverageInbox;

// The wall as one node of it sees it: the layout and the node's own id in it.
struct WallPosition {
  protocol::WallLayout layout;
  uint32_t node_id = 0;
};

class DisplayRole {
 public:
  virtual ~DisplayRole() = default;

  // The display clock: seconds of display time (the lead's clock on a follower).
  virtual double now() const = 0;
  // The camera of the image at display time t.
  virtual Camera camera_at(double t) const = 0;
  // The pixels this node shows, in whole-image coordinates (the whole image without a wall).
  virtual PixelRect cell() const = 0;
  virtual ServiceMetrics& metrics() = 0;
  // The session the metrics name (0 on a follower: the session is the lead's).
  virtual uint64_t session() const = 0;
  // The coordinator's regions by sampler id, for the tiling overlay (none on a follower).
  virtual std::vector<std::pair<uint32_t, PixelRect>> regions() const = 0;
  // The wall this node is part of: the current layout and its id in it (nullopt while it has
  // none); the coverage its peers sent; the lead's sample endpoint ("" on the lead itself).
  virtual std::optional<WallPosition> wall_position() const = 0;
  virtual WallCoverageInbox& wall_coverage() = 0;
  virtual std::string lead_samples_endpoint() const = 0;
  // Snapshots this node is asked to write (snapshots.h): the lead's own, a follower's from the
  // lead.
  virtual SnapshotQueue& snapshots() = 0;
  // True once the role cannot go on (a follower the lead refused for good).
  virtual bool failed() const = 0;
  // Tells the peers (samplers leave, a follower leaves the lead) and joins the threads.
  virtual void stop() = 0;
};

}  // namespace afr::service
