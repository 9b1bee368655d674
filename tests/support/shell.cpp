#include "support/shell.h"

#include <sys/wait.h>

#include <cstdlib>

#include "support/support.h"

namespace st::test {

int run_shell(const std::string& cmd) {
  const int status = std::system(cmd.c_str());
  return status != -1 && WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::string shell_quoted(const std::filesystem::path& p) {
  std::string out(1, '\'');  // appends: GCC 12 warns falsely on "'" + s
  out.append(p.string());
  out.push_back('\'');
  return out;
}

std::string bin_command(const std::string& name) { return shell_quoted(bin_dir() / name); }

}  // namespace st::test
