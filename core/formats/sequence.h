// sequence.yaml (docs sequence-format.md) as text: parsed and written with
// cv::FileStorage in memory, so OpenCV reads what we write and OpenCV's
// calibration output can be pasted in. No file access here: hal/
// sequence_loader.h resolves the referenced files.
#pragma once

#include <string>
#include <string_view>

#include "core/geometry/camera.h"
#include "core/base/result.h"
#include "core/geometry/se3.h"

namespace st {

struct SequenceConfig {
  int width = 0, height = 0;       // image size, pixels (= the Y4M header)
  Pinhole K;                       // K.width/height mirror width/height
  Distortion distortion;           // OpenCV radial-tangential, 4/5/8 coefficients
  double fps = 0.0;                // frame i has timestamp i / fps seconds
  SE3 T_camera_model_init;         // model (mm) -> camera of frame 0
  std::string video, mesh;         // file names relative to the sequence folder
  std::string groundtruth, markers;  // optional: empty when absent
  bool T_init_reorthonormalised = false;  // the stored rotation was off by < 1e-3 and was fixed
};

// Largest |R^T R - I| (Frobenius) that is treated as rounding and fixed.
inline constexpr double kMaxRotationError = 1e-3;

// Parses and validates: image size within caps, fx, fy > 0, principal point
// inside the image, distortion 4/5/8 finite values, fps > 0, a rigid
// T_camera_model_init (last row 0 0 0 1; a rotation within
// kMaxRotationError is re-orthonormalised, anything worse is rejected),
// non-empty video and mesh names. Bad YAML becomes an Error.
Result<SequenceConfig> parse_sequence_yaml(std::string_view text);

// A live camera's calibration/registration file: the camera keys of
// sequence.yaml (image_width, image_height, camera_matrix,
// distortion_coefficients, T_camera_model_init), validated the same way;
// fps is optional (0 when absent), file names are not required. A
// sequence.yaml is a valid calibration file.
Result<SequenceConfig> parse_calibration_yaml(std::string_view text);

// OpenCV FileStorage YAML with the keys of the spec (optional names only
// when non-empty).
std::string format_sequence_yaml(const SequenceConfig& config);

}  // namespace st
