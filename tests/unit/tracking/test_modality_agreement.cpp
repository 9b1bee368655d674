// judge_agreement: a pose without features is reported only when the
// outline and the shading both measured it, the outline alone fixes the
// organ in view, and the two agree.
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
