// scopetrack-eval SEQ OUT [--json]: the figures of a tracker run against the
// sequence's ground truth (see core/evaluation/evaluation.h for the definitions).
#include <cstdio>
#include <cstring>

#include "eval_report.h"

int main(int argc, char** argv) {
  const char* seq = nullptr;
  const char* out = nullptr;
  bool json = false;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--json")) {
      json = true;
    } else if (!std::strcmp(argv[i], "--help") || !std::strcmp(argv[i], "-h")) {
      std::printf("usage: scopetrack-eval SEQUENCE_DIR OUTPUT_DIR [--json]\n");
      return 0;
    } else if (!seq) {
      seq = argv[i];
    } else if (!out) {
      out = argv[i];
    } else {
      std::fprintf(stderr, "scopetrack-eval: unexpected argument '%s'\n", argv[i]);
      return 2;
    }
  }
  if (!seq || !out) {
    std::fprintf(stderr, "usage: scopetrack-eval SEQUENCE_DIR OUTPUT_DIR [--json]\n");
    return 2;
  }
  auto report = st::evaluate_run(seq, out);
  if (!report) {
    std::fprintf(stderr, "scopetrack-eval: %s\n", report.message().c_str());
    return 1;
  }
  const std::string text = json ? st::format_eval_json(report.value())
                                : st::format_eval_table(report.value());
  std::fputs(text.c_str(), stdout);
  return 0;
}
