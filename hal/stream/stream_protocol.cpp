#include "hal/stream/stream_protocol.h"

#include <algorithm>
#include <cstring>

namespace st {

namespace {

stream::TrackingState to_wire(TrackState s) {
  switch (s) {
    case TrackState::kInitialised:
      return stream::TrackingState::Initialised;
    case TrackState::kTracking:
      return stream::TrackingState::Tracking;
    case TrackState::kRelocalised:
      return stream::TrackingState::Relocalised;
    case TrackState::kLost:
      break;
  }
  return stream::TrackingState::Lost;
}

TrackState from_wire(stream::TrackingState s) {
  switch (s) {
    case stream::TrackingState::Initialised:
      return TrackState::kInitialised;
    case stream::TrackingState::Tracking:
      return TrackState::kTracking;
    case stream::TrackingState::Relocalised:
      return TrackState::kRelocalised;
    default:
      break;  // Lost, or a value a newer sender added: not trustworthy
  }
  return TrackState::kLost;
}

void fnv1a(const void* data, std::size_t n, std::uint64_t* h) {
  const auto* p = static_cast<const std::uint8_t*>(data);
  for (std::size_t i = 0; i < n; ++i) {
    *h ^= p[i];
    *h *= 0x100000001b3ull;
  }
}

// Builder capacity: the largest message plus the builder's own bookkeeping.
constexpr std::size_t kBuilderBytes = kMaxStreamMessageBytes + 4096;

StreamHello hello_from_wire(const stream::Hello& m) {
  StreamHello h;
  h.protocol_version = m.protocol_version();
  h.mesh_triangle_count = m.mesh_triangle_count();
  h.mesh_checksum = m.mesh_checksum();
  h.image_width = m.image_width();
  h.image_height = m.image_height();
  h.source_fps = m.source_fps();
  if (const stream::Intrinsics* in = m.intrinsics()) {
    h.K.fx = in->fx();
    h.K.fy = in->fy();
    h.K.cx = in->cx();
    h.K.cy = in->cy();
    h.distortion.k = {in->k1(), in->k2(), in->p1(), in->p2(), in->k3(), 0, 0, 0};
    h.distortion.count = 5;
  }
  h.K.width = h.image_width;
  h.K.height = h.image_height;
  return h;
}

PoseSample pose_from_wire(const stream::Pose& p) {
  PoseSample s;
  s.frame = p.frame();
  s.state = from_wire(p.state());
  s.inliers = p.inliers();
  s.timestamp_ns = p.timestamp_ns();
  s.q_xyzw[0] = p.qx();
  s.q_xyzw[1] = p.qy();
  s.q_xyzw[2] = p.qz();
  s.q_xyzw[3] = p.qw();
  s.t_mm[0] = p.tx();
  s.t_mm[1] = p.ty();
  s.t_mm[2] = p.tz();
  s.quality = p.quality();
  s.latency_us = p.latency_us();
  return s;
}

void evidence_from_wire(const stream::PoseEvidence& e, PoseSample* s) {
  s->by_outline = e.source() == stream::PoseSource::Outline;
  s->outline_lines = e.outline_lines();
  s->outline_sigma_px = e.outline_sigma_px();
  s->joint_sigma_px = e.joint_sigma_px();
  s->outline_shading_px = e.outline_shading_px();
}

}  // namespace

void set_pose(PoseSample* s, const SE3& T_camera_model) {
  const SE3 T_model_camera = T_camera_model.inverse();
  const Quat q = T_model_camera.quaternion();
  s->q_xyzw[0] = q.x();
  s->q_xyzw[1] = q.y();
  s->q_xyzw[2] = q.z();
  s->q_xyzw[3] = q.w();
  for (int i = 0; i < 3; ++i) s->t_mm[i] = T_model_camera.translation()[i];
}

SE3 T_model_camera(const PoseSample& s) {
  return SE3(Quat(s.q_xyzw[3], s.q_xyzw[0], s.q_xyzw[1], s.q_xyzw[2]),
             Vec3(s.t_mm[0], s.t_mm[1], s.t_mm[2]));
}

std::uint64_t mesh_checksum(const Mesh& mesh) {
  std::uint64_t h = 0xcbf29ce484222325ull;
  fnv1a(mesh.x.data(), mesh.x.size() * sizeof(float), &h);
  fnv1a(mesh.y.data(), mesh.y.size() * sizeof(float), &h);
  fnv1a(mesh.z.data(), mesh.z.size() * sizeof(float), &h);
  fnv1a(mesh.tri.data(), mesh.tri.size() * sizeof(std::int32_t), &h);
  return h;
}

StreamEncoder::StreamEncoder() : fbb_(kBuilderBytes) {
  // The builder allocates its buffer lazily: build the largest message once
  // here so that no later message grows it.
  begin_colours(kMaxColoursPerDelta);
  finish_colours();
  fbb_.Clear();
}

std::span<const std::uint8_t> StreamEncoder::finish(stream::Payload type,
                                                    flatbuffers::Offset<void> payload) {
  const auto root = stream::CreateMessage(fbb_, type, payload);
  stream::FinishSizePrefixedMessageBuffer(fbb_, root);
  return {fbb_.GetBufferPointer(), fbb_.GetSize()};
}

std::span<const std::uint8_t> StreamEncoder::hello(const StreamHello& h) {
  fbb_.Clear();
  const double* k = h.distortion.k.data();
  const stream::Intrinsics in(h.K.fx, h.K.fy, h.K.cx, h.K.cy, k[0], k[1], k[2], k[3], k[4]);
  const auto m = stream::CreateHello(fbb_, h.protocol_version, h.mesh_triangle_count,
                                     h.mesh_checksum, static_cast<std::uint16_t>(h.image_width),
                                     static_cast<std::uint16_t>(h.image_height), &in, h.source_fps);
  return finish(stream::Payload::Hello, m.Union());
}

std::span<const std::uint8_t> StreamEncoder::pose(const PoseSample& p) {
  fbb_.Clear();
  const stream::Pose wire(p.frame, to_wire(p.state), p.inliers, p.timestamp_ns, p.q_xyzw[0],
                          p.q_xyzw[1], p.q_xyzw[2], p.q_xyzw[3], p.t_mm[0], p.t_mm[1], p.t_mm[2],
                          p.quality, p.latency_us);
  const stream::PoseEvidence evidence(p.by_outline ? stream::PoseSource::Outline : stream::PoseSource::Features,
                                      p.outline_lines, p.outline_sigma_px, p.joint_sigma_px,
                                      p.outline_shading_px);
  const auto m = stream::CreatePoseUpdate(fbb_, &wire, &evidence);
  return finish(stream::Payload::PoseUpdate, m.Union());
}

stream::TriangleColour* StreamEncoder::begin_colours(int n) {
  fbb_.Clear();
  stream::TriangleColour* out = nullptr;
  const auto v = fbb_.CreateUninitializedVectorOfStructs<stream::TriangleColour>(
      static_cast<std::size_t>(std::clamp(n, 0, kMaxColoursPerDelta)), &out);
  colours_vector_ = v.o;
  return out;
}

std::span<const std::uint8_t> StreamEncoder::finish_colours() {
  const flatbuffers::Offset<flatbuffers::Vector<const stream::TriangleColour*>> v(colours_vector_);
  const auto m = stream::CreateColourDelta(fbb_, v);
  return finish(stream::Payload::ColourDelta, m.Union());
}

std::span<const std::uint8_t> StreamEncoder::colours(std::span<const ColourUpdate> c) {
  const int n = static_cast<int>(std::min<std::size_t>(c.size(), kMaxColoursPerDelta));
  stream::TriangleColour* out = begin_colours(n);
  for (int i = 0; i < n; ++i)
    out[i] = stream::TriangleColour(c[i].triangle, c[i].r, c[i].g, c[i].b);
  return finish_colours();
}

std::span<const std::uint8_t> StreamEncoder::health(const HealthSample& h) {
  fbb_.Clear();
  const auto m = stream::CreateHealth(fbb_, h.fps, h.overruns, h.dropped_messages, h.frames,
                                      h.calibration_suspect, h.calibration_focal_scale);
  return finish(stream::Payload::Health, m.Union());
}

Result<DecodedMessage> decode_message(std::span<const std::uint8_t> b) {
  if (b.size() < sizeof(flatbuffers::uoffset_t))
    return make_error("truncated message: " + std::to_string(b.size()) +
                      " bytes, less than the 4-byte size prefix");
  const std::size_t declared = flatbuffers::ReadScalar<flatbuffers::uoffset_t>(b.data());
  if (declared > kMaxStreamMessageBytes)
    return make_error("oversized message: the size prefix declares " + std::to_string(declared) +
                      " bytes, the limit is " + std::to_string(kMaxStreamMessageBytes) +
                      " (not a ScopeTrack stream, or corrupt)");
  if (declared + sizeof(flatbuffers::uoffset_t) != b.size())
    return make_error("truncated message: the size prefix declares " + std::to_string(declared) +
                      " bytes, got " + std::to_string(b.size() - sizeof(flatbuffers::uoffset_t)));
  if (!stream::SizePrefixedMessageBufferHasIdentifier(b.data()))
    return make_error("not a ScopeTrack stream message (file identifier is not \"STCS\")");
  flatbuffers::Verifier verifier(b.data(), b.size(), 16, 64);
  if (!stream::VerifySizePrefixedMessageBuffer(verifier))
    return make_error("corrupt message: FlatBuffers verification failed (" +
                      std::to_string(b.size()) + " bytes)");
  const stream::Message* msg = stream::GetSizePrefixedMessage(b.data());
  DecodedMessage out;
  if (const auto* h = msg->payload_as_Hello()) {
    out.kind = MessageKind::kHello;
    out.hello = hello_from_wire(*h);
  } else if (const auto* p = msg->payload_as_PoseUpdate(); p && p->pose()) {
    out.kind = MessageKind::kPose;
    out.pose = pose_from_wire(*p->pose());
    if (const auto* e = p->evidence()) evidence_from_wire(*e, &out.pose);
  } else if (const auto* c = msg->payload_as_ColourDelta()) {
    out.kind = MessageKind::kColours;
    out.colours = c->colours();
    if (!out.colours) return make_error("colour delta without a colour vector");
  } else if (const auto* hl = msg->payload_as_Health()) {
    out.kind = MessageKind::kHealth;
    out.health = {hl->fps(), hl->overruns(), hl->dropped_messages(), hl->frames(),
                  hl->calibration_suspect(), hl->calibration_focal_scale()};
  } else {
    return make_error("message without a payload this console understands (payload type " +
                      std::to_string(static_cast<int>(msg->payload_type())) + ")");
  }
  return out;
}

MessageFramer::MessageFramer()
    : buf_(2 * (kMaxStreamMessageBytes + sizeof(flatbuffers::uoffset_t))) {}

std::span<std::uint8_t> MessageFramer::write_area() {
  if (begin_ > 0 && (end_ == buf_.size() || begin_ % 8 != 0)) {
    // Move the partial message to the front: room for the rest, and 8-byte
    // alignment of the buffer (the Verifier checks scalar alignment).
    std::memmove(buf_.data(), buf_.data() + begin_, end_ - begin_);
    end_ -= begin_;
    begin_ = 0;
  }
  return {buf_.data() + end_, buf_.size() - end_};
}

void MessageFramer::commit(std::size_t n) { end_ = std::min(buf_.size(), end_ + n); }

MessageFramer::Next MessageFramer::next(std::span<const std::uint8_t>* message,
                                        std::string* error) {
  constexpr std::size_t kPrefix = sizeof(flatbuffers::uoffset_t);
  if (end_ - begin_ < kPrefix) return Next::kNeedMore;
  const std::size_t declared =
      flatbuffers::ReadScalar<flatbuffers::uoffset_t>(buf_.data() + begin_);
  if (declared > kMaxStreamMessageBytes) {
    *error = "oversized message: the size prefix declares " + std::to_string(declared) +
             " bytes, the limit is " + std::to_string(kMaxStreamMessageBytes) +
             " (not a ScopeTrack stream, or corrupt)";
    return Next::kError;
  }
  if (end_ - begin_ < kPrefix + declared) return Next::kNeedMore;
  if (begin_ % 8 != 0) {  // align before handing out (see write_area)
    std::memmove(buf_.data(), buf_.data() + begin_, end_ - begin_);
    end_ -= begin_;
    begin_ = 0;
  }
  *message = {buf_.data() + begin_, kPrefix + declared};
  begin_ += kPrefix + declared;
  if (begin_ == end_) begin_ = end_ = 0;
  return Next::kMessage;
}

}  // namespace st
