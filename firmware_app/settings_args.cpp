#include "firmware_app/settings_args.h"

#include <cstdio>
#include <cstring>
#include <string_view>

#include "core/tracking/tracker_settings.h"
#include "hal/storage/file_io.h"

namespace st::app {

namespace {
constexpr std::int64_t kMaxSettingsBytes = 1 << 20;
}  // namespace

bool take_settings_arg(Args args, int* i, SettingsArgs* settings, bool* bad) {
  const auto at = [&](int k) { return args[static_cast<std::size_t>(k)]; };
  const char* arg = at(*i);
  const bool is_config = !std::strcmp(arg, "--config"), is_set = !std::strcmp(arg, "--set");
  if (!is_config && !is_set) return false;
  if (*i + 1 >= static_cast<int>(args.size())) {
    std::fprintf(stderr, "scopetrack: %s needs %s\n", arg, is_config ? "a settings file" : "KEY=VALUE");
    *bad = true;
    return true;
  }
  const std::string_view value = at(++*i);
  if (is_config) {
    settings->config_file = std::string(value);
    return true;
  }
  std::string_view key, setting;
  if (!split_setting_assignment(value, &key, &setting)) {
    std::fprintf(stderr, "scopetrack: --set takes KEY=VALUE (a key of scopetrack --print-config), not '%.*s'\n",
                 static_cast<int>(value.size()), value.data());
    *bad = true;
    return true;
  }
  settings->sets.emplace_back(std::string(key), std::string(setting));
  return true;
}

Status apply_settings(const SettingsArgs& settings, TrackerConfig* config) {
  if (!settings.config_file.empty()) {
    auto text = read_file(settings.config_file, kMaxSettingsBytes);
    if (!text) return make_error("--config: " + text.message());
    if (Status s = read_tracker_settings(text.value(), config); !s)
      return make_error("--config " + settings.config_file + ": " + s.message());
  }
  for (const auto& [key, value] : settings.sets)
    if (Status s = apply_tracker_setting(key, value, config); !s) return make_error("--set " + s.message());
  return validate_tracker_settings(*config);
}

int run_print_config(Args args) {
  if (!args.empty()) {
    std::fprintf(stderr, "scopetrack: --print-config takes no arguments\n");
    return 2;
  }
  const std::string text = format_tracker_settings(TrackerConfig{});
  std::fwrite(text.data(), 1, text.size(), stdout);
  return 0;
}

}  // namespace st::app
