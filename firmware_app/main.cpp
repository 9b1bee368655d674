// scopetrack: the tracker application. main() is the only place that exits.
// Modes are rows of kCommands; add a row (and a file) for a new mode.
#include <array>
#include <csignal>
#include <cstdio>
#include <string_view>

#include "firmware_app/camera_command.h"
#include "firmware_app/cli.h"
#include "firmware_app/settings_args.h"

namespace {

constexpr std::string_view kVersion = "0.1.0";

int run_version(st::app::Args) {
  std::printf("scopetrack %.*s\n", static_cast<int>(kVersion.size()), kVersion.data());
  return 0;
}
int run_help(st::app::Args);

constexpr std::array kCommands = {
    st::app::Command{"--check", "DIR", "validate a sequence folder and say whether it is usable",
                     st::app::run_check},
    st::app::Command{"--sequence",
                     "DIR --out DIR [--config FILE] [--set KEY=VALUE]... [--ba-lag N] [--realtime] [--ring N] "
                     "[--stream EP [--stream-wait N] [--texture-every K]]",
                     "replay a sequence through the tracker: trajectory.txt, frames.csv, summary.json in --out",
                     st::app::run_replay},
    st::app::Command{"--camera", "ID --mesh FILE --calibration FILE [--out DIR] [--ring N] [--config FILE] [--set KEY=VALUE]...",
                     "track a live libcamera camera until Ctrl-C (not yet run on hardware)", st::app::run_camera},
    st::app::Command{"--print-config", "", "print the tracker's settings file: every key, its default, range and meaning",
                     st::app::run_print_config},
    st::app::Command{"--list-cameras", "", "list the cameras libcamera finds", st::app::run_list_cameras},
    st::app::Command{"--version", "", "print the version", run_version},
    st::app::Command{"--help", "", "this text", run_help},
};

int run_help(st::app::Args) {
  std::printf("ScopeTrack %.*s: laparoscope pose tracking against a prior organ mesh\nusage:\n",
              static_cast<int>(kVersion.size()), kVersion.data());
  for (const auto& c : kCommands)
    std::printf("  scopetrack %-10.*s %-6.*s %.*s\n", static_cast<int>(c.flag.size()), c.flag.data(),
                static_cast<int>(c.usage.size()), c.usage.data(), static_cast<int>(c.help.size()),
                c.help.data());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  // A file-size limit reached (SIGXFSZ) or a closed pipe (SIGPIPE) is a
  // write error the writers report, not a reason to end tracking.
  std::signal(SIGXFSZ, SIG_IGN);
  std::signal(SIGPIPE, SIG_IGN);
  if (argc >= 2) {
    for (const auto& c : kCommands)
      if (c.flag == argv[1]) return c.run(st::app::Args(argv + 2, static_cast<std::size_t>(argc - 2)));
    std::fprintf(stderr, "scopetrack: unknown option '%s'\n", argv[1]);
  }
  run_help({});
  return 2;
}
