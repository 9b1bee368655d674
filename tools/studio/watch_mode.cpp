#include "tools/studio/watch_mode.h"

#include <poll.h>
#include <sys/socket.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <vector>

#include "core/formats/text_scan.h"
#include "platform/clock.h"

namespace st::studio {

namespace {

constexpr int kRetryMs = 500;     // between attempts to reach the tracker
constexpr int kFrameEveryMs = 30;  // at most ~33 frames a second to the pages

Outgoing stream_message(std::span<const std::uint8_t> sized, std::uint32_t frame) {
  std::string bytes = binary_header(BinaryKind::kStream, frame);
  bytes.append(reinterpret_cast<const char*>(sized.data()), sized.size());
  return binary_message(std::move(bytes));
}

}  // namespace

WatchController::WatchController(Result<LoadedSequence> sequence, std::string endpoint, WebServer* server)
    : endpoint_text_(std::move(endpoint)), server_(server) {
  if (!sequence) {
    error_ = sequence.message();
    return;
  }
  seq_ = std::move(sequence.value());
  std::string e;
  if (!platform::parse_endpoint(endpoint_text_, &endpoint_, &e)) error_ = "--stream: " + e;
  mesh_message_ = binary_message(binary_header(BinaryKind::kMesh, 0) + mesh_payload(seq_->mesh));
}

WatchController::~WatchController() { stop(); }

Status WatchController::start() {
  if (!error_.empty()) return Status::Ok();  // pages are told; nothing to run
  link_thread_ = std::thread([this] { link_loop(); });
  frame_thread_ = std::thread([this] { frame_loop(); });
  return Status::Ok();
}

void WatchController::stop() {
  stop_ = true;
  new_pose_.notify_all();
  if (link_thread_.joinable()) link_thread_.join();
  if (frame_thread_.joinable()) frame_thread_.join();
}

std::string WatchController::link_json() const {
  return "{\"type\":\"link\",\"state\":" + json_string(link_state_) + ",\"endpoint\":" +
         json_string(endpoint_text_) + ",\"message\":" + json_string(link_message_) + "}";
}

void WatchController::set_link(const char* state, const std::string& message) {
  std::string json;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (link_state_ == state && link_message_ == message) return;
    link_state_ = state;
    link_message_ = message;
    json = link_json();
  }
  std::printf("scopetrack-studio: %s %s%s%s\n", endpoint_text_.c_str(), state, message.empty() ? "" : ": ",
              message.c_str());
  std::fflush(stdout);
  server_->broadcast(text_message(std::move(json)));
}

void WatchController::link_loop() {
  std::vector<std::uint8_t> rx(64 * 1024);
  while (!stop_) {
    std::string error;
    platform::Fd fd = platform::connect_to(endpoint_, &error);
    if (!fd.valid()) {
      set_link("connecting", "waiting for the tracker (" + error + ")");
      for (int waited = 0; waited < kRetryMs && !stop_; waited += 50)
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
      continue;
    }
    {
      std::lock_guard<std::mutex> lock(mutex_);
      session_.emplace(&seq_->mesh);
      ++generation_;
      newest_pose_ = -1;
    }
    set_link("connected", "");
    MessageFramer framer;
    std::string why = "the tracker closed the stream (the run ended)";
    while (!stop_) {
      pollfd p{fd.get(), POLLIN, 0};
      if (::poll(&p, 1, 100) < 0 && errno != EINTR) break;
      if (!p.revents) continue;
      const std::span<std::uint8_t> area = framer.write_area();
      const ssize_t n = ::recv(fd.get(), area.data(), area.size(), 0);
      if (n == 0) break;
      if (n < 0) {
        if (errno == EINTR || errno == EAGAIN) continue;
        why = std::string("connection lost: ") + std::strerror(errno);
        break;
      }
      framer.commit(static_cast<std::size_t>(n));
      std::span<const std::uint8_t> msg;
      std::string frame_error;
      MessageFramer::Next next;
      bool fatal = false;
      while ((next = framer.next(&msg, &frame_error)) == MessageFramer::Next::kMessage) {
        std::lock_guard<std::mutex> lock(mutex_);
        const std::int64_t rejected = session_->rejected();
        if (Status s = session_->handle_buffer(msg); !s) {
          why = "stream refused: " + s.message();
          fatal = true;
          break;
        }
        if (session_->rejected() > rejected) {
          std::fprintf(stderr, "scopetrack-studio: rejected a buffer: %s\n", session_->last_error().c_str());
          continue;  // not forwarded: the pages read only verified buffers
        }
        std::uint32_t frame = 0;
        if (!session_->poses().empty()) frame = session_->poses().back().frame;
        server_->broadcast(stream_message(msg, frame));
        if (static_cast<std::int64_t>(session_->poses().size()) - 1 != newest_pose_) {
          newest_pose_ = static_cast<std::int64_t>(session_->poses().size()) - 1;
          new_pose_.notify_all();
        }
      }
      if (next == MessageFramer::Next::kError) {
        why = "stream refused: " + frame_error;
        fatal = true;
      }
      if (fatal) break;
    }
    if (!stop_) set_link("disconnected", why);
    for (int waited = 0; waited < kRetryMs && !stop_; waited += 50)
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
}

void WatchController::frame_loop() {
  VideoFrames video;
  overlay::OverlayRenderer renderer;
  std::string setup_error;
  if (Status s = video.open(seq_->video_path); !s) setup_error = s.message();
  if (Status s = renderer.configure(*seq_, studio_overlay_style()); !s && setup_error.empty())
    setup_error = s.message();
  if (!setup_error.empty()) {
    set_link("disconnected", "the studio cannot show the video: " + setup_error);
    return;
  }
  std::int64_t shown = -1;
  std::uint64_t shown_generation = 0;
  std::string last_video_error;
  while (!stop_) {
    PoseSample pose;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      new_pose_.wait_for(lock, std::chrono::milliseconds(200), [&] {
        return stop_ || (newest_pose_ >= 0 && (newest_pose_ != shown || generation_ != shown_generation));
      });
      if (stop_) break;
      if (!session_ || newest_pose_ < 0 || (newest_pose_ == shown && generation_ == shown_generation)) continue;
      shown = newest_pose_;
      shown_generation = generation_;
      pose = session_->poses()[static_cast<std::size_t>(newest_pose_)];
    }
    const std::int64_t t0 = platform::monotonic_ns();
    auto frame = video.frame(static_cast<int>(pose.frame));
    if (!frame) {
      if (frame.message() != last_video_error) {
        last_video_error = frame.message();
        server_->broadcast(error_message("frame " + std::to_string(pose.frame) + ": " + frame.message()));
      }
      continue;
    }
    std::string jpeg = binary_header(BinaryKind::kFrame, pose.frame) + encode_jpeg(frame.value());
    std::string png = binary_header(BinaryKind::kOverlay, pose.frame);
    if (pose.state != TrackState::kLost) {
      const SE3 T = T_model_camera(pose);
      overlay::FrameAnnotations a;
      a.index = static_cast<int>(pose.frame);
      a.T_model_camera = &T;
      png += encode_png(renderer.draw_layer(a));
    }
    {
      std::lock_guard<std::mutex> lock(mutex_);
      last_frame_ = jpeg;
      last_overlay_ = png;
    }
    server_->broadcast(binary_message(std::move(jpeg), true));
    server_->broadcast(binary_message(std::move(png), true));
    // Pace: the tracker may run far faster than a page can draw.
    const std::int64_t spent_ms = (platform::monotonic_ns() - t0) / 1'000'000;
    if (spent_ms < kFrameEveryMs) std::this_thread::sleep_for(std::chrono::milliseconds(kFrameEveryMs - spent_ms));
  }
}

void WatchController::on_open(const PagePtr& page) {
  if (!error_.empty()) {
    page->send(error_message(error_));
    return;
  }
  page->send(text_message(info_json(*seq_, "watch", -1, 0, ",\"endpoint\":" + json_string(endpoint_text_))));
  page->send(mesh_message_);
  // Catch up: what the link kept, re-encoded in the stream's own messages.
  std::lock_guard<std::mutex> lock(mutex_);
  page->send(text_message(link_json()));
  if (!session_ || !session_->has_hello()) return;
  StreamEncoder enc;
  page->send(stream_message(enc.hello(session_->hello()), 0));
  for (const PoseSample& p : session_->poses()) page->send(stream_message(enc.pose(p), p.frame));
  std::vector<ColourUpdate> colours;
  const auto& rgb = session_->face_rgb();
  const auto& has = session_->has_colour();
  for (std::size_t t = 0; t < has.size(); ++t) {
    if (!has[t]) continue;
    colours.push_back({static_cast<std::uint32_t>(t), rgb[3 * t], rgb[3 * t + 1], rgb[3 * t + 2]});
    if (static_cast<int>(colours.size()) == kMaxColoursPerDelta) {
      page->send(stream_message(enc.colours(colours), 0));
      colours.clear();
    }
  }
  if (!colours.empty()) page->send(stream_message(enc.colours(colours), 0));
  if (session_->health()) page->send(stream_message(enc.health(*session_->health()), 0));
  if (!last_frame_.empty()) {
    page->send(binary_message(last_frame_, true));
    page->send(binary_message(last_overlay_, true));
  }
}

void WatchController::on_text(const PagePtr& page, std::string_view text) {
  page->send(error_message("the watch view takes no commands (got " + quote_bytes(text) + ")"));
}

}  // namespace st::studio
