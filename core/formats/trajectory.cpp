#include "core/formats/trajectory.h"

#include <array>
#include <charconv>
#include <cmath>

#include "core/base/capacity.h"
#include "core/formats/json_text.h"
#include "core/formats/text_scan.h"

namespace st {

std::string format_number(double v) {
  std::array<char, 64> buf{};
  const auto [end, ec] = std::to_chars(buf.data(), buf.data() + buf.size(), v);
  return ec == std::errc() ? std::string(buf.data(), end) : std::string("nan");
}

namespace {

// Exactly n finite numbers on the line, else a message naming the line.
template <std::size_t N>
Status read_numbers(std::string_view line, int number, const char* what, std::array<double, N>* v) {
  TextScanner sc(line);
  for (std::size_t i = 0; i < N; ++i) {
    const std::string_view tok = sc.next_token();
    if (tok.empty())
      return make_error(std::string(what) + " line " + std::to_string(number) + ": expected " +
                        std::to_string(N) + " numbers, found " + std::to_string(i));
    if (!parse_double(tok, &(*v)[i]) || !std::isfinite((*v)[i]))
      return make_error(std::string(what) + " line " + std::to_string(number) + ": field " +
                        std::to_string(i + 1) + " " + quote_bytes(tok) + " is not a finite number");
  }
  if (!sc.at_end())
    return make_error(std::string(what) + " line " + std::to_string(number) + ": more than " +
                      std::to_string(N) + " fields");
  return Status::Ok();
}

}  // namespace

Result<std::vector<TimedPose>> parse_tum(std::string_view text) {
  std::vector<TimedPose> poses;
  const Status s = for_each_data_line(text, [&](std::string_view line, int number) -> Status {
    if (static_cast<std::int64_t>(poses.size()) >= kMaxTrajectoryLines)
      return make_error("TUM trajectory has more than " + std::to_string(kMaxTrajectoryLines) + " poses");
    std::array<double, 8> v{};
    if (Status r = read_numbers(line, number, "TUM", &v); !r) return r;
    const Quat q(v[7], v[4], v[5], v[6]);  // Eigen order: w, x, y, z
    const double norm = q.norm();
    if (norm < 0.9 || norm > 1.1)
      return make_error("TUM line " + std::to_string(number) + ": quaternion norm " +
                        std::to_string(norm) + " is not close to 1");
    poses.push_back({v[0], SE3(q, Vec3(v[1], v[2], v[3]))});
    return Status::Ok();
  });
  if (!s) return Error{s.message()};
  return poses;
}

std::string format_tum_line(const TimedPose& p) {
  const Quat q = p.T_model_camera.quaternion();
  const Vec3& t = p.T_model_camera.translation();
  std::string s = format_number(p.timestamp_s);
  for (double v : {t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w()}) {
    s += ' ';
    s += format_number(v);
  }
  s += '\n';
  return s;
}

std::string format_tum(const std::vector<TimedPose>& poses) {
  std::string s = "# timestamp tx ty tz qx qy qz qw (T_model_camera, mm)\n";
  for (const TimedPose& p : poses) s += format_tum_line(p);
  return s;
}

Result<std::vector<Marker>> parse_markers(std::string_view text) {
  std::vector<Marker> markers;
  const Status s = for_each_data_line(text, [&](std::string_view line, int number) -> Status {
    if (static_cast<int>(markers.size()) >= kMaxMarkers)
      return make_error("markers: more than " + std::to_string(kMaxMarkers) + " markers");
    std::array<double, 4> v{};
    if (Status r = read_numbers(line, number, "markers", &v); !r) return r;
    if (v[0] != std::floor(v[0]) || v[0] < 0 || v[0] > 1e9)
      return make_error("markers line " + std::to_string(number) + ": id must be a non-negative integer");
    const int id = static_cast<int>(v[0]);
    for (const Marker& m : markers)
      if (m.id == id)
        return make_error("markers line " + std::to_string(number) + ": id " + std::to_string(id) +
                          " appears twice");
    markers.push_back({id, Vec3(v[1], v[2], v[3])});
    return Status::Ok();
  });
  if (!s) return Error{s.message()};
  return markers;
}

std::string format_markers(const std::vector<Marker>& markers) {
  std::string s = "# id x y z (model frame, mm)\n";
  for (const Marker& m : markers)
    s += std::to_string(m.id) + ' ' + format_number(m.p_model.x()) + ' ' +
         format_number(m.p_model.y()) + ' ' + format_number(m.p_model.z()) + '\n';
  return s;
}

const char* to_string(FrameState s) {
  switch (s) {
    case FrameState::kTracking: return "tracking";
    case FrameState::kLost: return "lost";
    case FrameState::kRelocalised: return "relocalised";
    case FrameState::kInitialised: return "initialised";
  }
  return "lost";
}

std::string frames_csv_header() { return "frame,timestamp,state,inliers,latency_ms,map_points,keyframes\n"; }

bool is_frames_csv_header(std::string_view line) {
  constexpr std::string_view kBase = "frame,timestamp,state,inliers,latency_ms";
  return line.substr(0, kBase.size()) == kBase && (line.size() == kBase.size() || line[kBase.size()] == ',');
}

std::string format_frames_csv_row(const FrameRecord& r) {
  return std::to_string(r.frame) + ',' + format_number(r.timestamp_s) + ',' + to_string(r.state) +
         ',' + std::to_string(r.inliers) + ',' + format_number(r.latency_ms) + ',' +
         std::to_string(r.map_points) + ',' + std::to_string(r.keyframes) + '\n';
}

namespace {
std::string json_string(std::string_view s) { return '"' + json_escaped(s) + '"'; }
std::string json_number(double v) { return std::isfinite(v) ? format_number(v) : "null"; }
}  // namespace

std::string format_summary_json(const RunSummary& s) {
  std::vector<std::pair<std::string, std::string>> fields = {
      {"frames", std::to_string(s.frames)},
      {"tracked_frames", std::to_string(s.tracked_frames)},
      {"lost_frames", std::to_string(s.lost_frames)},
      {"mean_latency_ms", json_number(s.mean_latency_ms)},
      {"p99_latency_ms", json_number(s.p99_latency_ms)},
      {"fps", json_number(s.fps)},
      {"peak_rss_mb", json_number(s.peak_rss_mb)}};
  for (const auto& [key, value] : s.extra) fields.emplace_back(key, json_number(value));
  std::string out = "{\n";
  for (std::size_t i = 0; i < fields.size(); ++i)
    out += "  " + json_string(fields[i].first) + ": " + fields[i].second +
           (i + 1 < fields.size() ? ",\n" : "\n");
  return out + "}\n";
}

}  // namespace st
