// Fuzzes the console link's receiving side with the bytes a console gets
// from its socket. The first input byte sets the receive chunk size (as a
// socket may deliver any split); the rest goes through
// ConsoleSession::feed (framer, size prefix, verification, decode, pose /
// colour / health bookkeeping) and its status line. Separately, every
// buffer decode_message accepts (the input cut at its own size prefixes)
// must re-encode into a buffer that decodes to the same fields.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>

#include "hal/stream/stream_protocol.h"
#include "tools/console/console_session.h"

namespace {

template <typename T>
bool same(T a, T b) {
  return a == b || (std::isnan(a) && std::isnan(b));
}

// decode(encode(m)) must give m back (NaN equal to NaN).
void check_round_trip(const st::DecodedMessage& m) {
  static st::StreamEncoder enc;  // builds its largest message once, on construction
  std::span<const std::uint8_t> bytes;
  switch (m.kind) {
    case st::MessageKind::kHello: bytes = enc.hello(m.hello); break;
    case st::MessageKind::kPose: bytes = enc.pose(m.pose); break;
    case st::MessageKind::kHealth: bytes = enc.health(m.health); break;
    case st::MessageKind::kColours: {
      const int n = static_cast<int>(std::min<std::size_t>(m.colours->size(), st::kMaxColoursPerDelta));
      st::stream::TriangleColour* out = enc.begin_colours(n);
      for (int i = 0; i < n; ++i) out[i] = *m.colours->Get(static_cast<flatbuffers::uoffset_t>(i));
      bytes = enc.finish_colours();
      break;
    }
  }
  const auto again = st::decode_message(bytes);
  if (!again || again->kind != m.kind) __builtin_trap();
  const st::DecodedMessage& r = again.value();
  switch (m.kind) {
    case st::MessageKind::kHello:
      if (r.hello.mesh_triangle_count != m.hello.mesh_triangle_count || r.hello.mesh_checksum != m.hello.mesh_checksum ||
          r.hello.image_width != m.hello.image_width || r.hello.image_height != m.hello.image_height ||
          r.hello.protocol_version != m.hello.protocol_version ||
          !same(r.hello.K.fx, m.hello.K.fx) || !same(r.hello.K.fy, m.hello.K.fy) || !same(r.hello.K.cx, m.hello.K.cx) ||
          !same(r.hello.K.cy, m.hello.K.cy) || !same(r.hello.source_fps, m.hello.source_fps))
        __builtin_trap();
      // Coefficients, not their count: a Hello without intrinsics decodes
      // with none (count 0), re-encoded it carries five zeros, the same lens.
      for (int i = 0; i < 8; ++i)
        if (!same(r.hello.distortion.k[static_cast<std::size_t>(i)], m.hello.distortion.k[static_cast<std::size_t>(i)]))
          __builtin_trap();
      break;
    case st::MessageKind::kPose:
      if (r.pose.frame != m.pose.frame || r.pose.state != m.pose.state || r.pose.inliers != m.pose.inliers ||
          r.pose.timestamp_ns != m.pose.timestamp_ns || r.pose.latency_us != m.pose.latency_us ||
          !same(r.pose.quality, m.pose.quality))
        __builtin_trap();
      for (int i = 0; i < 4; ++i)
        if (!same(r.pose.q_xyzw[i], m.pose.q_xyzw[i])) __builtin_trap();
      for (int i = 0; i < 3; ++i)
        if (!same(r.pose.t_mm[i], m.pose.t_mm[i])) __builtin_trap();
      break;
    case st::MessageKind::kHealth:
      if (r.health.overruns != m.health.overruns || r.health.dropped_messages != m.health.dropped_messages ||
          r.health.frames != m.health.frames || r.health.calibration_suspect != m.health.calibration_suspect ||
          !same(r.health.fps, m.health.fps) || !same(r.health.calibration_focal_scale, m.health.calibration_focal_scale))
        __builtin_trap();
      break;
    case st::MessageKind::kColours:
      if (r.colours->size() != std::min<std::size_t>(m.colours->size(), st::kMaxColoursPerDelta)) __builtin_trap();
      for (flatbuffers::uoffset_t i = 0; i < r.colours->size(); ++i)
        if (std::memcmp(r.colours->Get(i), m.colours->Get(i), sizeof(st::stream::TriangleColour)) != 0)
          __builtin_trap();
      break;
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::size_t chunk = 1 + data[0] % 64 * 17;  // 1 .. 1072 bytes per receive
  std::span<const std::uint8_t> stream(data + 1, size - 1);
  st::console::ConsoleSession session;
  for (std::size_t at = 0; at < stream.size(); at += chunk) {
    if (!session.feed(stream.subspan(at, std::min(chunk, stream.size() - at)))) break;  // the session ended
    (void)session.status_line();
  }
  (void)session.status_line();
  // Buffers at the input's own size prefixes, copied to 8-byte-aligned
  // storage (as the framer hands them out).
  static std::uint8_t aligned[st::kMaxStreamMessageBytes + 8] __attribute__((aligned(8)));
  std::size_t at = 0;
  while (stream.size() - at >= 4) {
    std::uint32_t declared;
    std::memcpy(&declared, stream.data() + at, 4);
    const std::size_t len = std::min<std::size_t>(static_cast<std::size_t>(declared) + 4, stream.size() - at);
    if (len > sizeof aligned) break;
    std::memcpy(aligned, stream.data() + at, len);
    const auto m = st::decode_message({aligned, len});
    if (m) check_round_trip(m.value());
    at += len;
  }
  return 0;
}
