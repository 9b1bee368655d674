// Running the project's executables from end-to-end tests through the shell.
#pragma once

#include <filesystem>
#include <string>

namespace st::test {

// Runs a command line through /bin/sh; its exit status (-1 if it did not exit).
int run_shell(const std::string& cmd);
// A path in single quotes for the shell.
std::string shell_quoted(const std::filesystem::path& p);
// build/bin/NAME, quoted.
std::string bin_command(const std::string& name);

}  // namespace st::test
