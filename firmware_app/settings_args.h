// The tracker's settings on scopetrack's command line, the same for the
// replay and the live camera: --config FILE (a settings file,
// core/tracking/tracker_settings.h) and --set KEY=VALUE (one key of it,
// after the file, in order). Everything tunable is a key; the command line
// keeps what a user changes per run.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "core/base/result.h"
#include "core/tracking/tracker.h"
#include "firmware_app/cli.h"

namespace st::app {

struct SettingsArgs {
  std::string config_file;                               // --config FILE
  std::vector<std::pair<std::string, std::string>> sets;  // --set KEY=VALUE, in order
};

// If args[*i] is --config or --set with its value, takes it (advancing *i)
// and returns true; *bad is set (with a message on stderr) when the option
// is malformed. Otherwise leaves everything alone and returns false.
bool take_settings_arg(Args args, int* i, SettingsArgs* settings, bool* bad);

// The tracker's settings: config as given (its defaults), then the file,
// then each --set, then the checks across keys (validate_tracker_settings).
// An error names the file, the line and the key.
Status apply_settings(const SettingsArgs& settings, TrackerConfig* config);

// scopetrack --print-config: the settings file of the defaults, every key
// with a comment (firmware_app/main.cpp's table).
int run_print_config(Args args);

}  // namespace st::app
