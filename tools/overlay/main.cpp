// scopetrack-overlay SEQ OUT_DIR VIDEO [--no-wireframe] [--no-text] [--frames N]
// The tracked organ drawn over the sequence's video (see overlay.h). VIDEO
// ending in .y4m is written directly; anything else (.mp4) through ffmpeg.
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "core/formats/text_scan.h"
#include "tools/overlay/overlay.h"

static int usage() {
  std::fprintf(stderr,
               "usage: scopetrack-overlay SEQUENCE_DIR RUN_DIR VIDEO [--no-wireframe] [--no-text] [--frames N]\n"
               "  RUN_DIR holds the tracker's trajectory.txt (and frames.csv); VIDEO is .y4m, or .mp4 via ffmpeg\n"
               "  green: organ silhouette at the tracked pose; yellow dots: markers at the tracked pose;\n"
               "  magenta rings: markers at the ground truth; red border: lost\n");
  return 2;
}

int main(int argc, char** argv) {
  st::overlay::OverlayOptions o;
  std::vector<std::string> positional;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--no-wireframe")) {
      o.style.wireframe = false;
    } else if (!std::strcmp(argv[i], "--no-text")) {
      o.style.text = false;
    } else if (!std::strcmp(argv[i], "--frames") && i + 1 < argc) {
      long long n = 0;
      if (!st::parse_int64_in(argv[++i], 0, 10000000, &n)) {
        std::fprintf(stderr, "scopetrack-overlay: --frames takes a frame count in 0..10000000\n");
        return 2;
      }
      o.max_frames = static_cast<int>(n);
    } else if (!std::strcmp(argv[i], "--help") || !std::strcmp(argv[i], "-h")) {
      usage();
      return 0;
    } else if (argv[i][0] == '-' && argv[i][1] != '\0') {
      std::fprintf(stderr, "scopetrack-overlay: unknown option '%s'\n", argv[i]);
      return usage();
    } else {
      positional.emplace_back(argv[i]);
    }
  }
  if (positional.size() != 3) return usage();
  o.sequence_dir = positional[0];
  o.run_dir = positional[1];
  o.video_out = positional[2];
  auto r = st::overlay::render_overlay(o);
  if (!r) {
    std::fprintf(stderr, "scopetrack-overlay: %s\n", r.message().c_str());
    return 1;
  }
  std::printf("%d frames (%d with a tracked pose, %d with ground truth) -> %s\n", r->frames, r->frames_with_pose,
              r->frames_with_groundtruth, o.video_out.c_str());
  if (!r->error.empty()) {
    std::fprintf(stderr, "scopetrack-overlay: the video broke off: %s (frames before it were written)\n",
                 r->error.c_str());
    return 1;
  }
  return 0;
}
