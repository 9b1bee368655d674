// scopetrack-studio: registration by pointing and the tracking watched
// live, in a browser (the page is tools/studio/web, built into the build
// folder's studio-web/dist).
//   scopetrack-studio register SEQ [--frame N]
//   scopetrack-studio watch SEQ --stream tcp://HOST:PORT|unix:PATH
//   scopetrack-studio mask SEQ --frame N --out FILE.pgm
// Common: --port P (8090; 0 picks a free one), --address A (127.0.0.1),
// --web DIR. Prints the page's address on stdout once listening.
// Exit: 0 stopped by a signal, 1 cannot start (port, page not built, a
// mask that cannot be made), 2 bad command line.
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <string>

#include "core/evaluation/evaluation.h"
#include "core/formats/text_scan.h"
#include "hal/storage/file_io.h"
#include "tools/studio/register_mode.h"
#include "tools/studio/watch_mode.h"

#ifndef SCOPETRACK_STUDIO_WEB
#define SCOPETRACK_STUDIO_WEB ""
#endif

namespace {

int usage(int status) {
  std::fprintf(status == 0 ? stdout : stderr,
               "usage: scopetrack-studio register SEQUENCE_DIR [--frame N (0)]\n"
               "       scopetrack-studio watch SEQUENCE_DIR --stream tcp://HOST:PORT|unix:PATH\n"
               "       scopetrack-studio mask SEQUENCE_DIR --frame N --out FILE.pgm\n"
               "  register: pick pairs (a point of the frame, the same point on the mesh) in the page;\n"
               "            Save writes T_camera_model_init into SEQUENCE_DIR/sequence.yaml\n"
               "  watch:    the page shows `scopetrack --sequence SEQUENCE_DIR --stream ENDPOINT` live\n"
               "  mask:     the organ's mask (255) at frame N's ground-truth pose, through the lens\n"
               "            distortion, as a binary PGM (the reference the browser tests compare with)\n"
               "options: --port P (8090; 0: any free port)  --address A (127.0.0.1: this machine only)\n"
               "         --web DIR (the built page; default: the build's studio-web/dist)\n");
  return status;
}

int make_mask(const std::filesystem::path& dir, int frame, const std::filesystem::path& out) {
  auto seq = st::load_sequence(dir);
  if (!seq) return std::fprintf(stderr, "scopetrack-studio: %s\n", seq.message().c_str()), 1;
  if (seq->groundtruth.empty())
    return std::fprintf(stderr, "scopetrack-studio: %s has no ground truth\n", dir.c_str()), 1;
  // The evaluation's rule for which frame a ground-truth pose belongs to;
  // the video itself is not read, so any frame number may be asked.
  const st::TimedPose* pose = nullptr;
  for (const st::TimedPose& p : seq->groundtruth)
    if (st::frame_for_timestamp(p.timestamp_s, seq->config.fps, std::numeric_limits<int>::max()) == frame) pose = &p;
  if (!pose) return std::fprintf(stderr, "scopetrack-studio: no ground-truth pose for frame %d\n", frame), 1;
  st::overlay::OverlayRenderer renderer;
  st::overlay::OverlayStyle style;
  style.state = style.text = style.markers = false;
  if (st::Status s = renderer.configure(seq.value(), style); !s)
    return std::fprintf(stderr, "scopetrack-studio: %s\n", s.message().c_str()), 1;
  st::overlay::FrameAnnotations a;
  a.index = frame;
  a.T_model_camera = &pose->T_model_camera;
  (void)renderer.draw_layer(a);
  const auto labels = renderer.labels();
  std::string pgm = "P5\n" + std::to_string(labels.width) + " " + std::to_string(labels.height) + "\n255\n";
  for (int y = 0; y < labels.height; ++y)
    for (int x = 0; x < labels.width; ++x) pgm += labels(x, y) >= 0 ? '\xff' : '\0';
  if (st::Status s = st::write_file(out, pgm); !s)
    return std::fprintf(stderr, "scopetrack-studio: %s\n", s.message().c_str()), 1;
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) return usage(2);
  const std::string mode = argv[1];
  if (mode == "--help" || mode == "-h") return usage(0);
  if (mode != "register" && mode != "watch" && mode != "mask") {
    std::fprintf(stderr, "scopetrack-studio: unknown mode '%s'\n", mode.c_str());
    return usage(2);
  }
  std::string seq_dir, endpoint, out;
  long long frame = 0, port = 8090;
  st::studio::ServerOptions server_options;
  server_options.web_dir = SCOPETRACK_STUDIO_WEB;
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    const bool has_value = i + 1 < argc;
    if (a == "--help" || a == "-h") return usage(0);
    if (a == "--frame" && has_value) {
      if (!st::parse_int64_in(argv[++i], 0, 10'000'000, &frame))
        return std::fprintf(stderr, "scopetrack-studio: --frame wants a frame number\n"), 2;
    } else if (a == "--port" && has_value) {
      if (!st::parse_int64_in(argv[++i], 0, 65535, &port))
        return std::fprintf(stderr, "scopetrack-studio: --port wants 0..65535\n"), 2;
    } else if (a == "--address" && has_value) {
      server_options.address = argv[++i];
    } else if (a == "--web" && has_value) {
      server_options.web_dir = argv[++i];
    } else if (a == "--stream" && has_value) {
      endpoint = argv[++i];
    } else if (a == "--out" && has_value) {
      out = argv[++i];
    } else if (!a.empty() && a[0] == '-') {
      std::fprintf(stderr, "scopetrack-studio: unknown or incomplete argument '%s'\n", a.c_str());
      return usage(2);
    } else if (seq_dir.empty()) {
      seq_dir = a;
    } else {
      std::fprintf(stderr, "scopetrack-studio: unexpected argument '%s'\n", a.c_str());
      return usage(2);
    }
  }
  if (seq_dir.empty()) return usage(2);
  if (mode == "mask") {
    if (out.empty()) return std::fprintf(stderr, "scopetrack-studio: mask wants --out FILE.pgm\n"), 2;
    return make_mask(seq_dir, static_cast<int>(frame), out);
  }
  if (mode == "watch" && endpoint.empty())
    return std::fprintf(stderr, "scopetrack-studio: watch wants --stream ENDPOINT (the tracker's)\n"), 2;
  server_options.port = static_cast<int>(port);

  // A sequence the checks refuse still gets a server: the page shows why.
  auto sequence = mode == "register" ? [&] {
    return st::load_sequence(seq_dir);
  }()
                                     : st::studio::load_checked_sequence(seq_dir);
  if (!sequence) std::fprintf(stderr, "scopetrack-studio: %s\n", sequence.message().c_str());
  st::studio::WebServer server;
  std::unique_ptr<st::studio::RegisterController> reg;
  std::unique_ptr<st::studio::WatchController> watch;
  st::studio::PageHandler* handler = nullptr;
  if (mode == "register") {
    reg = std::make_unique<st::studio::RegisterController>(std::move(sequence), static_cast<int>(frame));
    if (!reg->error().empty() && sequence) std::fprintf(stderr, "scopetrack-studio: %s\n", reg->error().c_str());
    handler = reg.get();
  } else {
    watch = std::make_unique<st::studio::WatchController>(std::move(sequence), endpoint, &server);
    handler = watch.get();
  }
  if (st::Status s = server.start(server_options, handler); !s)
    return std::fprintf(stderr, "scopetrack-studio: %s\n", s.message().c_str()), 1;
  const std::string host = server_options.address.find(':') != std::string::npos
                               ? "[" + server_options.address + "]"
                               : server_options.address;
  if (server_options.address != "127.0.0.1" && server_options.address != "::1")
    std::fprintf(stderr, "scopetrack-studio: warning: listening on %s, reachable from other machines; the studio "
                 "has no authentication\n", server_options.address.c_str());
  std::printf("scopetrack-studio: http://%s:%d/\n", host.c_str(), server.port());
  std::fflush(stdout);
  if (watch) (void)watch->start();
  server.run();
  if (watch) watch->stop();
  return 0;
}
