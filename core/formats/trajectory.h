// Text formats of the data contract: TUM trajectories, markers.txt, and the
// tracker's frames.csv / summary.json. Parsers take text; formatters return
// strings (hal/ writes the files). Numbers are written in shortest
// round-trip form, locale-independent.
#pragma once

#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "core/base/result.h"
#include "core/geometry/se3.h"

namespace st {

// One TUM line: the camera's pose in the model frame at a time.
struct TimedPose {
  double timestamp_s = 0.0;
  SE3 T_model_camera;
};

// "timestamp tx ty tz qx qy qz qw" per line, '#' comments and blank lines
// skipped. Rejects (with the line number) wrong field counts, non-numbers,
// NaN/inf, quaternions far from unit length (|q| outside [0.9, 1.1]; others
// are normalised), and more than kMaxTrajectoryLines poses.
Result<std::vector<TimedPose>> parse_tum(std::string_view text);
// One line with '\n'. Allocates the returned string.
std::string format_tum_line(const TimedPose& pose);
std::string format_tum(const std::vector<TimedPose>& poses);

struct Marker {
  int id = 0;
  Vec3 p_model = Vec3::Zero();  // mm
};
// "id x y z" per line, '#' comments; ids unique, coordinates finite, at
// most kMaxMarkers.
Result<std::vector<Marker>> parse_markers(std::string_view text);
std::string format_markers(const std::vector<Marker>& markers);

// Per-frame state written to frames.csv.
enum class FrameState { kTracking, kLost, kRelocalised, kInitialised };
const char* to_string(FrameState s);

struct FrameRecord {
  int frame = 0;
  double timestamp_s = 0.0;
  FrameState state = FrameState::kLost;
  int inliers = 0;
  double latency_ms = 0.0;
  int map_points = 0;  // the map's pools after the frame: points and keyframes alive
  int keyframes = 0;
};
// "frame,timestamp,state,inliers,latency_ms,map_points,keyframes\n"
std::string frames_csv_header();
// True for a frames.csv header line (without its '\n'): the first five
// columns as above, then any columns a later build appends (readers take
// what they know, so files of earlier and later builds both read).
bool is_frames_csv_header(std::string_view line);
// One row with '\n', e.g. "12,0.48,tracking,311,6.25,2403,14\n".
std::string format_frames_csv_row(const FrameRecord& r);

struct RunSummary {
  int frames = 0, tracked_frames = 0, lost_frames = 0;
  double mean_latency_ms = 0.0, p99_latency_ms = 0.0;
  double fps = 0.0;          // frames processed per second of wall time
  double peak_rss_mb = 0.0;
  std::vector<std::pair<std::string, double>> extra;  // more numeric fields, in order
};
// A JSON object, one field per line; non-finite numbers become null.
std::string format_summary_json(const RunSummary& s);

// Shortest decimal text that reads back to exactly v ("nan"/"inf" as such).
std::string format_number(double v);

}  // namespace st
