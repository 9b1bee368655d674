// scopetrack-studio's HTTP + WebSocket server (Boost.Beast, header-only in
// Debian's libboost-dev; asynchronous, on one io thread). It serves the
// page's files from one folder and hands each page's WebSocket to a
// PageHandler: text commands in, text (JSON) and binary messages out.
// Every page has its own send queue: frames are droppable (a slow page
// skips frames, the newest wins), stream messages are not (a page whose
// queue still grows past a bound is disconnected). A page that disconnects
// or sends a malformed frame ends only its own connection. Host tool code.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <string_view>

#include "core/base/result.h"

namespace st::studio {

class PageConnection;
using PagePtr = std::shared_ptr<PageConnection>;

// One outgoing message (shared, so a broadcast does not copy it per page).
struct Outgoing {
  std::shared_ptr<const std::string> bytes;
  bool binary = false;
  bool droppable = false;  // a frame: may be skipped for a slow page
};
Outgoing text_message(std::string json);
Outgoing binary_message(std::string bytes, bool droppable = false);

// One page's WebSocket (created by the server). send() from any thread.
class PageConnection {
 public:
  virtual ~PageConnection() = default;
  virtual void send(Outgoing m) = 0;
  virtual std::uint64_t id() const = 0;
};

// Called on the server's io thread.
class PageHandler {
 public:
  virtual ~PageHandler() = default;
  virtual void on_open(const PagePtr& page) = 0;
  virtual void on_text(const PagePtr& page, std::string_view text) = 0;
  virtual void on_close(const PagePtr& /*page*/) {}
};

struct ServerOptions {
  std::string address = "127.0.0.1";  // another address only when asked
  int port = 8090;                    // 0: any free port (port() says which)
  std::filesystem::path web_dir;      // the page's files (index.html, the bundle)
  std::size_t max_command_bytes = 1 << 20;      // a page's message above this closes it
  std::size_t max_queued_bytes = 256u << 20;    // undroppable bytes a page may owe
};

class WebServer {
 public:
  WebServer();
  ~WebServer();
  WebServer(const WebServer&) = delete;
  WebServer& operator=(const WebServer&) = delete;

  // Binds and listens (errors: a bad address, a port in use, no index.html).
  Status start(const ServerOptions& options, PageHandler* handler);
  int port() const;
  // Runs the io loop on the calling thread until stop() or SIGINT/SIGTERM.
  void run();
  void stop();  // any thread
  // To every open page (any thread).
  void broadcast(const Outgoing& m);
  // Runs fn on the io thread (any thread).
  void post(std::function<void()> fn);
  int pages() const;

  struct Impl;  // the io context, the acceptor, the open pages (web_server.cpp)

 private:
  std::unique_ptr<Impl> impl_;
};

// Minimal JSON writing for the server's messages.
std::string json_string(std::string_view s);  // quoted and escaped
std::string json_number(double v);            // finite: %.10g; otherwise null
// {"type":"error","message":...}: what a page shows as an error.
Outgoing error_message(std::string_view message);

// The 8-byte header of a binary message: kind, 3 zero bytes, frame (LE).
enum class BinaryKind : std::uint8_t { kMesh = 1, kFrame = 2, kOverlay = 3, kStream = 4 };
std::string binary_header(BinaryKind kind, std::uint32_t frame);

}  // namespace st::studio
