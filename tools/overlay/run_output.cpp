#include "tools/overlay/run_output.h"

#include <charconv>
#include <cmath>
#include <cstring>

#include "hal/storage/file_io.h"

namespace st::overlay {

namespace {
constexpr std::int64_t kMaxRunFileBytes = std::int64_t{1} << 30;
constexpr int kMaxFrameIndex = 10'000'000;

template <class T>
void put(std::vector<std::optional<T>>* v, int index, const T& value) {
  if (static_cast<int>(v->size()) <= index) v->resize(static_cast<std::size_t>(index) + 1);
  (*v)[static_cast<std::size_t>(index)] = value;
}

std::optional<FrameState> state_from_name(std::string_view s) {
  for (FrameState f : {FrameState::kTracking, FrameState::kLost, FrameState::kRelocalised, FrameState::kInitialised})
    if (s == to_string(f)) return f;
  return std::nullopt;
}
}  // namespace

const SE3* RunFrames::pose(int frame) const {
  if (frame < 0 || frame >= static_cast<int>(T_model_camera.size())) return nullptr;
  const auto& p = T_model_camera[static_cast<std::size_t>(frame)];
  return p ? &*p : nullptr;
}

std::optional<FrameState> RunFrames::state_of(int frame) const {
  if (frame < 0 || frame >= static_cast<int>(state.size())) return std::nullopt;
  return state[static_cast<std::size_t>(frame)];
}

Result<std::vector<std::optional<SE3>>> poses_by_frame(const std::vector<TimedPose>& poses, double fps) {
  std::vector<std::optional<SE3>> out;
  if (!(fps > 0)) return make_error("fps must be positive to match poses to frames");
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const double f = poses[i].timestamp_s * fps;
    const double index = std::round(f);
    if (!(std::abs(f - index) <= 0.25) || index < 0 || index >= kMaxFrameIndex)
      return make_error("pose " + std::to_string(i + 1) + " at t = " + format_number(poses[i].timestamp_s) +
                        " s is not at a frame time of a " + format_number(fps) + " fps video");
    put(&out, static_cast<int>(index), poses[i].T_model_camera);
  }
  return out;
}

Result<std::vector<std::optional<FrameState>>> parse_frame_states(std::string_view csv) {
  std::vector<std::optional<FrameState>> out;
  const std::size_t header_end = std::min(csv.find('\n'), csv.size());
  if (!is_frames_csv_header(csv.substr(0, header_end))) {
    const std::string header = frames_csv_header();
    return make_error("frames.csv: the first line is not '" + header.substr(0, header.size() - 1) + "'");
  }
  std::size_t pos = header_end + 1;
  for (int line = 2; pos < csv.size(); ++line) {
    std::size_t end = csv.find('\n', pos);
    if (end == std::string_view::npos) end = csv.size();
    const std::string_view row = csv.substr(pos, end - pos);
    pos = end + 1;
    if (row.empty()) continue;
    const std::size_t c1 = row.find(','), c2 = row.find(',', c1 == row.npos ? row.size() : c1 + 1);
    const std::size_t c3 = row.find(',', c2 == row.npos ? row.size() : c2 + 1);
    int frame = -1;
    const bool frame_ok = c1 != row.npos && std::from_chars(row.data(), row.data() + c1, frame).ec == std::errc{};
    const auto state = c3 != row.npos ? state_from_name(row.substr(c2 + 1, c3 - c2 - 1)) : std::nullopt;
    if (!frame_ok || frame < 0 || frame >= kMaxFrameIndex || !state)
      return make_error("frames.csv line " + std::to_string(line) + ": expected 'frame,timestamp,state,...'");
    put(&out, frame, *state);
  }
  return out;
}

Result<RunFrames> read_run_output(const std::filesystem::path& out_dir, double fps) {
  RunFrames run;
  auto traj_text = read_file(out_dir / "trajectory.txt", kMaxRunFileBytes);
  if (!traj_text) return traj_text.error();
  auto traj = parse_tum(traj_text.value());
  if (!traj) return make_error((out_dir / "trajectory.txt").string() + ": " + traj.message());
  auto poses = poses_by_frame(traj.value(), fps);
  if (!poses) return make_error((out_dir / "trajectory.txt").string() + ": " + poses.message());
  run.T_model_camera = std::move(poses.value());
  std::error_code ec;
  if (std::filesystem::exists(out_dir / "frames.csv", ec)) {
    auto csv = read_file(out_dir / "frames.csv", kMaxRunFileBytes);
    if (!csv) return csv.error();
    auto states = parse_frame_states(csv.value());
    if (!states) return make_error((out_dir / "frames.csv").string() + ": " + states.message());
    run.state = std::move(states.value());
  }
  return run;
}

}  // namespace st::overlay
