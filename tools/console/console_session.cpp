#include "tools/console/console_session.h"

#include <algorithm>
#include <cstdio>
#include <cstring>

#include "core/base/capacity.h"
#include "core/formats/trajectory.h"
#include "hal/storage/file_io.h"
#include "hal/storage/mesh_file.h"

namespace st::console {

Status ConsoleSession::feed(std::span<const std::uint8_t> bytes) {
  while (!bytes.empty()) {
    const std::span<std::uint8_t> area = framer_.write_area();
    const std::size_t n = std::min(area.size(), bytes.size());
    std::memcpy(area.data(), bytes.data(), n);
    framer_.commit(n);
    bytes = bytes.subspan(n);
    for (;;) {
      std::span<const std::uint8_t> message;
      std::string error;
      const MessageFramer::Next next = framer_.next(&message, &error);
      if (next == MessageFramer::Next::kNeedMore) break;
      if (next == MessageFramer::Next::kError) {
        ++rejected_;
        last_error_ = error;
        return make_error(error);
      }
      if (Status s = handle_buffer(message); !s) return s;
    }
  }
  return Status::Ok();
}

Status ConsoleSession::handle_buffer(std::span<const std::uint8_t> buffer) {
  auto m = decode_message(buffer);
  if (!m) {
    ++rejected_;
    last_error_ = m.message();
    return Status::Ok();  // framing is intact: skip this buffer, keep the session
  }
  ++messages_;
  return handle(m.value());
}

Status ConsoleSession::handle(const DecodedMessage& m) {
  switch (m.kind) {
    case MessageKind::kHello: {
      const StreamHello& h = m.hello;
      if (h.protocol_version != kStreamProtocolVersion)
        return make_error("protocol version " + std::to_string(h.protocol_version) +
                          ", this console speaks " + std::to_string(kStreamProtocolVersion));
      if (mesh_ && (h.mesh_triangle_count != static_cast<std::uint32_t>(mesh_->triangle_count()) ||
                    h.mesh_checksum != mesh_checksum(*mesh_)))
        return make_error("the tracker's mesh (" + std::to_string(h.mesh_triangle_count) +
                          " triangles) is not the mesh given with --mesh (" +
                          std::to_string(mesh_->triangle_count()) +
                          " triangles, or another checksum)");
      if (h.mesh_triangle_count > kMaxMeshTriangles)
        return make_error("hello: mesh triangle count out of range");
      if (!hello_ || hello_->mesh_triangle_count != h.mesh_triangle_count) {
        face_rgb_.assign(3 * static_cast<std::size_t>(h.mesh_triangle_count), 128);
        has_colour_.assign(h.mesh_triangle_count, 0);
        coloured_count_ = 0;
      }
      hello_ = h;
      ++hellos_;
      return Status::Ok();
    }
    case MessageKind::kPose:
      if (!poses_.empty() && m.pose.frame <= poses_.back().frame) ++out_of_order_;
      poses_.push_back(m.pose);
      return Status::Ok();
    case MessageKind::kColours:
      if (!hello_) return make_error("colour delta before the hello");
      for (const stream::TriangleColour* c : *m.colours) {
        const std::uint32_t t = c->triangle();
        if (t >= hello_->mesh_triangle_count) {
          ++rejected_;
          last_error_ = "colour for triangle " + std::to_string(t) + " of a " +
                        std::to_string(hello_->mesh_triangle_count) + "-triangle mesh";
          continue;
        }
        face_rgb_[3 * t] = c->r();
        face_rgb_[3 * t + 1] = c->g();
        face_rgb_[3 * t + 2] = c->b();
        coloured_count_ += has_colour_[t] ? 0 : 1;
        has_colour_[t] = 1;
      }
      return Status::Ok();
    case MessageKind::kHealth:
      health_ = m.health;
      return Status::Ok();
  }
  return Status::Ok();
}

std::string ConsoleSession::status_line() const {
  char buf[256];
  if (poses_.empty()) {
    std::snprintf(buf, sizeof(buf), "%s, no pose yet", hello_ ? "connected" : "waiting for hello");
    return buf;
  }
  const PoseSample& p = poses_.back();
  const HealthSample h = health_.value_or(HealthSample{});
  std::snprintf(buf, sizeof(buf),
                "frame %6u %-11s fps %5.1f  latency %6.2f ms  drops %u  overruns %u  colours %d/%u",
                p.frame, to_string(p.state), static_cast<double>(h.fps), p.latency_us * 1e-3,
                h.dropped_messages, h.overruns, coloured_count_,
                hello_ ? hello_->mesh_triangle_count : 0u);
  std::string line = buf;
  if (p.by_outline && p.state != TrackState::kLost) {
    std::snprintf(buf, sizeof(buf), "  by the outline (%u lines, %.1f px apart from the shading)",
                  static_cast<unsigned>(p.outline_lines), static_cast<double>(p.outline_shading_px));
    line += buf;
  }
  if (h.calibration_suspect) {
    std::snprintf(buf, sizeof(buf), "  CALIBRATION SUSPECT (the video fits focal lengths x%.3f)",
                  static_cast<double>(h.calibration_focal_scale));
    line += buf;
  }
  return line;
}

Status ConsoleSession::write_record(const std::filesystem::path& dir) const {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) return make_error("cannot create " + dir.string() + ": " + ec.message());
  std::string tum = "# scopetrack-console: T_model_camera per frame with a pose (TUM)\n";
  for (const PoseSample& p : poses_) {
    if (p.state == TrackState::kLost) continue;
    tum += format_tum_line({static_cast<double>(p.timestamp_ns) * 1e-9, T_model_camera(p)});
  }
  if (Status s = write_file(dir / "trajectory.txt", tum); !s) return s;
  if (mesh_ && !face_rgb_.empty())
    return save_mesh_ply(dir / "textured_mesh.ply", *mesh_, face_rgb_.data());
  return Status::Ok();
}

}  // namespace st::console
