// The console link's bytes (hal/stream/stream_protocol.h, hal/stream/console_stream.fbs):
// round trips, bad buffers (truncated, oversized, garbage, foreign), stream
// reassembly, an independent decoder (flatc --json), endpoints, and the
// console session fed with bytes.
#include <doctest/doctest.h>

#include <cstdlib>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "hal/stream/stream_protocol.h"
#include "platform/socket.h"
#include "support/alloc_guard.h"
#include "support/shell.h"
#include "support/support.h"
#include "support/tiny_sequence.h"
#include "tools/console/console_session.h"

using namespace st;

namespace {

using Bytes = std::vector<std::uint8_t>;
Bytes copy(std::span<const std::uint8_t> s) { return Bytes(s.begin(), s.end()); }

PoseSample sample_pose() {
  PoseSample p;
  p.frame = 42;
  p.timestamp_ns = 1'400'000'000;
  p.state = TrackState::kTracking;
  p.inliers = 311;
  p.quality = 0.75f;
  p.latency_us = 6250;
  set_pose(&p, SE3(Eigen::AngleAxisd(0.3, Vec3(1, 2, 3).normalized()).toRotationMatrix(),
                   Vec3(10, -20, 130)));
  return p;
}

StreamHello sample_hello(const Mesh& mesh) {
  StreamHello h;
  h.mesh_triangle_count = static_cast<std::uint32_t>(mesh.triangle_count());
  h.mesh_checksum = mesh_checksum(mesh);
  h.image_width = 480;
  h.image_height = 270;
  h.K = Pinhole{400, 401, 239.5, 134.5, 480, 270};
  h.distortion.k = {-0.28, 0.1, 0.001, -0.002, 0.01, 0, 0, 0};
  h.distortion.count = 5;
  h.source_fps = 30;
  return h;
}

std::string decode_error(const Bytes& b) {
  auto m = decode_message(b);
  return m.ok() ? std::string() : m.message();
}

}  // namespace

TEST_CASE("console_protocol: hello, pose, colours and health survive encode -> verify -> decode") {
  const Mesh cube = test::centred_cube(40);
  StreamEncoder enc;
  const Bytes hello = copy(enc.hello(sample_hello(cube)));
  auto h = decode_message(hello);
  REQUIRE_MESSAGE(h.ok(), h.message());
  REQUIRE(h->kind == MessageKind::kHello);
  CHECK(h->hello.mesh_triangle_count == 12);
  CHECK(h->hello.mesh_checksum == mesh_checksum(cube));
  CHECK(h->hello.image_width == 480);
  CHECK(h->hello.K.fy == 401);
  CHECK(h->hello.distortion.k[0] == -0.28);
  CHECK(h->hello.protocol_version == kStreamProtocolVersion);

  const PoseSample p = sample_pose();
  const Bytes pose = copy(enc.pose(p));
  auto d = decode_message(pose);
  REQUIRE_MESSAGE(d.ok(), d.message());
  REQUIRE(d->kind == MessageKind::kPose);
  CHECK(d->pose.frame == 42);
  CHECK(d->pose.state == TrackState::kTracking);
  CHECK(d->pose.inliers == 311);
  CHECK(d->pose.timestamp_ns == 1'400'000'000);
  CHECK(d->pose.latency_us == 6250);
  CHECK(d->pose.quality == 0.75f);
  CHECK((T_model_camera(d->pose).matrix() - T_model_camera(p).matrix()).norm() < 1e-12);

  const std::vector<ColourUpdate> cols = {{3, 10, 20, 30}, {11, 255, 0, 128}};
  auto c = decode_message(copy(enc.colours(cols)));
  REQUIRE_MESSAGE(c.ok(),
                  c.message());  // decoded from a temporary: read nothing from it but the kind
  CHECK(c->kind == MessageKind::kColours);
  const Bytes colours = copy(enc.colours(cols));
  auto c2 = decode_message(colours);
  REQUIRE(c2.ok());
  REQUIRE(c2->colours->size() == 2);
  CHECK(c2->colours->Get(1)->triangle() == 11);
  CHECK(c2->colours->Get(1)->b() == 128);

  auto hl = decode_message(copy(enc.health({29.5f, 3, 7, 1000})));
  REQUIRE(hl.ok());
  CHECK(hl->kind == MessageKind::kHealth);
  CHECK(hl->health.dropped_messages == 7);
  CHECK(hl->health.fps == 29.5f);
  CHECK_FALSE(hl->health.calibration_suspect);
  HealthSample suspect;
  suspect.calibration_suspect = true;
  suspect.calibration_focal_scale = 0.87f;
  auto hs = decode_message(copy(enc.health(suspect)));
  REQUIRE(hs.ok());
  CHECK(hs->health.calibration_suspect);
  CHECK(hs->health.calibration_focal_scale == 0.87f);
}

TEST_CASE(
    "console_protocol: truncated, oversized, garbage and foreign buffers are rejected with a clear "
    "error") {
  StreamEncoder enc;
  const Bytes pose = copy(enc.pose(sample_pose()));
  // Truncated: every shorter prefix of a valid buffer.
  for (std::size_t n = 0; n < pose.size(); ++n) {
    CAPTURE(n);
    const std::string e =
        decode_error(Bytes(pose.begin(), pose.begin() + static_cast<std::ptrdiff_t>(n)));
    CHECK(e.find("truncated") != std::string::npos);
  }
  // Oversized size prefix.
  Bytes big = pose;
  big[0] = 0xff;
  big[1] = 0xff;
  big[2] = 0xff;
  big[3] = 0x7f;
  CHECK(decode_error(big).find("oversized") != std::string::npos);
  // A foreign file identifier.
  Bytes foreign = pose;
  foreign[8] = 'X';
  CHECK(decode_error(foreign).find("identifier") != std::string::npos);
  // Garbage with a correct prefix and identifier: the Verifier must refuse
  // (random bytes can verify by chance: a decodable one must then decode
  // without reading outside the buffer, which ASan runs check).
  std::mt19937 rng(7);
  int refused = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    Bytes g = pose;
    for (std::size_t i = 12; i < g.size(); ++i)
      if (rng() % 4 == 0) g[i] = static_cast<std::uint8_t>(rng());
    const std::string e = decode_error(g);
    if (!e.empty()) {
      ++refused;
      CHECK(e.find("message") != std::string::npos);
    }
  }
  CHECK(refused > 100);
  // Pure noise.
  Bytes noise(64);
  for (auto& b : noise) b = static_cast<std::uint8_t>(rng());
  noise[0] = 60;
  noise[1] = noise[2] = noise[3] = 0;
  CHECK_FALSE(decode_error(noise).empty());
}

TEST_CASE(
    "console_protocol: the framer reassembles buffers split anywhere and refuses an oversized "
    "prefix") {
  StreamEncoder enc;
  Bytes stream;
  for (int i = 0; i < 5; ++i) {
    PoseSample p = sample_pose();
    p.frame = static_cast<std::uint32_t>(i);
    const auto b = enc.pose(p);
    stream.insert(stream.end(), b.begin(), b.end());
  }
  for (std::size_t chunk : {std::size_t{1}, std::size_t{3}, std::size_t{7}, std::size_t{1000}}) {
    CAPTURE(chunk);
    MessageFramer framer;
    std::vector<std::uint32_t> frames;
    for (std::size_t off = 0; off < stream.size(); off += chunk) {
      const std::size_t n = std::min(chunk, stream.size() - off);
      std::memcpy(framer.write_area().data(), stream.data() + off, n);
      framer.commit(n);
      std::span<const std::uint8_t> msg;
      std::string err;
      while (framer.next(&msg, &err) == MessageFramer::Next::kMessage) {
        auto d = decode_message(msg);
        REQUIRE_MESSAGE(d.ok(), d.message());
        frames.push_back(d->pose.frame);
      }
    }
    CHECK(frames == std::vector<std::uint32_t>{0, 1, 2, 3, 4});
  }
  MessageFramer framer;
  const std::uint8_t huge[4] = {0, 0, 0, 0x10};
  std::memcpy(framer.write_area().data(), huge, 4);
  framer.commit(4);
  std::span<const std::uint8_t> msg;
  std::string err;
  CHECK(framer.next(&msg, &err) == MessageFramer::Next::kError);
  CHECK(err.find("oversized") != std::string::npos);
}

TEST_CASE("console_protocol: the encoder allocates nothing after construction") {
  StreamEncoder enc;
  std::vector<ColourUpdate> cols(kMaxColoursPerDelta);
  for (int i = 0; i < kMaxColoursPerDelta; ++i)
    cols[static_cast<std::size_t>(i)].triangle = static_cast<std::uint32_t>(i);
  const Mesh cube = test::centred_cube(10);
  const StreamHello hello = sample_hello(cube);
  test::AllocationCounter allocs;
  std::size_t bytes = 0;
  for (int i = 0; i < 100; ++i) {
    bytes += enc.pose(sample_pose()).size();
    bytes += enc.colours(cols).size();
    bytes += enc.health({}).size();
    bytes += enc.hello(hello).size();
  }
  CHECK(allocs.count() == 0);
  CHECK(bytes > 100 * 8 * kMaxColoursPerDelta);
}

TEST_CASE(
    "console_protocol: flatc --json (an independent decoder) reads a captured buffer with the same "
    "fields") {
  const auto dir = test::scratch_dir("console_flatc");
  StreamEncoder enc;
  const PoseSample p = sample_pose();
  const Bytes pose = copy(enc.pose(p));
  {
    std::ofstream f(dir / "pose.bin", std::ios::binary);
    f.write(reinterpret_cast<const char*>(pose.data()), static_cast<std::streamsize>(pose.size()));
  }
  const std::string cmd =
      std::string(SCOPETRACK_FLATC) + " --json --strict-json --size-prefixed --raw-binary -o '" +
      dir.string() + "' '" + SCOPETRACK_STREAM_SCHEMA + "' -- '" + (dir / "pose.bin").string() +
      "' 2> '" + (dir / "flatc.err").string() + "'";
  REQUIRE_MESSAGE(test::run_shell(cmd) == 0,
                  (cmd + "\n" + test::read_file_bytes(dir / "flatc.err")));
  const std::string json = test::read_file_bytes(dir / "pose.json");
  INFO(json);
  CHECK(json.find("\"payload_type\": \"PoseUpdate\"") != std::string::npos);
  CHECK(json.find("\"frame\": 42") != std::string::npos);
  CHECK(json.find("\"state\": \"Tracking\"") != std::string::npos);
  CHECK(json.find("\"inliers\": 311") != std::string::npos);
  CHECK(json.find("\"timestamp_ns\": 1400000000") != std::string::npos);
  CHECK(json.find("\"latency_us\": 6250") != std::string::npos);
  CHECK(json.find("\"quality\": 0.75") != std::string::npos);
  // The hello and a colour delta through the same decoder.
  const Mesh cube = test::centred_cube(40);
  const std::vector<ColourUpdate> cols = {{3, 10, 20, 30}, {11, 255, 0, 128}};
  for (const auto& [name, bytes] : {std::pair{"hello", copy(enc.hello(sample_hello(cube)))},
                                    std::pair{"colours", copy(enc.colours(cols))}}) {
    std::ofstream f(dir / (std::string(name) + ".bin"), std::ios::binary);
    f.write(reinterpret_cast<const char*>(bytes.data()),
            static_cast<std::streamsize>(bytes.size()));
  }
  std::string cmd2 = std::string(SCOPETRACK_FLATC) + " --json --strict-json --size-prefixed -o ";
  cmd2 += test::shell_quoted(dir) + " " + test::shell_quoted(SCOPETRACK_STREAM_SCHEMA) + " -- ";
  cmd2 += test::shell_quoted(dir / "hello.bin") + " " + test::shell_quoted(dir / "colours.bin");
  REQUIRE_MESSAGE(test::run_shell(cmd2) == 0, cmd2);
  const std::string hello_json = test::read_file_bytes(dir / "hello.json");
  INFO(hello_json);
  CHECK(hello_json.find("\"payload_type\": \"Hello\"") != std::string::npos);
  CHECK(hello_json.find("\"protocol_version\": 1") != std::string::npos);
  CHECK(hello_json.find("\"mesh_triangle_count\": 12") != std::string::npos);
  CHECK(hello_json.find("\"mesh_checksum\": " + std::to_string(mesh_checksum(cube))) !=
        std::string::npos);
  CHECK(hello_json.find("\"image_width\": 480") != std::string::npos);
  CHECK(hello_json.find("\"fy\": 401") != std::string::npos);
  const std::string colours_json = test::read_file_bytes(dir / "colours.json");
  INFO(colours_json);
  CHECK(colours_json.find("\"payload_type\": \"ColourDelta\"") != std::string::npos);
  CHECK(colours_json.find("\"triangle\": 11") != std::string::npos);
  CHECK(colours_json.find("\"r\": 255") != std::string::npos);
  // Translation: flatc prints doubles its own way; compare the numbers.
  for (const char* key : {"\"tx\": ", "\"ty\": ", "\"tz\": ", "\"qw\": "}) {
    CAPTURE(key);
    const std::size_t at = json.find(key);
    REQUIRE(at != std::string::npos);
    const double v = std::strtod(json.c_str() + at + std::strlen(key), nullptr);
    const double want = std::string(key) == "\"tx\": "   ? p.t_mm[0]
                        : std::string(key) == "\"ty\": " ? p.t_mm[1]
                        : std::string(key) == "\"tz\": " ? p.t_mm[2]
                                                         : p.q_xyzw[3];
    CHECK(v == doctest::Approx(want).epsilon(1e-9));
  }
}

TEST_CASE("console_protocol: a pose's evidence (outline, shading) round trips, an older sender's reads as none") {
  StreamEncoder enc;
  PoseSample p = sample_pose();
  p.inliers = 0;
  p.quality = 0;
  p.by_outline = true;
  p.outline_lines = 212;
  p.outline_sigma_px = 2.25f;
  p.joint_sigma_px = 0.5f;
  p.outline_shading_px = 1.75f;
  const Bytes bytes = copy(enc.pose(p));
  auto d = decode_message(bytes);
  REQUIRE_MESSAGE(d.ok(), d.message());
  CHECK(d->pose.by_outline);
  CHECK(d->pose.outline_lines == 212);
  CHECK(d->pose.outline_sigma_px == 2.25f);
  CHECK(d->pose.joint_sigma_px == 0.5f);
  CHECK(d->pose.outline_shading_px == 1.75f);
  // A feature pose with nothing measured by the outline.
  const Bytes plain = copy(enc.pose(sample_pose()));
  auto f = decode_message(plain);
  REQUIRE(f.ok());
  CHECK_FALSE(f->pose.by_outline);
  CHECK(f->pose.outline_lines == 0);
  CHECK(f->pose.outline_sigma_px == -1.f);
  // A sender from before the evidence field: a PoseUpdate with the pose only.
  flatbuffers::FlatBufferBuilder fbb;
  const stream::Pose wire(7, stream::TrackingState::Tracking, 90, 0, 0, 0, 0, 1, 1, 2, 3, 0.5f, 100);
  const auto update = stream::CreatePoseUpdate(fbb, &wire);
  stream::FinishSizePrefixedMessageBuffer(fbb, stream::CreateMessage(fbb, stream::Payload::PoseUpdate, update.Union()));
  const Bytes old(fbb.GetBufferPointer(), fbb.GetBufferPointer() + fbb.GetSize());
  auto o = decode_message(old);
  REQUIRE_MESSAGE(o.ok(), o.message());
  CHECK(o->pose.frame == 7);
  CHECK(o->pose.inliers == 90);
  CHECK_FALSE(o->pose.by_outline);
  CHECK(o->pose.outline_lines == 0);
  CHECK(o->pose.joint_sigma_px == -1.f);
}

TEST_CASE("console_protocol: endpoints parse, bad ones say why") {
  platform::Endpoint e;
  std::string err;
  REQUIRE(platform::parse_endpoint("tcp://127.0.0.1:7700", &e, &err));
  CHECK(e.kind == platform::Endpoint::Kind::kTcp);
  CHECK(e.port == 7700);
  CHECK(e.to_string() == "tcp://127.0.0.1:7700");
  REQUIRE(platform::parse_endpoint("unix:/tmp/st.sock", &e, &err));
  CHECK(e.path == "/tmp/st.sock");
  for (const char* bad : {"", "tcp://", "tcp://host", "tcp://:7700", "tcp://1.2.3.4:99999",
                          "tcp://1.2.3.4:7x", "unix:", "udp://1.2.3.4:5", "/tmp/sock"}) {
    CAPTURE(bad);
    err.clear();
    CHECK_FALSE(platform::parse_endpoint(bad, &e, &err));
    CHECK_FALSE(err.empty());
  }
  CHECK_FALSE(platform::parse_endpoint("unix:/" + std::string(200, 'a'), &e, &err));
}

TEST_CASE(
    "console_protocol: the console session takes bytes: bad buffers rejected, wrong mesh refused") {
  const Mesh cube = test::centred_cube(40);
  StreamEncoder enc;
  console::ConsoleSession session(&cube);
  REQUIRE(session.feed(enc.hello(sample_hello(cube))).ok());
  REQUIRE(session.has_hello());
  REQUIRE(session.feed(enc.pose(sample_pose())).ok());
  const std::vector<ColourUpdate> cols = {{3, 10, 20, 30},
                                          {99, 1, 2, 3}};  // 99: not a triangle of the cube
  REQUIRE(session.feed(enc.colours(cols)).ok());
  CHECK(session.coloured_triangles() == 1);
  CHECK(session.face_rgb()[9] == 10);
  CHECK(session.rejected() == 1);
  CHECK(session.last_error().find("triangle 99") != std::string::npos);
  // A verified-size buffer with garbage inside: rejected, the session goes on.
  Bytes bad = copy(enc.pose(sample_pose()));
  for (std::size_t i = 8; i < bad.size(); ++i) bad[i] = static_cast<std::uint8_t>(i * 37);
  REQUIRE(session.feed(bad).ok());
  CHECK(session.rejected() == 2);
  REQUIRE(session.feed(enc.pose(sample_pose())).ok());
  CHECK(session.poses().size() == 2);
  CHECK(session.out_of_order_poses() == 1);  // the same frame twice
  // An oversized prefix ends the session.
  const std::uint8_t huge[8] = {0xff, 0xff, 0xff, 0x0f, 0, 0, 0, 0};
  CHECK_FALSE(session.feed(huge).ok());
  // A hello for another mesh is refused.
  console::ConsoleSession other(&cube);
  const Mesh bigger = test::centred_cube(41);
  const Status s = other.feed(enc.hello(sample_hello(bigger)));
  CHECK_FALSE(s.ok());
  CHECK(s.message().find("not the mesh") != std::string::npos);
}
