// scopetrack's live-camera modes (firmware_app/camera_command.cpp), rows of
// main.cpp's command table.
#pragma once

#include <csignal>

#include <functional>
#include <string>

#include "core/formats/sequence.h"
#include "core/mesh/mesh.h"
#include "core/tracking/tracker.h"
#include "firmware_app/cli.h"
#include "hal/capture/frame_source.h"
#include "hal/capture/libcamera_capture.h"

namespace st::app {

// scopetrack --list-cameras: the cameras libcamera sees, one id a line.
// Exit 0 with at least one camera, 1 with none (the message says what was found).
int run_list_cameras(Args args);

// scopetrack --camera ID --mesh FILE --calibration FILE [--out DIR] [--ring N]
// [--config FILE] [--set KEY=VALUE]...: tracks the live camera until SIGINT/SIGTERM. Exit 0 after a
// clean stop, 1 when the camera, mesh or calibration cannot be used, 2 on a
// bad command line or settings.
int run_camera(Args args);

// A live run once its inputs are open: what run_camera hands run_live.
struct LiveRun {
  TrackerConfig config;           // width and height are taken from the calibration
  SequenceConfig calibration;
  const Mesh* mesh = nullptr;
  std::string calibration_path;   // named in the calibration check's message
  std::string out_dir;            // empty: no files written
  std::string source_label;       // the status line's "tracking ..." (e.g. "camera 'ID' (NV12 1280x720)")
  FrameSource* source = nullptr;  // opened, not started; run_live starts and stops it
  std::function<CaptureCounters()> counters;  // optional: the camera's own counts for the summary
  bool print_status = true;       // a status line on stderr each second
};

// Tracks run.source on a tracking thread until a signal of stop_signals
// (SIGINT, SIGTERM), which the caller blocked in every thread before any
// thread existed, or until the source ends by itself; then stops the
// source, joins the thread and writes summary.json (stop_signal: the
// signal, 0 when the source ended). Exit 0 after a clean stop, 1 when the
// tracker cannot be configured, the output cannot be written or the source
// failed.
int run_live(const LiveRun& run, const sigset_t& stop_signals);

}  // namespace st::app
