#include "platform/socket.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cstring>

namespace st::platform {

namespace {

std::string errno_text(const char* what, const Endpoint& e) {
  return std::string(what) + " " + e.to_string() + ": " + std::strerror(errno);
}

bool tcp_address(const Endpoint& e, sockaddr_in* addr, std::string* error) {
  std::memset(addr, 0, sizeof(*addr));
  addr->sin_family = AF_INET;
  addr->sin_port = htons(static_cast<std::uint16_t>(e.port));
  const std::string host = e.host == "localhost" ? "127.0.0.1" : e.host;
  if (inet_pton(AF_INET, host.c_str(), &addr->sin_addr) != 1) {
    *error = "not an IPv4 address: '" + e.host + "' (use e.g. tcp://127.0.0.1:7700)";
    return false;
  }
  return true;
}

void unix_address(const Endpoint& e, sockaddr_un* addr) {
  std::memset(addr, 0, sizeof(*addr));
  addr->sun_family = AF_UNIX;
  std::memcpy(addr->sun_path, e.path.data(), e.path.size());  // length checked by parse_endpoint
}

}  // namespace

std::string Endpoint::to_string() const {
  return kind == Kind::kUnix ? "unix:" + path : "tcp://" + host + ":" + std::to_string(port);
}

bool parse_endpoint(std::string_view text, Endpoint* out, std::string* error_out) {
  std::string ignored;
  std::string* error = error_out ? error_out : &ignored;
  Endpoint e;
  if (text.starts_with("unix:")) {
    e.kind = Endpoint::Kind::kUnix;
    text.remove_prefix(5);
    if (text.starts_with("//")) text.remove_prefix(2);
    if (text.empty() || text.size() >= sizeof(sockaddr_un::sun_path)) {
      *error = "unix endpoint needs a path shorter than " +
               std::to_string(sizeof(sockaddr_un::sun_path)) + " bytes (unix:/tmp/scopetrack.sock)";
      return false;
    }
    e.path = std::string(text);
  } else if (text.starts_with("tcp://")) {
    text.remove_prefix(6);
    const std::size_t colon = text.rfind(':');
    if (colon == std::string_view::npos || colon == 0 || colon + 1 == text.size()) {
      *error = "tcp endpoint needs HOST:PORT (tcp://127.0.0.1:7700)";
      return false;
    }
    e.host = std::string(text.substr(0, colon));
    const std::string_view port = text.substr(colon + 1);
    const auto [end, ec] = std::from_chars(port.data(), port.data() + port.size(), e.port);
    if (ec != std::errc() || end != port.data() + port.size() || e.port < 0 || e.port > 65535) {
      *error = "tcp port must be a number 0..65535, got '" + std::string(port) + "'";
      return false;
    }
  } else {
    *error = "endpoint must be tcp://HOST:PORT or unix:PATH, got '" + std::string(text) + "'";
    return false;
  }
  *out = std::move(e);
  return true;
}

void Fd::reset(int fd) {
  if (fd_ >= 0) ::close(fd_);
  fd_ = fd;
}

Fd listen_on(const Endpoint& e, int backlog, Endpoint* bound, std::string* error) {
  const bool is_unix = e.kind == Endpoint::Kind::kUnix;
  Fd fd(::socket(is_unix ? AF_UNIX : AF_INET, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0));
  if (!fd.valid()) {
    *error = errno_text("cannot create a socket for", e);
    return {};
  }
  int rc = -1;
  if (is_unix) {
    struct stat st {};
    if (::lstat(e.path.c_str(), &st) == 0) {
      if (!S_ISSOCK(st.st_mode)) {
        *error =
            "cannot listen on " + e.to_string() + ": a file that is not a socket is in the way";
        return {};
      }
      ::unlink(e.path.c_str());  // a stale socket of an earlier run
    }
    sockaddr_un addr;
    unix_address(e, &addr);
    rc = ::bind(fd.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof(addr));
  } else {
    sockaddr_in addr;
    if (!tcp_address(e, &addr, error)) return {};
    const int one = 1;
    ::setsockopt(fd.get(), SOL_SOCKET, SO_REUSEADDR, &one, sizeof(one));
    rc = ::bind(fd.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof(addr));
  }
  if (rc != 0 || ::listen(fd.get(), backlog) != 0) {
    *error = errno_text("cannot listen on", e);
    return {};
  }
  if (bound) {
    *bound = e;
    sockaddr_in addr{};
    socklen_t len = sizeof(addr);
    if (!is_unix && ::getsockname(fd.get(), reinterpret_cast<sockaddr*>(&addr), &len) == 0)
      bound->port = ntohs(addr.sin_port);
  }
  return fd;
}

Fd accept_client(int listen_fd) {
  Fd fd(::accept4(listen_fd, nullptr, nullptr, SOCK_NONBLOCK | SOCK_CLOEXEC));
  if (fd.valid()) {
    const int one = 1;  // poses are small and latency matters (fails harmlessly on Unix sockets)
    ::setsockopt(fd.get(), IPPROTO_TCP, TCP_NODELAY, &one, sizeof(one));
  }
  return fd;
}

Fd connect_to(const Endpoint& e, std::string* error) {
  const bool is_unix = e.kind == Endpoint::Kind::kUnix;
  Fd fd(::socket(is_unix ? AF_UNIX : AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0));
  if (!fd.valid()) {
    *error = errno_text("cannot create a socket for", e);
    return {};
  }
  int rc = -1;
  if (is_unix) {
    sockaddr_un addr;
    unix_address(e, &addr);
    rc = ::connect(fd.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof(addr));
  } else {
    sockaddr_in addr;
    if (!tcp_address(e, &addr, error)) return {};
    rc = ::connect(fd.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof(addr));
  }
  if (rc != 0) {
    *error = errno_text("cannot connect to", e);
    return {};
  }
  return fd;
}

}  // namespace st::platform
