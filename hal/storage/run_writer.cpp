#include "hal/storage/run_writer.h"

#include <cerrno>
#include <cstring>

#include "platform/clock.h"

namespace st {

RunWriter::~RunWriter() {
  if (thread_.joinable()) (void)finish();
  close_files();
}

Status RunWriter::open(const std::filesystem::path& out_dir) {
  out_dir_ = out_dir;
  std::error_code ec;
  std::filesystem::create_directories(out_dir, ec);
  if (ec) return make_error("cannot create output folder " + out_dir.string() + ": " + ec.message());
  const std::filesystem::path traj = out_dir / "trajectory.txt", csv = out_dir / "frames.csv";
  trajectory_ = std::fopen(traj.c_str(), "w");
  if (!trajectory_) return make_error("cannot write " + traj.string() + ": " + std::strerror(errno));
  frames_ = std::fopen(csv.c_str(), "w");
  if (!frames_) {
    close_files();
    return make_error("cannot write " + csv.string() + ": " + std::strerror(errno));
  }
  std::fputs("# timestamp tx ty tz qx qy qz qw (T_model_camera, mm)\n", trajectory_);
  std::fputs(frames_csv_header().c_str(), frames_);
  flush();
  if (!write_error_.empty()) return make_error(write_error_);
  return Status::Ok();
}

void RunWriter::start(const ProgressOptions& progress) {
  t_start_ns_ = t_last_print_ns_ = platform::monotonic_ns();
  thread_ = std::thread([this, progress] { run(progress); });
}

Status RunWriter::finish() {
  if (thread_.joinable()) {
    FrameRow end;
    end.end = true;
    queue_.push_wait(end);
    thread_.join();
  }
  close_files();
  if (!write_error_.empty()) return make_error(write_error_);
  return Status::Ok();
}

void RunWriter::run(ProgressOptions progress) {
  for (;;) {
    FrameRow row;
    queue_.pop_wait(&row);
    if (row.end) break;
    write_row(row);
    // Caught up: put everything on disk before waiting for the next row.
    if (queue_.size() == 0) flush();
    if (progress.enabled) print_progress(progress, false);
  }
  flush();
  if (progress.enabled) print_progress(progress, true);
}

void RunWriter::write_row(const FrameRow& row) {
  if (row.pose_valid)
    std::fputs(format_tum_line({row.record.timestamp_s, row.T_model_camera}).c_str(), trajectory_);
  std::fputs(format_frames_csv_row(row.record).c_str(), frames_);
  const int s = static_cast<int>(row.record.state);
  if (s >= 0 && s < 4) ++counts_[s];
  rows_written_.fetch_add(1, std::memory_order_relaxed);
}

void RunWriter::flush() {
  for (std::FILE* f : {trajectory_, frames_}) {
    if (!f) continue;
    if ((std::fflush(f) != 0 || std::ferror(f)) && write_error_.empty()) {
      // Said once, when it happens (a disk that fills): tracking and
      // streaming go on, the rows that follow are lost, finish() returns it.
      write_error_ = "writing the tracker output in " + out_dir_.string() + " failed: " + std::strerror(errno);
      std::fprintf(stderr, "\nscopetrack: %s; tracking goes on without it\n", write_error_.c_str());
    }
  }
}

void RunWriter::print_progress(const ProgressOptions& p, bool final_line) {
  const std::int64_t now = platform::monotonic_ns();
  if (!final_line && now - t_last_print_ns_ < static_cast<std::int64_t>(p.interval_s * 1e9)) return;
  t_last_print_ns_ = now;
  const std::int64_t n = rows_written();
  const double secs = static_cast<double>(now - t_start_ns_) * 1e-9;
  const double fps = secs > 0 ? static_cast<double>(n) / secs : 0.0;
  char total[32] = "?";
  if (p.expected_frames > 0) std::snprintf(total, sizeof total, "%d", p.expected_frames);
  using FS = FrameState;
  std::fprintf(stderr, "\rframe %lld/%s  %.1f fps  tracking %d  initialised %d  relocalised %d  lost %d   %s",
               static_cast<long long>(n), total, fps, counts_[static_cast<int>(FS::kTracking)],
               counts_[static_cast<int>(FS::kInitialised)], counts_[static_cast<int>(FS::kRelocalised)],
               counts_[static_cast<int>(FS::kLost)], final_line ? "\n" : "");
  std::fflush(stderr);
}

void RunWriter::close_files() {
  for (std::FILE** f : {&trajectory_, &frames_}) {
    if (*f && std::fclose(*f) != 0 && write_error_.empty())
      write_error_ = "closing the tracker output in " + out_dir_.string() + " failed";
    *f = nullptr;
  }
}

}  // namespace st
