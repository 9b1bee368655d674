// Stream sockets for the console link: endpoint strings, a listening socket
// (TCP or Unix, non-blocking), accept, connect. Linux only. Errors are
// returned as text for the caller to wrap (platform depends on nothing).
#pragma once

#include <string>
#include <string_view>

namespace st::platform {

struct Endpoint {
  enum class Kind { kTcp, kUnix };
  Kind kind = Kind::kTcp;
  std::string host;               // tcp: IPv4 address or "localhost"
  int port = 0;                   // tcp: 0 = any free port (listen only)
  std::string path;               // unix: socket file
  std::string to_string() const;  // "tcp://127.0.0.1:7700" or "unix:/path"
};

// "tcp://HOST:PORT" or "unix:PATH" (also "unix://PATH"). False with *error
// set on anything else: missing host or port, port outside 0..65535, a
// Unix path longer than sockaddr_un holds, empty path. error may be null.
bool parse_endpoint(std::string_view text, Endpoint* out, std::string* error);

// An owned file descriptor (closed on destruction).
class Fd {
 public:
  Fd() = default;
  explicit Fd(int fd) : fd_(fd) {}
  ~Fd() { reset(); }
  Fd(Fd&& o) noexcept : fd_(o.release()) {}
  Fd& operator=(Fd&& o) noexcept {
    if (this != &o) reset(o.release());
    return *this;
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  int get() const { return fd_; }
  bool valid() const { return fd_ >= 0; }
  int release() {
    const int f = fd_;
    fd_ = -1;
    return f;
  }
  void reset(int fd = -1);

 private:
  int fd_ = -1;
};

// A non-blocking listening socket. Unix: a stale socket file at the path is
// replaced (another file type there is an error). TCP: SO_REUSEADDR; with
// port 0 *bound (may be null) gets the port the kernel chose.
Fd listen_on(const Endpoint& endpoint, int backlog, Endpoint* bound, std::string* error);
// Accepts one pending connection as a non-blocking socket; invalid Fd when
// none is pending (or on error).
Fd accept_client(int listen_fd);
// A blocking connection to the endpoint (the console side).
Fd connect_to(const Endpoint& endpoint, std::string* error);

}  // namespace st::platform
