// Whether a pose measured without features may be reported: the organ's
// outline (core/contour/region_modality.h) and its shading (direct
// alignment against the last reported frame, core/motion/direct_alignment.h)
// are independent measurements of the pose; a pose is reported only when
// both measured one, the outline alone places the organ in view to a few
// pixels, the two put the organ at the same place, and together they fix
// it to a pixel or so (the shading fixes what a short outline leaves open). A pose that one modality
// alone supports stays lost. Pure function of the evidence; tracking
// thread.
#pragma once

#include <cstdint>
#include <limits>

namespace st {

struct OutlineShadingEvidence {
  int outline_lines = 0;  // outline lines measured; 0: the outline gave no pose
  // How far the organ in view may be off under the outline's own pose
  // covariance (its lines whitened by their measured spread): RMS over the
  // organ, level-0 px, 1 sigma. Large where the outline is short or
  // straight (cut by the field stop, the organ filling the view).
  double outline_sigma_px = std::numeric_limits<double>::infinity();
  bool shading_measured = false;  // the direct alignment converged and passed its own checks
  // As outline_sigma_px for the joint pose: the outline's information plus
  // the shading's (as weighted in the joint solve).
  double joint_sigma_px = std::numeric_limits<double>::infinity();
  // How far apart the outline's pose and the shading's pose put the organ
  // (mean over the organ in view, level-0 px).
  double disagreement_px = std::numeric_limits<double>::infinity();
};

struct AgreementLimits {
  int min_lines = 40;
  double max_outline_sigma_px = 3.0;
  double max_disagreement_px = 6.0;
  double max_joint_sigma_px = 1.5;  // 0: not tested
};

enum class Agreement : std::uint8_t {
  kAgree,         // report the joint pose
  kNoOutline,     // too few outline lines, or the outline's solve failed
  kOutlineLoose,  // the outline alone does not fix the organ in view
  kNoShading,     // the direct alignment failed (too little texture, left the view)
  kDisagree,      // both measured, at different places
};
const char* to_string(Agreement a);

Agreement judge_agreement(const OutlineShadingEvidence& e, const AgreementLimits& limits);

}  // namespace st
