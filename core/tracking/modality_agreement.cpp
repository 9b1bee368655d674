#include "core/tracking/modality_agreement.h"

namespace st {

const char* to_string(Agreement a) {
  switch (a) {
    case Agreement::kAgree: return "agree";
    case Agreement::kNoOutline: return "no_outline";
    case Agreement::kOutlineLoose: return "outline_loose";
    case Agreement::kNoShading: return "no_shading";
    case Agreement::kDisagree: return "disagree";
  }
  return "unknown";
}

Agreement judge_agreement(const OutlineShadingEvidence& e, const AgreementLimits& limits) {
  if (e.outline_lines < limits.min_lines) return Agreement::kNoOutline;
  // NaN fails every comparison: it never agrees.
  if (!(e.outline_sigma_px <= limits.max_outline_sigma_px)) return Agreement::kOutlineLoose;
  if (!e.shading_measured) return Agreement::kNoShading;
  if (!(e.disagreement_px <= limits.max_disagreement_px)) return Agreement::kDisagree;
  if (limits.max_joint_sigma_px > 0 && !(e.joint_sigma_px <= limits.max_joint_sigma_px)) return Agreement::kOutlineLoose;
  return Agreement::kAgree;
}

}  // namespace st
