#include "firmware_app/replay.h"

#include <memory>

#include "hal/capture/y4m_capture.h"
#include "hal/storage/file_io.h"
#include "hal/storage/run_writer.h"

namespace st {

int estimate_frame_count(const LoadedSequence& sequence) {
  if (sequence.video_is_pipe) return 0;
  std::error_code ec;
  const auto bytes = std::filesystem::file_size(sequence.video_path, ec);
  const std::size_t record = sequence.video_header.frame_bytes() + 6;  // "FRAME\n" + planes
  if (ec || record <= 6 || bytes < sequence.video_header.header_bytes) return 0;
  return static_cast<int>((bytes - sequence.video_header.header_bytes) / record);
}

Result<RunStats> run_replay(const LoadedSequence& sequence, FrameProcessor& processor,
                            const ReplayOptions& options) {
  auto capture = std::make_unique<Y4mCapture>();
  const double fps = sequence.config.fps;
  if (Status s = capture->open(sequence.video_path, options.ring_slots, fps, options.realtime ? fps : 0.0); !s)
    return Error{s.message()};
  const Y4mHeader& h = capture->header();
  if (h.width != sequence.config.width || h.height != sequence.config.height)
    return make_error("video " + sequence.video_path.string() + " is " + std::to_string(h.width) + "x" +
                      std::to_string(h.height) + " but sequence.yaml calibrates " +
                      std::to_string(sequence.config.width) + "x" + std::to_string(sequence.config.height));
  if (options.working_width > 0 && options.working_height > 0) {
    if (Status s = capture->set_working_size(options.working_width, options.working_height); !s)
      return Error{"capture at the working size: " + s.message()};
  }
  auto writer = std::make_unique<RunWriter>();
  if (Status s = writer->open(options.out_dir); !s) return Error{s.message()};

  auto loop = std::make_unique<FrameLoop>();
  loop->source = capture.get();
  loop->processor = &processor;
  loop->writer = writer.get();
  loop->observer = options.observer;
  loop->stop_signal = options.stop_signal;
  writer->start({options.progress, estimate_frame_count(sequence), 0.25});
  // Spawning the capture thread allocates: before the loop counts.
  if (Status s = capture->start(); !s) return Error{s.message()};
  loop->run();  // the calling thread is the tracking thread
  capture->stop();

  std::vector<std::pair<std::string, double>> extra = options.summary_extra;
  processor.append_summary(&extra);
  if (options.observer) options.observer->finish(&extra);
  RunStats& stats = loop->stats;
  if (loop->source_error) stats.error = capture->error();
  if (Status s = writer->finish(); !s && stats.error.empty()) stats.error = s.message();
  loop->fill_timing();
  if (Status s = write_file(options.out_dir / "summary.json", format_run_summary(stats, options.realtime, extra)); !s)
    return Error{s.message()};
  return stats;
}

}  // namespace st
