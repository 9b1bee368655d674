// scopetrack-eval's work, separate from its command line so tests can call it.
#pragma once

#include <filesystem>
#include <string>

#include "core/evaluation/evaluation.h"
#include "core/base/result.h"

namespace st {

struct EvalReport {
  EvalResult result;
  double fps = -1.0;             // from summary.json, -1 when absent
  double p99_latency_ms = -1.0;  // from summary.json, -1 when absent
  int frames_in_csv = -1;        // rows of frames.csv, -1 when absent
};

// Reads the sequence (sequence.yaml, groundtruth, markers) and the tracker's
// output folder (trajectory.txt, optional frames.csv and summary.json).
Result<EvalReport> evaluate_run(const std::filesystem::path& sequence_dir,
                                const std::filesystem::path& output_dir);

std::string format_eval_json(const EvalReport& r);
std::string format_eval_table(const EvalReport& r);

// Numeric value of a top-level "key": number in a JSON object, or nullopt.
Result<double> json_number(const std::string& text, const std::string& key);

}  // namespace st
