// scopetrack's live-camera modes (firmware_app/camera_command.cpp), rows of
// main.cpp's command table.
#pragma once

#include "firmware_app/cli.h"

namespace st::app {

// scopetrack --list-cameras: the cameras libcamera sees, one id a line.
// Exit 0 with at least one camera, 1 with none (the message says what was found).
int run_list_cameras(Args args);

// scopetrack --camera ID --mesh FILE --calibration FILE [--out DIR] [--ring N]
// [--config FILE] [--set KEY=VALUE]...: tracks the live camera until SIGINT/SIGTERM. Exit 0 after a
// clean stop, 1 when the camera, mesh or calibration cannot be used, 2 on a
// bad command line or settings.
int run_camera(Args args);

}  // namespace st::app
