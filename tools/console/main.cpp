// scopetrack-console ENDPOINT [--record DIR] [--mesh FILE] [--connect-timeout S]
// A surgical-console stand-in: connects to `scopetrack --stream ENDPOINT`,
// verifies every buffer, shows a live status line on a terminal, and at the
// end of the stream (or Ctrl-C) writes DIR/trajectory.txt (TUM) and, with
// --mesh (the sequence's organ.ply), DIR/textured_mesh.ply with the
// streamed triangle colours. Exit: 0 stream ended cleanly, 1 connection or
// stream error (a clear message; what was received is still written), 2 usage.
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "core/formats/text_scan.h"
#include "hal/storage/mesh_file.h"
#include "platform/clock.h"
#include "platform/socket.h"
#include "tools/console/console_session.h"

namespace {

volatile std::sig_atomic_t g_stop = 0;
void on_signal(int) { g_stop = 1; }

struct Args {
  std::string endpoint, record, mesh;
  double connect_timeout_s = 10;
};

bool parse(int argc, char** argv, Args* a) {
  if (argc < 2 || argv[1][0] == '-') return false;
  a->endpoint = argv[1];
  for (int i = 2; i < argc; ++i) {
    const bool has_value = i + 1 < argc;
    if (!std::strcmp(argv[i], "--record") && has_value) {
      a->record = argv[++i];
    } else if (!std::strcmp(argv[i], "--mesh") && has_value) {
      a->mesh = argv[++i];
    } else if (!std::strcmp(argv[i], "--connect-timeout") && has_value) {
      if (!st::parse_double_in(argv[++i], 0.0, 86400.0, &a->connect_timeout_s)) {
        std::fprintf(stderr, "scopetrack-console: --connect-timeout takes seconds in 0..86400\n");
        return false;
      }
    } else {
      std::fprintf(stderr, "scopetrack-console: unknown or incomplete argument '%s'\n", argv[i]);
      return false;
    }
  }
  return true;
}

// Retries until the tracker listens (it may still be loading) or the timeout.
st::platform::Fd connect_retrying(const st::platform::Endpoint& ep, double timeout_s) {
  const std::int64_t deadline =
      st::platform::monotonic_ns() + static_cast<std::int64_t>(timeout_s * 1e9);
  std::string error;
  for (;;) {
    st::platform::Fd fd = st::platform::connect_to(ep, &error);
    if (fd.valid() || g_stop) return fd;
    if (st::platform::monotonic_ns() > deadline) {
      std::fprintf(stderr, "scopetrack-console: %s (gave up after %.0f s)\n", error.c_str(),
                   timeout_s);
      return fd;
    }
    st::platform::sleep_until_ns(st::platform::monotonic_ns() + 50'000'000);
  }
}

// Receives until the stream ends, a fatal stream error, or a signal.
// Returns the exit status.
int receive(int fd, st::console::ConsoleSession& session, bool live) {
  std::vector<std::uint8_t> buf(64 * 1024);
  std::int64_t next_status_ns = 0, rejected_shown = 0;
  for (;;) {
    if (g_stop) return 0;
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 100) < 0 && errno != EINTR) return 1;
    if (p.revents) {
      const ssize_t n = ::recv(fd, buf.data(), buf.size(), 0);
      if (n == 0) return 0;  // the tracker closed the stream
      if (n < 0 && errno != EINTR && errno != EAGAIN) {
        std::fprintf(stderr, "\nscopetrack-console: connection lost: %s\n", std::strerror(errno));
        return 1;
      }
      if (n > 0) {
        if (st::Status s = session.feed({buf.data(), static_cast<std::size_t>(n)}); !s) {
          std::fprintf(stderr, "\nscopetrack-console: stream rejected: %s\n", s.message().c_str());
          return 1;
        }
      }
    }
    if (session.rejected() > rejected_shown) {
      rejected_shown = session.rejected();
      std::fprintf(stderr, "\nscopetrack-console: rejected a buffer: %s\n",
                   session.last_error().c_str());
    }
    if (live && st::platform::monotonic_ns() >= next_status_ns) {
      std::fprintf(stderr, "\r%s\033[K", session.status_line().c_str());
      next_status_ns = st::platform::monotonic_ns() + 100'000'000;
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  Args args;
  const char* usage =
      "usage: scopetrack-console tcp://HOST:PORT|unix:PATH [--record DIR] [--mesh FILE] [--connect-timeout S]\n";
  if (argc == 2 && (!std::strcmp(argv[1], "--help") || !std::strcmp(argv[1], "-h"))) {
    std::fputs(usage, stdout);
    return 0;
  }
  if (!parse(argc, argv, &args)) {
    std::fputs(usage, stderr);
    return 2;
  }
  st::platform::Endpoint ep;
  std::string error;
  if (!st::platform::parse_endpoint(args.endpoint, &ep, &error)) {
    std::fprintf(stderr, "scopetrack-console: %s\n", error.c_str());
    return 2;
  }
  st::Mesh mesh;
  if (!args.mesh.empty()) {
    auto m = st::load_mesh_file(args.mesh, nullptr);
    if (!m) {
      std::fprintf(stderr, "scopetrack-console: %s\n", m.message().c_str());
      return 1;
    }
    mesh = std::move(m.value());
  }
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  st::platform::Fd fd = connect_retrying(ep, args.connect_timeout_s);
  if (!fd.valid()) return 1;
  st::console::ConsoleSession session(args.mesh.empty() ? nullptr : &mesh);
  const int code = receive(fd.get(), session, ::isatty(STDERR_FILENO) == 1);
  std::fprintf(stderr, "\n");
  std::printf(
      "%zu poses (%d out of order), %d hello(s), %d triangles coloured, %lld buffers rejected\n",
      session.poses().size(), session.out_of_order_poses(), session.hellos(),
      session.coloured_triangles(), static_cast<long long>(session.rejected()));
  if (session.health() && session.health()->calibration_suspect)
    std::printf("the tracker judged the calibration suspect: the video fits focal lengths %.3f x the calibrated"
                " ones (or the organ differs from its prior in shape); the poses may be off by degrees and mm\n",
                static_cast<double>(session.health()->calibration_focal_scale));
  if (!args.record.empty()) {
    if (st::Status s = session.write_record(args.record); !s) {
      std::fprintf(stderr, "scopetrack-console: %s\n", s.message().c_str());
      return 1;
    }
    std::printf("-> %s\n", args.record.c_str());
  }
  return code;
}
