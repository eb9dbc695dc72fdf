// The binary encoding of afr's messages: a 12-byte header (magic, version, type, payload
// length) and a little-endian payload per type; docs/protocol.md has every byte.
//
// Encoding writes one whole message into a caller's std::vector<uint8_t>, replacing its
// contents and reusing its capacity. It validates first, with the same rules as decoding, so
// what one side encodes the other side accepts; a message that breaks them is not written.
//
// Decoding never throws on bad input, never reads outside the given bytes, and never
// allocates more than a count that has been checked against both its limit and the bytes that
// are actually there. It checks every length, count, enum and float; the Status names the
// message, the field and the problem. Batches and snapshots decode into caller-owned objects
// whose vectors are reused.
#pragma once

#include <afr/protocol/messages.h>
#include <afr/protocol/result.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace afr::protocol {

using Bytes = std::span<const uint8_t>;

// ---------------------------------------------------------------------------------------------
// Header

inline constexpr uint32_t kMagic = 0x50524641;  // the bytes "AFRP"
inline constexpr size_t kHeaderBytes = 12;

struct Header {
  uint16_t version = 0;
  MessageType type{};
  uint32_t payload_bytes = 0;
};

// Reads and checks the header: magic, a known type, and a payload length equal to the bytes
// that follow. Accepts any version (so a peer of another version can be told why it is
// refused); every decode function below also requires version == kProtocolVersion.
Result<Header> peek_header(Bytes message);

// ---------------------------------------------------------------------------------------------
// Sizes of sample batches (docs/protocol.md, "Bytes per sample")

inline constexpr size_t kBatchHeaderBytes = 40;  // after the message header
// Bytes of one packed sample for a batch's field flags: 12 (position in the image, time, miss,
// color), + 12 with kFieldPosition, + 6 with kFieldVelocity.
constexpr size_t packed_sample_bytes(uint32_t fields) {
  return 12 + ((fields & kFieldPosition) ? 12 : 0) + ((fields & kFieldVelocity) ? 6 : 0);
}
// Bytes of a whole encoded batch message.
constexpr size_t batch_message_bytes(uint32_t fields, size_t samples) {
  return kHeaderBytes + kBatchHeaderBytes + samples * packed_sample_bytes(fields);
}
inline constexpr size_t kTileBytes = 36;
inline constexpr size_t kSnapshotHeaderBytes = 32;
constexpr size_t snapshot_message_bytes(size_t tiles) {
  return kHeaderBytes + kSnapshotHeaderBytes + tiles * kTileBytes;
}

// A wall_coverage message of `pixels` cells (8 bytes each).
inline constexpr size_t kWallCoverageHeaderBytes = 24;
constexpr size_t wall_coverage_message_bytes(size_t pixels) {
  return kHeaderBytes + kWallCoverageHeaderBytes + pixels * 8;
}

// The largest message of each channel, for ZMQ_MAXMSGSIZE.
inline constexpr size_t kMaxSampleChannelMessage =
    std::max(batch_message_bytes(kFieldPosition | kFieldVelocity, kMaxSamplesPerBatch),
             snapshot_message_bytes(kMaxTilesPerSnapshot));
inline constexpr size_t kMaxControlChannelMessage = kHeaderBytes + 64 + kMaxChunkBytes;
inline constexpr size_t kMaxViewChannelMessage = kHeaderBytes + 136;

// The image that decoded samples and tiles must lie in. Receivers that know the current
// image size pass it; the default only enforces the protocol's 32768 x 32768.
inline constexpr ImageExtent kMaxImageExtent{kMaxImageSize, kMaxImageSize};

// ---------------------------------------------------------------------------------------------
// Encoding. `out` is cleared and filled with one message; on error it is left empty.

Status encode(const Join& m, std::vector<uint8_t>* out);
Status encode(const Welcome& m, std::vector<uint8_t>* out);
Status encode(const SceneRequest& m, std::vector<uint8_t>* out);
Status encode(const SceneChunk& m, std::vector<uint8_t>* out);
Status encode(const RegionAssignment& m, std::vector<uint8_t>* out);
Status encode(const View& m, std::vector<uint8_t>* out);
// Sample times become base_time (the earliest) plus 15-bit ticks of the finest power-of-two
// tick that spans the batch; positions, colors and velocities are packed as packing.h says
// (colors and velocities are clamped there). Fails on non-finite or negative times, a span
// over 32767 s, positions outside the image, non-finite world positions or velocities, and
// unknown field bits.
Status encode(const SampleBatch& m, std::vector<uint8_t>* out,
              const ImageExtent& bounds = kMaxImageExtent);
Status encode(const TilingSnapshot& m, std::vector<uint8_t>* out,
              const ImageExtent& bounds = kMaxImageExtent);
Status encode(const SamplerStats& m, std::vector<uint8_t>* out);
Status encode(const Heartbeat& m, std::vector<uint8_t>* out);
Status encode(const SnapshotRequest& m, std::vector<uint8_t>* out);
Status encode(const MemberList& m, std::vector<uint8_t>* out);
Status encode(const Leave& m, std::vector<uint8_t>* out);
Status encode(const DisplayJoin& m, std::vector<uint8_t>* out);
Status encode(const WallLayout& m, std::vector<uint8_t>* out);
Status encode(const WallCoverage& m, std::vector<uint8_t>* out,
              const ImageExtent& bounds = kMaxImageExtent);
Status encode(const Message& m, std::vector<uint8_t>* out);

// ---------------------------------------------------------------------------------------------
// Decoding. Each function requires a whole message of its type; on error *out is unspecified
// (but valid).

Status decode(Bytes message, Join* out);
Status decode(Bytes message, Welcome* out);
Status decode(Bytes message, SceneRequest* out);
Status decode(Bytes message, SceneChunk* out);
Status decode(Bytes message, RegionAssignment* out);
Status decode(Bytes message, View* out);
// Reuses out->samples' capacity: no allocation once it has held the largest batch seen.
Status decode(Bytes message, SampleBatch* out, const ImageExtent& bounds = kMaxImageExtent);
Status decode(Bytes message, TilingSnapshot* out, const ImageExtent& bounds = kMaxImageExtent);
Status decode(Bytes message, SamplerStats* out);
Status decode(Bytes message, Heartbeat* out);
Status decode(Bytes message, SnapshotRequest* out);
Status decode(Bytes message, MemberList* out);
Status decode(Bytes message, Leave* out);
Status decode(Bytes message, DisplayJoin* out);
Status decode(Bytes message, WallLayout* out);
Status decode(Bytes message, WallCoverage* out, const ImageExtent& bounds = kMaxImageExtent);
// Any type, by its header (allocates a fresh object; for control messages).
Result<Message> decode_message(Bytes message, const ImageExtent& bounds = kMaxImageExtent);

// ---------------------------------------------------------------------------------------------
// Validation: the rules decode enforces on values, for senders that want to check before
// building a message. Batches and snapshots are checked sample by sample / tile by tile.

Status validate(const Join& m);
Status validate(const Welcome& m);
Status validate(const SceneRequest& m);
Status validate(const SceneChunk& m);
Status validate(const RegionAssignment& m);
Status validate(const View& m);
Status validate(const SampleBatch& m, const ImageExtent& bounds = kMaxImageExtent);
Status validate(const TilingSnapshot& m, const ImageExtent& bounds = kMaxImageExtent);
Status validate(const SamplerStats& m);
Status validate(const Heartbeat& m);
Status validate(const SnapshotRequest& m);
Status validate(const MemberList& m);
Status validate(const Leave& m);
Status validate(const DisplayJoin& m);
Status validate(const WallLayout& m);
Status validate(const WallCoverage& m, const ImageExtent& bounds = kMaxImageExtent);

}  // namespace afr::protocol
