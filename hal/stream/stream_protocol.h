// The console link's messages as bytes (schema: hal/stream/console_stream.fbs):
// plain structs the threads exchange, an encoder that builds size-prefixed
// FlatBuffers with one reused builder, a decoder that verifies a buffer
// before reading it, and a framer that cuts a byte stream into buffers.
//
// Allocation: StreamEncoder allocates its builder once in the constructor
// (sized for the largest message) and never again; decode_message() and
// MessageFramer::next() allocate only for an error message.
#pragma once

#include <flatbuffers/flatbuffers.h>

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "core/geometry/camera.h"
#include "core/mesh/mesh.h"
#include "core/texture/mesh_texture.h"
#include "core/base/result.h"
#include "core/tracking/tracker.h"
#include "hal/stream/console_stream_generated.h"

namespace st {

inline constexpr std::uint16_t kStreamProtocolVersion = 1;
// A size prefix above this is refused: the largest message we send (a full
// colour delta) is ~33 KiB, so a bigger one is corruption or another protocol.
inline constexpr std::size_t kMaxStreamMessageBytes = 256 * 1024;
// Triangles per ColourDelta message (more are split over several messages).
inline constexpr int kMaxColoursPerDelta = 4096;

// One frame's result as the tracking thread hands it over: plain data, no
// pointers, copied through a fixed queue.
struct PoseSample {
  std::int64_t timestamp_ns = 0;
  std::uint32_t frame = 0;
  TrackState state = TrackState::kLost;
  std::uint16_t inliers = 0;
  double q_xyzw[4] = {0, 0, 0, 1};  // rotation of T_model_camera
  double t_mm[3] = {0, 0, 0};       // translation of T_model_camera
  float quality = 0;                // inlier ratio, 0..1
  std::uint32_t latency_us = 0;
  // PoseEvidence: what the outline and the shading saw (-1: not measured).
  bool by_outline = false;          // the pose is the outline's and the shading's
  std::uint16_t outline_lines = 0;
  float outline_sigma_px = -1, joint_sigma_px = -1, outline_shading_px = -1;
};
// Fills q/t from T_camera_model (inverted: the stream carries T_model_camera).
void set_pose(PoseSample* s, const SE3& T_camera_model);
SE3 T_model_camera(const PoseSample& s);

struct StreamHello {
  std::uint32_t mesh_triangle_count = 0;
  std::uint64_t mesh_checksum = 0;
  int image_width = 0, image_height = 0;
  Pinhole K;
  Distortion distortion;
  float source_fps = 0;
  std::uint16_t protocol_version = kStreamProtocolVersion;
};

// One triangle's colour (core/texture/mesh_texture.h produces them).
using ColourUpdate = TriangleRgb;

struct HealthSample {
  float fps = 0;
  std::uint32_t overruns = 0, dropped_messages = 0, frames = 0;
  bool calibration_suspect = false;     // TrackerConfig::check_calibration's verdict
  float calibration_focal_scale = 1.f;  // the focal scale the video fits (when suspect)
};

// FNV-1a 64 over the vertex coordinates and triangle indices (their bytes):
// the console checks that it colours the mesh the tracker uses.
std::uint64_t mesh_checksum(const Mesh& mesh);

// Builds one message at a time into a reused, preallocated builder. The
// returned bytes (size prefix included) stay valid until the next call.
class StreamEncoder {
 public:
  StreamEncoder();
  StreamEncoder(const StreamEncoder&) = delete;
  StreamEncoder& operator=(const StreamEncoder&) = delete;

  std::span<const std::uint8_t> hello(const StreamHello& h);
  std::span<const std::uint8_t> pose(const PoseSample& p);
  // At most kMaxColoursPerDelta entries are encoded (the rest are ignored).
  std::span<const std::uint8_t> colours(std::span<const ColourUpdate> c);
  // Colours built in place: begin_colours(n) gives room for n (<= kMaxColoursPerDelta), then
  // finish.
  stream::TriangleColour* begin_colours(int n);
  std::span<const std::uint8_t> finish_colours();
  std::span<const std::uint8_t> health(const HealthSample& h);

 private:
  std::span<const std::uint8_t> finish(stream::Payload type, flatbuffers::Offset<void> payload);
  flatbuffers::FlatBufferBuilder fbb_;
  flatbuffers::uoffset_t colours_vector_ = 0;
};

enum class MessageKind { kHello, kPose, kColours, kHealth };

// A verified message. For kColours, `colours` points into the buffer given
// to decode_message (valid as long as those bytes are).
struct DecodedMessage {
  MessageKind kind = MessageKind::kHello;
  StreamHello hello;
  PoseSample pose;
  const flatbuffers::Vector<const stream::TriangleColour*>* colours = nullptr;
  HealthSample health;
};

// One size-prefixed buffer, exactly (4-byte prefix + the buffer it declares).
// Errors: shorter than the prefix, prefix above kMaxStreamMessageBytes,
// declared size different from the bytes given, wrong file identifier,
// FlatBuffers verification failure, a payload this version does not know.
Result<DecodedMessage> decode_message(std::span<const std::uint8_t> sized_buffer);

// Cuts a received byte stream into size-prefixed buffers. Receive into
// write_area(), commit() what arrived, then next() until kNeedMore. After
// kError (an oversized prefix) the stream cannot be resynchronised.
class MessageFramer {
 public:
  enum class Next { kMessage, kNeedMore, kError };
  MessageFramer();  // allocates its buffer (2 x the largest message)
  std::span<std::uint8_t> write_area();
  void commit(std::size_t n);
  Next next(std::span<const std::uint8_t>* message, std::string* error);
  std::size_t buffered() const { return end_ - begin_; }

 private:
  std::vector<std::uint8_t> buf_;
  std::size_t begin_ = 0, end_ = 0;
};

}  // namespace st
