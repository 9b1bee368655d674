// What scopetrack-console keeps from one connection: the Hello, every pose
// in order, the latest colour of every triangle, the latest health. Takes
// raw bytes as they arrive (feed()); every buffer is verified
// (hal/stream/stream_protocol.h decode_message) before it is read. Host tool: may
// allocate.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "core/mesh/mesh.h"
#include "core/base/result.h"
#include "hal/stream/stream_protocol.h"

namespace st::console {

class ConsoleSession {
 public:
  // mesh: the organ mesh the colours belong to (checked against the Hello's
  // triangle count and checksum); nullptr: colours are kept without a mesh.
  explicit ConsoleSession(const Mesh* mesh = nullptr) : mesh_(mesh) {}

  // Bytes as received. A buffer that fails verification is rejected (counted,
  // error text kept) and skipped; an oversized size prefix or a Hello for
  // another mesh or protocol ends the session (the returned Error).
  Status feed(std::span<const std::uint8_t> bytes);
  // One complete size-prefixed buffer (the framer's output, or a test's).
  Status handle_buffer(std::span<const std::uint8_t> buffer);

  bool has_hello() const { return hello_.has_value(); }
  const StreamHello& hello() const { return *hello_; }
  int hellos() const { return hellos_; }
  const std::vector<PoseSample>& poses() const { return poses_; }
  int out_of_order_poses() const { return out_of_order_; }
  // Per triangle: RGB (3 bytes) and whether a colour arrived.
  const std::vector<std::uint8_t>& face_rgb() const { return face_rgb_; }
  int coloured_triangles() const { return coloured_count_; }
  // Per triangle: 1 once a colour arrived.
  const std::vector<std::uint8_t>& has_colour() const { return has_colour_; }
  const std::optional<HealthSample>& health() const { return health_; }
  std::int64_t rejected() const { return rejected_; }
  const std::string& last_error() const { return last_error_; }
  std::int64_t messages() const { return messages_; }

  // One line: frame, state, fps, latency, drops, colours.
  std::string status_line() const;
  // trajectory.txt (TUM, poses that are not lost) and, with a mesh,
  // textured_mesh.ply (binary PLY, per-face RGB; uncoloured faces grey).
  Status write_record(const std::filesystem::path& dir) const;

 private:
  Status handle(const DecodedMessage& m);

  const Mesh* mesh_ = nullptr;
  MessageFramer framer_;
  std::optional<StreamHello> hello_;
  int hellos_ = 0;
  std::vector<PoseSample> poses_;
  int out_of_order_ = 0;
  std::vector<std::uint8_t> face_rgb_, has_colour_;
  int coloured_count_ = 0;
  std::optional<HealthSample> health_;
  std::int64_t rejected_ = 0, messages_ = 0;
  std::string last_error_;
};

}  // namespace st::console
