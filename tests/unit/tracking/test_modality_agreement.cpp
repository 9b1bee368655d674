// judge_agreement: a pose without features is reported only when the
// outline and the shading both measured it, the outline alone places the
// organ in view, the two agree, and together they fix it.
#include <doctest/doctest.h>

#include <cmath>
#include <limits>
#include <string>

#include "core/tracking/modality_agreement.h"

using namespace st;

namespace {

OutlineShadingEvidence agreeing() {
  OutlineShadingEvidence e;
  e.outline_lines = 120;
  e.outline_sigma_px = 0.8;
  e.shading_measured = true;
  e.disagreement_px = 2.0;
  e.joint_sigma_px = 0.3;
  return e;
}

}  // namespace

TEST_CASE("modality agreement: both measured, the outline tight, the same place: agree") {
  const AgreementLimits limits;
  CHECK(judge_agreement(agreeing(), limits) == Agreement::kAgree);
  // On the limits themselves: still agree.
  OutlineShadingEvidence e = agreeing();
  e.outline_lines = limits.min_lines;
  e.outline_sigma_px = limits.max_outline_sigma_px;
  e.disagreement_px = limits.max_disagreement_px;
  e.joint_sigma_px = limits.max_joint_sigma_px;
  CHECK(judge_agreement(e, limits) == Agreement::kAgree);
}

TEST_CASE("modality agreement: a pose that one modality alone supports is refused") {
  const AgreementLimits limits;
  // The outline fits, the shading measured nothing.
  OutlineShadingEvidence e = agreeing();
  e.shading_measured = false;
  CHECK(judge_agreement(e, limits) == Agreement::kNoShading);
  // The shading measured, the outline did not (too few lines).
  e = agreeing();
  e.outline_lines = limits.min_lines - 1;
  CHECK(judge_agreement(e, limits) == Agreement::kNoOutline);
  e.outline_lines = 0;
  CHECK(judge_agreement(e, limits) == Agreement::kNoOutline);
  // The outline measured, but too loosely to fix the organ.
  e = agreeing();
  e.outline_sigma_px = limits.max_outline_sigma_px * 1.01;
  CHECK(judge_agreement(e, limits) == Agreement::kOutlineLoose);
  // Both measured, at different places.
  e = agreeing();
  e.disagreement_px = limits.max_disagreement_px + 0.01;
  CHECK(judge_agreement(e, limits) == Agreement::kDisagree);
}

TEST_CASE("modality agreement: NaN and infinity never agree") {
  const AgreementLimits limits;
  for (double bad : {std::nan(""), std::numeric_limits<double>::infinity()}) {
    OutlineShadingEvidence e = agreeing();
    e.outline_sigma_px = bad;
    CHECK(judge_agreement(e, limits) == Agreement::kOutlineLoose);
    e = agreeing();
    e.disagreement_px = bad;
    CHECK(judge_agreement(e, limits) == Agreement::kDisagree);
  }
  CHECK(std::string(to_string(Agreement::kNoShading)) == "no_shading");
}

TEST_CASE("modality agreement: the outline and the shading together must fix the organ") {
  AgreementLimits limits;
  limits.max_outline_sigma_px = 4.0;
  limits.max_joint_sigma_px = 1.5;
  OutlineShadingEvidence e = agreeing();
  e.outline_sigma_px = 3.5;  // the outline alone places the organ only roughly...
  e.joint_sigma_px = 0.4;    // ...but the shading fixes what it leaves open
  CHECK(judge_agreement(e, limits) == Agreement::kAgree);
  e.joint_sigma_px = 1.6;
  CHECK(judge_agreement(e, limits) == Agreement::kOutlineLoose);
  for (double bad : {std::nan(""), std::numeric_limits<double>::infinity()}) {
    e.joint_sigma_px = bad;
    CHECK(judge_agreement(e, limits) == Agreement::kOutlineLoose);
  }
  // The outline's own cap still holds whatever the joint pose.
  e = agreeing();
  e.outline_sigma_px = 4.1;
  e.joint_sigma_px = 0.2;
  CHECK(judge_agreement(e, limits) == Agreement::kOutlineLoose);
  // Not tested when its limit is 0 (the evidence's default is infinite).
  limits.max_joint_sigma_px = 0.0;
  e = agreeing();
  e.joint_sigma_px = std::numeric_limits<double>::infinity();
  CHECK(judge_agreement(e, limits) == Agreement::kAgree);
}
