// scopetrack-studio register: the first frame's registration by pointing.
// The page sends the pairs it has (a pixel of the shown frame, the same
// point picked on the mesh) after every change; the server checks that
// they can fix a pose, runs the registration of scopetrack-register
// (tools/register/registration.h), checks the result (the organ in front of
// the camera, the picked surface facing it) and answers with the pose,
// each pair's residual and the organ drawn at the result. "save" writes
// T_camera_model_init into sequence.yaml (the old file kept as
// sequence.yaml.bak) and the pairs beside it. Host tool code.
#pragma once

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/mesh/closest_point.h"
#include "hal/storage/sequence_loader.h"
#include "tools/overlay/overlay.h"
#include "tools/register/registration.h"
#include "tools/studio/studio_media.h"
#include "tools/studio/web_server.h"

namespace st::studio {

// A sequence folder as scopetrack-studio needs it: loaded and passing the
// checks of `scopetrack --check` (the same function).
Result<LoadedSequence> load_checked_sequence(const std::filesystem::path& dir);

// Why a set of pairs cannot fix a pose, before trying: fewer than
// kMinRegistrationPairs, the mesh points (or the pixels) all on one spot or
// on one line. Empty: they may.
std::string pairs_degeneracy(const std::vector<RegistrationPair>& pairs);

// What is wrong with a registered pose although it fits the picks: the
// organ behind the camera, or the picked surface seen from inside the organ
// (the picks mirrored). Empty: nothing.
std::string implausible_pose(const SE3& T_camera_model, const Mesh& mesh, const ClosestPointIndex& surface,
                             const std::vector<RegistrationPair>& pairs, const std::vector<bool>& inlier);

class RegisterController final : public PageHandler {
 public:
  // sequence: the loaded sequence, or the error to show every page.
  RegisterController(Result<LoadedSequence> sequence, int frame);

  void on_open(const PagePtr& page) override;
  void on_text(const PagePtr& page, std::string_view text) override;

  // The answers to one command, in order (what on_text sends): tests call it.
  std::vector<Outgoing> handle(std::string_view command);
  // What a page gets first: info, mesh, the frame, the last registration.
  std::vector<Outgoing> greeting();
  const std::string& error() const { return error_; }

 private:
  std::vector<Outgoing> show_frame(int index);
  std::vector<Outgoing> run_registration(std::string_view pairs_text, bool save);
  Outgoing overlay_message(const SE3* T_camera_model);
  void check_current_pose();

  std::string error_;  // the sequence cannot be used
  std::optional<LoadedSequence> seq_;
  CameraModel camera_;
  ClosestPointIndex surface_;
  overlay::OverlayRenderer renderer_;
  VideoFrames video_;
  int frame_ = 0;
  std::string frame_jpeg_;
  Outgoing mesh_message_;      // encoded once: the same for every page
  std::string check_message_;  // the tracker's verdict on T_camera_model_init ("" when usable)
  std::string last_pairs_;  // the last pairs text registered, re-run on another frame
  std::vector<Outgoing> last_answer_;
};

}  // namespace st::studio
