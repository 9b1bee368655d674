// scopetrack-studio watch: the tracking shown live. A link thread connects
// to the tracker's console stream as a console does (retrying while the
// tracker is not there, again after a run ends), verifies every buffer
// (tools/console/console_session.h) and forwards it to the pages as it came;
// a frame thread reads the sequence's video to the newest streamed frame
// and sends it with the organ drawn at that frame's pose (nothing when
// lost). A page that connects late, or reconnects, first gets what the link
// has kept: the Hello, every pose, every triangle's latest colour, the
// latest health and the last frame. Host tool code.
#pragma once

#include <atomic>
#include <condition_variable>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "hal/storage/sequence_loader.h"
#include "platform/socket.h"
#include "tools/console/console_session.h"
#include "tools/overlay/overlay.h"
#include "tools/studio/studio_media.h"
#include "tools/studio/web_server.h"

namespace st::studio {

class WatchController final : public PageHandler {
 public:
  // sequence: the loaded sequence, or the error to show every page.
  WatchController(Result<LoadedSequence> sequence, std::string endpoint, WebServer* server);
  ~WatchController() override;

  // Starts the link and frame threads (not when the sequence failed).
  Status start();
  void stop();

  void on_open(const PagePtr& page) override;
  void on_text(const PagePtr& page, std::string_view text) override;

 private:
  void link_loop();
  void frame_loop();
  void set_link(const char* state, const std::string& message);
  std::string link_json() const;  // under mutex_

  std::string error_;
  std::optional<LoadedSequence> seq_;
  std::string endpoint_text_;
  Outgoing mesh_message_;  // encoded once: the same for every page
  platform::Endpoint endpoint_;
  WebServer* server_;
  std::thread link_thread_, frame_thread_;
  std::atomic<bool> stop_{false};

  mutable std::mutex mutex_;             // guards everything below
  std::condition_variable new_pose_;
  std::optional<console::ConsoleSession> session_;  // the current connection's
  std::string link_state_ = "connecting", link_message_;
  std::uint64_t generation_ = 0;         // connections made so far
  std::int64_t newest_pose_ = -1;        // index into session_->poses()
  std::string last_frame_, last_overlay_;  // the last frame sent, with headers
};

}  // namespace st::studio
