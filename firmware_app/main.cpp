// scopetrack: the tracker application. main() is the only place that exits.
#include <cstdio>
#include <cstring>

static void print_usage() {
  std::printf(
      "usage: scopetrack --version\n"
      "ScopeTrack " "0.1.0" ": laparoscope pose tracking against a prior organ mesh\n");
}

int main(int argc, char** argv) {
  if (argc >= 2 && std::strcmp(argv[1], "--version") == 0) {
    std::printf("scopetrack 0.1.0\n");
    return 0;
  }
  print_usage();
  return argc >= 2 && std::strcmp(argv[1], "--help") == 0 ? 0 : 2;
}
