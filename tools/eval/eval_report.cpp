#include "eval_report.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>

#include "core/formats/trajectory.h"
#include "hal/storage/file_io.h"
#include "hal/storage/sequence_loader.h"

namespace st {
namespace {

constexpr std::int64_t kMaxTextBytes = 1ll << 30;

Result<std::string> read_text(const std::filesystem::path& p) { return read_file(p, kMaxTextBytes); }

// Counts data rows of frames.csv after checking its header.
Result<int> count_csv_rows(const std::string& text) {
  std::istringstream in(text);
  std::string line;
  if (!std::getline(in, line) || !is_frames_csv_header(line))
    return make_error("frames.csv: the first line is not the header '" +
                      frames_csv_header().substr(0, frames_csv_header().size() - 1) + "'");
  int rows = 0;
  while (std::getline(in, line))
    if (!line.empty()) ++rows;
  return rows;
}

Result<std::vector<std::optional<SE3>>> index_by_frame(const std::vector<TimedPose>& poses,
                                                       double fps, int frames,
                                                       const std::string& what) {
  std::vector<std::optional<SE3>> out(static_cast<std::size_t>(frames));
  for (const TimedPose& p : poses) {
    const int i = frame_for_timestamp(p.timestamp_s, fps, frames);
    if (i < 0)
      return make_error(what + ": timestamp " + format_number(p.timestamp_s) +
                        " s matches no frame of the sequence (fps " + format_number(fps) + ", " +
                        std::to_string(frames) + " frames)");
    if (out[i])
      return make_error(what + ": two poses for frame " + std::to_string(i));
    out[i] = p.T_model_camera;
  }
  return out;
}

}  // namespace

Result<double> json_number(const std::string& text, const std::string& key) {
  const std::string quoted = "\"" + key + "\"";
  const auto k = text.find(quoted);
  if (k == std::string::npos) return make_error("no \"" + key + "\" field");
  auto c = text.find_first_not_of(" \t\r\n", k + quoted.size());
  if (c == std::string::npos || text[c] != ':') return make_error("\"" + key + "\" has no value");
  c = text.find_first_not_of(" \t\r\n", c + 1);
  if (c == std::string::npos) return make_error("\"" + key + "\" has no value");
  if (text.compare(c, 4, "null") == 0) return std::nan("");
  const char* begin = text.c_str() + c;
  char* end = nullptr;
  const double v = std::strtod(begin, &end);
  if (end == begin) return make_error("\"" + key + "\" is not a number");
  return v;
}

Result<EvalReport> evaluate_run(const std::filesystem::path& sequence_dir,
                                const std::filesystem::path& output_dir) {
  auto seq = load_sequence(sequence_dir);
  if (!seq) return make_error("sequence " + sequence_dir.string() + ": " + seq.message());
  if (seq->groundtruth.empty())
    return make_error("sequence " + sequence_dir.string() +
                      " has no ground truth: nothing to evaluate against");
  EvalReport report;
  const double fps = seq->config.fps;
  const int frames = static_cast<int>(seq->groundtruth.size());

  auto traj_text = read_text(output_dir / "trajectory.txt");
  if (!traj_text) return make_error(traj_text.message());
  auto traj = parse_tum(traj_text.value());
  if (!traj) return make_error("trajectory.txt: " + traj.message());

  EvalInput in;
  in.frames = frames;
  in.camera = CameraModel(seq->config.K, seq->config.distortion);
  for (const Marker& m : seq->markers) in.markers_model.push_back(m.p_model);
  auto gt = index_by_frame(seq->groundtruth, fps, frames, "groundtruth");
  if (!gt) return make_error(gt.message());
  auto est = index_by_frame(traj.value(), fps, frames, "trajectory.txt");
  if (!est) return make_error(est.message());
  in.groundtruth = std::move(gt.value());
  in.estimated = std::move(est.value());
  report.result = evaluate(in);

  if (std::filesystem::exists(output_dir / "frames.csv")) {
    auto csv = read_text(output_dir / "frames.csv");
    if (!csv) return make_error(csv.message());
    auto rows = count_csv_rows(csv.value());
    if (!rows) return make_error(rows.message());
    report.frames_in_csv = rows.value();
  }
  if (std::filesystem::exists(output_dir / "summary.json")) {
    auto js = read_text(output_dir / "summary.json");
    if (!js) return make_error(js.message());
    auto f = json_number(js.value(), "fps");
    auto p = json_number(js.value(), "p99_latency_ms");
    if (!f || !p) return make_error("summary.json: " + (f ? p.message() : f.message()));
    report.fps = f.value();
    report.p99_latency_ms = p.value();
  }
  return report;
}

std::string format_eval_json(const EvalReport& rep) {
  const EvalResult& r = rep.result;
  std::string o = "{";
  auto num = [&](const char* k, double v) { o += std::string("\"") + k + "\": " +
                                                  (std::isfinite(v) ? format_number(v) : "null") + ", "; };
  num("frames", r.frames);
  o += std::string("\"init_ok\": ") + (r.init_ok ? "true" : "false") + ", ";
  num("lost_pct", r.lost_pct);
  num("tre_median_px", r.tre_median_px);
  num("tre_mean_px", r.tre_mean_px);
  num("tre_p95_px", r.tre_p95_px);
  num("tre_samples", r.tre_samples);
  num("wrong_pct", r.wrong_pct);
  num("rot_err_median_deg", r.rot_err_median_deg);
  num("rot_err_max_deg", r.rot_err_max_deg);
  num("trans_err_median_mm", r.trans_err_median_mm);
  num("fps", rep.fps);
  num("p99_latency_ms", rep.p99_latency_ms);
  o.resize(o.size() - 2);
  o += "}\n";
  return o;
}

std::string format_eval_table(const EvalReport& rep) {
  const EvalResult& r = rep.result;
  // Speed as people read it: fps to 0.1, latency to 0.01 ms.
  char fps[64] = "n/a (no summary.json)", p99[64] = "n/a";
  if (rep.fps >= 0) std::snprintf(fps, sizeof fps, "%.1f", rep.fps);
  if (rep.p99_latency_ms >= 0) std::snprintf(p99, sizeof p99, "%.2f ms", rep.p99_latency_ms);
  char buf[1024];
  std::snprintf(buf, sizeof buf,
                "frames            %d (reported %d)\n"
                "init_ok           %s\n"
                "lost              %.2f %%\n"
                "wrong             %.2f %% (%d frames with median marker TRE > %.0f px)\n"
                "TRE px            median %.3f  mean %.3f  p95 %.3f  (%d marker samples)\n"
                "pose error        median %.3f deg, %.3f mm; largest %.3f deg\n"
                "fps               %s\n"
                "p99 latency       %s\n",
                r.frames, r.reported_frames, r.init_ok ? "yes" : "NO", r.lost_pct, r.wrong_pct,
                r.wrong_frames, kWrongTrePx, r.tre_median_px, r.tre_mean_px, r.tre_p95_px,
                r.tre_samples, r.rot_err_median_deg, r.trans_err_median_mm, r.rot_err_max_deg,
                fps, p99);
  return buf;
}

}  // namespace st
