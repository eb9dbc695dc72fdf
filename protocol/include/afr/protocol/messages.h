// Every message that crosses a process in afr (DESIGN.md, "Network"), as plain structs, with
// the limits the decoder enforces. The byte layouts are in codec.h and docs/protocol.md; sample
// batches and tiling snapshots are the common types of afr/common/samples.h.
#pragma once

#include <afr/common/camera.h>
#include <afr/common/rect.h>
#include <afr/common/samples.h>

#include <array>
#include <cstdint>
#include <string>
#include <variant>
#include <vector>

namespace afr::protocol {

// ---------------------------------------------------------------------------------------------
// Versions and limits

// Bumped on every change of a byte layout; a peer of another version is refused (a decoder
// still reads the header of any version, so it can say why). Version 2 added the display wall
// (DisplayJoin, WallLayout), version 3 wall coverage, version 4 the member token (Welcome::token,
// carried by every sample batch and tiling snapshot), version 5 orthographic views
// (View::camera.ymag), version 6 the members' regions in the member list
// (MemberEntry::region).
inline constexpr uint16_t kProtocolVersion = 6;

inline constexpr int32_t kMaxImageSize = 32768;          // pixels a side (DESIGN.md, "Samples")
inline constexpr uint32_t kMaxSamplesPerBatch = 65536;   // the sampler's batch_size limit
inline constexpr uint32_t kMaxTilesPerSnapshot = 65536;  // far above any gain-control bound
inline constexpr uint32_t kMaxChunkBytes = 1u << 20;     // scene transfer chunk
inline constexpr uint64_t kMaxSceneBytes = 1ull << 32;   // 4 GiB
inline constexpr uint32_t kMaxNameBytes = 255;           // names, presets, leave texts
inline constexpr uint16_t kMaxThreads = 4096;
// A display wall: at most this many display nodes, and this many pixels of margin.
inline constexpr uint32_t kMaxWallNodes = 1024;
// Samplers a display admits at most (display_node --max-samplers), and so the entries of a
// member_list: 4096 entries of at most 54 bytes (a 40-character key) fit the control channel.
inline constexpr uint32_t kMaxMembers = 4096;
inline constexpr int32_t kMaxWallMargin = 1024;
// The sampler_id of sample batches one display node of a wall forwards to another (strays,
// docs/wall.md "Seams"): 0, which the coordinator never assigns to a sampler.
inline constexpr uint32_t kWallPeerSamplerId = 0;
// Pixels in one wall_coverage message (2 MiB of cells); larger rectangles go in strips.
inline constexpr uint32_t kMaxWallCoverageCells = 1u << 18;
// Batch time offsets are 15-bit ticks of 2^tick_exp seconds, tick_exp in this range: from
// about 1 ns ticks (a 30 us span) to 1 s ticks (a 9 h span).
inline constexpr int kMinTickExp = -30;
inline constexpr int kMaxTickExp = 0;
// A view's basis must be orthonormal to this tolerance.
inline constexpr double kBasisTolerance = 1e-3;
// refresh_interval of a welcome, seconds.
inline constexpr double kMaxRefreshInterval = 10.0;

enum class MessageType : uint16_t {
  kJoin = 1,
  kWelcome = 2,
  kSceneRequest = 3,
  kSceneChunk = 4,
  kRegionAssignment = 5,
  kView = 6,
  kSampleBatch = 7,
  kTilingSnapshot = 8,
  kStats = 9,
  kHeartbeat = 10,
  kLeave = 11,
  kDisplayJoin = 12,
  kWallLayout = 13,
  kWallCoverage = 14,
  kSnapshotRequest = 15,
  kMemberList = 16,
};
inline constexpr uint16_t kFirstMessageType = 1;
inline constexpr uint16_t kLastMessageType = 16;

// "join", "sample_batch", ...; "unknown" for values outside the enum.
const char* message_type_name(MessageType type);

// What a sampler can do (Join::capabilities). Unknown bits are rejected.
enum Capability : uint32_t {
  kCapWorldPosition = 1u << 0,  // can send world positions (reprojection at the display)
  kCapVelocity = 1u << 1,       // can send per-sample velocities
  kCapTilings = 1u << 2,        // sends tiling snapshots (adaptive mode)
  kCapSceneCache = 1u << 3,     // keeps received scenes by hash
};
inline constexpr uint32_t kKnownCapabilities =
    kCapWorldPosition | kCapVelocity | kCapTilings | kCapSceneCache;
inline constexpr uint32_t kKnownSampleFields = kFieldPosition | kFieldVelocity;

// A content hash (BLAKE2b-256 of the scene file's bytes, scene_hash.h).
using SceneHash = std::array<uint8_t, 32>;

// ---------------------------------------------------------------------------------------------
// Control channel (ROUTER/DEALER): membership, scene and region

// sampler -> display, first message of a sampler.
struct Join {
  // The id this sampler had before a reconnect, or 0. A hint the display may ignore (afr's does:
  // it assigns every id itself; the welcome says which).
  uint32_t sampler_id = 0;
  uint16_t protocol_version = kProtocolVersion;
  uint16_t threads = 1;       // 1..kMaxThreads
  uint32_t capabilities = 0;  // Capability bits
  std::string name;           // host or user-chosen name, for logs and the HUD
  bool operator==(const Join&) const = default;
};

// display -> sampler, the answer to a join.
struct Welcome {
  uint32_t sampler_id = 0;        // assigned, >= 1
  uint64_t session = 0;           // random per display run, != 0; a new value means a restart
  ImageExtent image;              // 1..kMaxImageSize a side
  double display_time = 0.0;      // display clock, seconds, when the welcome was sent
  double refresh_interval = 0.0;  // seconds between tiling snapshots, (0, kMaxRefreshInterval]
  SceneHash scene_hash{};
  uint64_t scene_size = 0;  // bytes, 1..kMaxSceneBytes
  // Random per membership, != 0, known only to the display and this member: the member puts it
  // in every sample batch and tiling snapshot, and the display drops those whose token is not
  // the one of the member their sampler_id names (docs/service.md, "Identity").
  uint64_t token = 0;
  std::string scene_name;
  std::string presets;  // name of the sampler presets to run
  bool operator==(const Welcome&) const = default;
};

// sampler -> display: send me this scene, from chunk `first_chunk` on.
struct SceneRequest {
  uint32_t sampler_id = 0;
  SceneHash scene_hash{};
  uint32_t first_chunk = 0;
  bool operator==(const SceneRequest&) const = default;
};

// display -> sampler: one piece of the scene file. Chunks may have any sizes up to
// kMaxChunkBytes; `offset` places the bytes, so reassembly needs no other state.
struct SceneChunk {
  SceneHash scene_hash{};
  uint64_t scene_size = 0;     // 1..kMaxSceneBytes
  uint64_t offset = 0;         // offset + bytes.size() <= scene_size
  uint32_t index = 0;          // < count
  uint32_t count = 0;          // >= 1
  std::vector<uint8_t> bytes;  // 1..kMaxChunkBytes
  bool operator==(const SceneChunk&) const = default;
};

// display -> sampler: the part of the image the sampler owns from now on.
struct RegionAssignment {
  uint32_t sampler_id = 0;
  uint64_t epoch = 0;  // +1 per recut; a sampler ignores an epoch older than its current one
  ImageExtent image;   // 1..kMaxImageSize a side
  PixelRect region;    // non-empty, inside the image
  bool operator==(const RegionAssignment&) const = default;
};

// sampler -> display, about once a second.
struct SamplerStats {
  uint32_t sampler_id = 0;
  double time = 0.0;  // display clock, seconds
  uint64_t samples = 0;
  uint64_t batches = 0;
  uint64_t batches_dropped = 0;  // by the sender's queue (high-water mark)
  uint64_t tilings = 0;
  uint64_t bytes_sent = 0;
  uint64_t crosshairs = 0;
  uint64_t reprojections = 0;
  uint64_t reprojections_dropped = 0;
  uint64_t occlusion_rays = 0;
  uint64_t sanitized = 0;
  double samples_per_second = 0.0;  // finite, >= 0
  double rays_per_second = 0.0;     // finite, >= 0
  uint32_t tiles = 0;
  uint16_t threads = 1;  // 1..kMaxThreads
  bool operator==(const SamplerStats&) const = default;
};

// Both ways, a few times a second: proof of life, and (session) a way to notice a restart.
// Each side's failure detector (afr/common/failure_detector.h) starts from these intervals
// and then learns the ones it actually sees.
inline constexpr double kDisplayHeartbeatInterval = 0.15;  // display to samplers and nodes
inline constexpr double kMemberHeartbeatInterval = 0.2;    // samplers and wall nodes to it
struct Heartbeat {
  uint32_t sampler_id = 0;
  uint64_t session = 0;
  uint64_t sequence = 0;
  double time = 0.0;  // sender's estimate of the display clock, finite, >= 0
  bool operator==(const Heartbeat&) const = default;
};

enum class LeaveReason : uint16_t {
  kShutdown = 0,         // the sender is going away
  kVersionMismatch = 1,  // display -> sampler: protocol versions differ
  kRefused = 2,          // display -> sampler: not admitted (full, bad capabilities, ...)
  kTimeout = 3,          // display -> sampler: heartbeats stopped; join again
  kError = 4,            // anything else; the text says what
};
inline constexpr uint16_t kLastLeaveReason = 4;

struct Leave {
  uint32_t sampler_id = 0;
  LeaveReason reason = LeaveReason::kShutdown;
  std::string text;
  bool operator==(const Leave&) const = default;
};

// ---------------------------------------------------------------------------------------------
// View channel (PUB/SUB, conflated): display -> all samplers

// The camera at display-clock time `time`. Samplers take the latest sequence.
struct View {
  uint64_t sequence = 0;
  double time = 0.0;  // finite, >= 0
  Camera camera;      // finite; orthonormal basis; 0 < yfov < pi; znear > 0; ymag >= 0
  bool operator==(const View& o) const {
    return sequence == o.sequence && time == o.time && camera.eye == o.camera.eye &&
           camera.right == o.camera.right && camera.up == o.camera.up &&
           camera.forward == o.camera.forward && camera.yfov == o.camera.yfov &&
           camera.znear == o.camera.znear && camera.ymag == o.camera.ymag;
  }
};

// Sample channel (PUSH/PULL): SampleBatch and TilingSnapshot of afr/common/samples.h.

// ---------------------------------------------------------------------------------------------
// Display wall (docs/wall.md): one lead display coordinates; follower displays each show one
// cell of a grid over the virtual display and receive the samples of their cell plus a margin.

// follower display -> lead display, on the control channel: "I show this cell". The lead
// answers with a Welcome (node id in sampler_id, the session and clock) and a WallLayout;
// afterwards the follower sends heartbeats, like a sampler.
struct DisplayJoin {
  uint32_t node_id = 0;  // 0: assign one; else the id this node had before a reconnect
  uint16_t protocol_version = kProtocolVersion;
  uint16_t column = 0;  // the cell of the lead's grid
  uint16_t row = 0;
  std::string samples_endpoint;  // where samplers push this node's samples (tcp://HOST:PORT)
  std::string name;
  bool operator==(const DisplayJoin&) const = default;
};

struct WallNode {
  uint32_t node_id = 0;  // >= 1, unique in a layout
  PixelRect cell;        // the part of the virtual display this node shows
  // Its sample channel; empty: the lead's own (the endpoint the sampler joined through).
  std::string samples_endpoint;
  bool operator==(const WallNode&) const = default;
};

// lead display -> samplers and followers, on the control channel, whenever the wall changes:
// which display node needs which samples. A sampler sends each sample (and each tile of its
// snapshots) to every node whose cell, grown by `margin` pixels and clipped to the image,
// contains it, and nothing to the others.
struct WallLayout {
  uint64_t epoch = 0;           // +1 per change; older epochs are ignored
  ImageExtent image;            // the virtual display, 1..kMaxImageSize a side
  int32_t margin = 0;           // 0..kMaxWallMargin pixels
  std::vector<WallNode> nodes;  // 1..kMaxWallNodes, cells inside the image, not overlapping
  bool operator==(const WallLayout&) const = default;
};

// display node -> display node of the same wall, on the receiver's sample channel, after
// each image: the coverage map (section 6.2) the sender computed over `rect`, a part of its
// cell that lies in the receiver's received region. The receiver sizes its next image's
// splats there from it (docs/wall.md, "Seams"). Strays, the other thing nodes exchange, are
// ordinary sample batches with sampler_id kWallPeerSamplerId.
struct WallCoverage {
  uint32_t node_id = 0;  // the sender, >= 1
  double time = 0.0;     // display time of the image the map belongs to
  // In pixels of the virtual display, inside the receiver's image; 1..kMaxWallCoverageCells
  // pixels.
  PixelRect rect;
  // Per pixel of rect, row by row: the count of splats that reached it, then the sum of their
  // growths (afr::CoverageCell); both finite and >= 0. 2 x rect.area() floats.
  std::vector<float> cells;
  bool operator==(const WallCoverage&) const = default;
};

// The samples a node of `layout` needs: its cell grown by the margin, clipped to the image.
PixelRect wall_receive_rect(const WallLayout& layout, const WallNode& node);
// What a wall node is sent (the samplers' routing, protocol/src/wall.cpp): the samples of
// `batch` inside `rect`, and the tiles of `snapshot` that overlap it. The other fields are
// copied; *out's vectors are reused.
void select_samples(const SampleBatch& batch, const PixelRect& rect, SampleBatch* out);
void select_tiles(const TilingSnapshot& snapshot, const PixelRect& rect, TilingSnapshot* out);

// Any message, for channels that carry several types.
// lead display -> follower display, on the control channel: "write your cell's image at display
// time `time` as snapshot `id`" (docs/wall.md, "Snapshots"). Every node's image of one moment,
// stitched, is the wall's image of that moment.
struct SnapshotRequest {
  uint64_t id = 0;    // >= 1; names the files (snapshot_<id>.png)
  double time = 0.0;  // display time, finite, >= 0
  bool operator==(const SnapshotRequest&) const = default;
};

// lead display -> follower display, on the control channel, on every change of membership or
// of the regions: the samplers that are members, with the token of their welcome, the CurveZMQ
// key they joined with and the region the lead gave them, so that a follower drops batches that
// do not come from the member they name and cuts a member's tiling snapshots to its region, as
// the lead does (docs/wall.md, "Identity on a wall").
struct MemberEntry {
  uint32_t sampler_id = 0;  // >= 1, distinct
  uint64_t token = 0;
  std::string public_key;  // Z85 (40 characters), empty without CurveZMQ
  PixelRect region;        // all zero while it waits for its first region, else non-empty
  bool operator==(const MemberEntry&) const = default;
};
struct MemberList {
  uint64_t epoch = 0;                // +1 per change; older epochs are ignored
  std::vector<MemberEntry> members;  // 0..kMaxMembers
  bool operator==(const MemberList&) const = default;
};

using Message = std::variant<Join, Welcome, SceneRequest, SceneChunk, RegionAssignment, View,
                             SampleBatch, TilingSnapshot, SamplerStats, Heartbeat, Leave,
                             DisplayJoin, WallLayout, WallCoverage, SnapshotRequest, MemberList>;

MessageType message_type(const Message& message);

}  // namespace afr::protocol
