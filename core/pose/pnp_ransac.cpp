#include "core/pose/pnp_ransac.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>

#include "core/base/capacity.h"
#include "core/pose/p3p.h"
#include "core/geometry/reprojection.h"
#include "core/base/rng.h"

namespace st {

const char* to_string(PnpRansacStatus s) {
  switch (s) {
    case PnpRansacStatus::kOk:
      return "ok";
    case PnpRansacStatus::kNotConfigured:
      return "PnP RANSAC not configured";
    case PnpRansacStatus::kTooManyPoints:
      return "more correspondences than the configured capacity";
    case PnpRansacStatus::kTooFewPoints:
      return "too few valid correspondences for PnP RANSAC";
    case PnpRansacStatus::kInvalidCamera:
      return "camera not finite or fx, fy <= 0";
    case PnpRansacStatus::kNoConsensus:
      return "no pose hypothesis reached min_inliers";
  }
  return "unknown PnP RANSAC status";
}

namespace {

// Samples needed so that, with inlier ratio w, at least one 4-sample is all
// inliers with probability `confidence`.
double adaptive_iterations(int inliers, int valid, double confidence) {
  const double w = static_cast<double>(inliers) / static_cast<double>(std::max(valid, 1));
  const double w4 = w * w * w * w;
  if (w4 >= 1.0) return 0.0;
  if (w4 <= 0.0) return 1e30;
  return std::log(1.0 - confidence) / std::log1p(-w4);
}

// Four distinct positions in [0, n), n >= 4.
void draw_sample(Pcg32* rng, int n, int sample[4]) {
  for (int k = 0; k < 4; ++k) {
    bool repeated = true;
    while (repeated) {
      sample[k] = static_cast<int>(rng->below(static_cast<std::uint32_t>(n)));
      repeated = std::find(sample, sample + k, sample[k]) != sample + k;
    }
  }
}

}  // namespace

Status PnpRansac::configure(int max_correspondences, const Options& opt) {
  configured_ = false;
  if (max_correspondences < 4 || max_correspondences > kMaxKeypoints)
    return make_error("PnpRansac: max_correspondences " + std::to_string(max_correspondences) +
                      " outside [4, kMaxKeypoints=" + std::to_string(kMaxKeypoints) + "]");
  if (!(opt.inlier_threshold_px > 0) || !(opt.confidence > 0 && opt.confidence < 1) ||
      opt.max_iterations < 1 || opt.min_iterations < 0 || opt.min_inliers < 4 ||
      opt.refine_passes < 1)
    return make_error(
        "PnpRansac: need threshold > 0, confidence in (0, 1), max_iterations >= 1, "
        "min_inliers >= 4");
  if (Status st = solver_.configure(max_correspondences, opt.refine_options); !st.ok())
    return make_error("PnpRansac: refine options: " + st.message());
  options_ = opt;
  threshold2_ = opt.inlier_threshold_px * opt.inlier_threshold_px;
  const auto n = static_cast<std::size_t>(max_correspondences);
  bearing_.assign(n, Vec3::Zero());
  valid_index_.assign(n, 0);
  inlier_.assign(n, 0);
  previous_inlier_.assign(n, 0);
  in_p_model_.assign(n, Vec3::Zero());
  in_px_.assign(n, Vec2::Zero());
  in_info_.assign(n, 0.0);
  configured_ = true;
  return Status::Ok();
}

// Bearings of every observation and the list of valid indices.
int PnpRansac::prepare(const Correspondences& c, const Pinhole& K) {
  num_valid_ = 0;
  for (int i = 0; i < c.count; ++i) {
    bearing_[i] = Vec3((c.px_ideal[i].x() - K.cx) / K.fx, (c.px_ideal[i].y() - K.cy) / K.fy, 1.0);
    if (c.valid(i)) valid_index_[num_valid_++] = i;
  }
  return num_valid_;
}

// P3P on sample[0..2]; of its solutions the one under which sample[3]
// reprojects best, if within the inlier threshold.
bool PnpRansac::hypothesis(const Correspondences& c, const Pinhole& K, const int sample[4],
                           SE3* T) const {
  const std::array<Vec3, 3> bearing{bearing_[sample[0]], bearing_[sample[1]], bearing_[sample[2]]};
  const std::array<Vec3, 3> p_model{c.p_model[sample[0]], c.p_model[sample[1]],
                                    c.p_model[sample[2]]};
  P3PSolutions sol;
  if (solve_p3p(bearing, p_model, &sol) == 0) return false;
  const int check = sample[3];
  double best_chi2 = threshold2_;
  bool found = false;
  for (int k = 0; k < sol.count; ++k) {
    Vec2 r;
    if (!reprojection_residual(K, sol.T_camera_model[k], c.p_model[check], c.px_ideal[check],
                               options_.min_depth_mm, &r, nullptr))
      continue;
    const double chi2 = c.info(check) * r.squaredNorm();
    if (chi2 < best_chi2) {
      best_chi2 = chi2;
      *T = sol.T_camera_model[k];
      found = true;
    }
  }
  return found;
}

// Inlier count of T over the valid correspondences; stops early once
// `to_beat` cannot be exceeded (the returned count is then a lower bound).
int PnpRansac::score(const Correspondences& c, const Pinhole& K, const SE3& T, int to_beat) const {
  int n = 0;
  Vec2 r;
  for (int k = 0; k < num_valid_; ++k) {
    if (n + (num_valid_ - k) <= to_beat) break;
    const int i = valid_index_[k];
    if (reprojection_residual(K, T, c.p_model[i], c.px_ideal[i], options_.min_depth_mm, &r,
                              nullptr) &&
        c.info(i) * r.squaredNorm() < threshold2_)
      ++n;
  }
  return n;
}

int PnpRansac::classify(const Correspondences& c, const Pinhole& K, const SE3& T) {
  std::memset(inlier_.data(), 0, static_cast<std::size_t>(c.count));
  int n = 0;
  Vec2 r;
  for (int k = 0; k < num_valid_; ++k) {
    const int i = valid_index_[k];
    if (reprojection_residual(K, T, c.p_model[i], c.px_ideal[i], options_.min_depth_mm, &r,
                              nullptr) &&
        c.info(i) * r.squaredNorm() < threshold2_) {
      inlier_[i] = 1;
      ++n;
    }
  }
  return n;
}

bool PnpRansac::sample_and_score(const Correspondences& c, const Pinhole& K, SE3* best_T,
                                 Summary* s) {
  Pcg32 rng(options_.seed);
  int best = 0;
  double needed = options_.max_iterations;
  int sample[4];
  for (int it = 0; it < options_.max_iterations && (it < needed || it < options_.min_iterations);
       ++it) {
    draw_sample(&rng, num_valid_, sample);
    for (int& k : sample) k = valid_index_[k];
    ++s->iterations;
    SE3 T;
    if (!hypothesis(c, K, sample, &T)) continue;
    ++s->hypotheses;
    const int n = score(c, K, T, best);
    if (n > best) {
      best = n;
      *best_T = T;
      s->best_iteration = it;
      needed = adaptive_iterations(best, num_valid_, options_.confidence);
    }
  }
  s->hypothesis_inliers = best;
  return best >= options_.min_inliers;
}

// LM on the current inliers (compacted), then all correspondences are
// re-classified at the refined pose and the LM runs again on the new set,
// until the set is stable (at most options.refine_passes). One pass is not
// enough: the hypothesis' inliers are biased toward the hypothesis (true
// inliers it misses cannot come back), which cost ~5x the noise-limited
// accuracy in the 50%-outlier test. Keeps the hypothesis if the LM fails.
bool PnpRansac::refine_once(const Correspondences& c, const Pinhole& K, SE3* T, Summary* s) {
  int n = 0;
  for (int i = 0; i < c.count; ++i) {
    if (!inlier_[i]) continue;
    in_p_model_[n] = c.p_model[i];
    in_px_[n] = c.px_ideal[i];
    in_info_[n] = c.info(i);
    ++n;
  }
  const Correspondences sub{in_p_model_.data(), in_px_.data(), in_info_.data(), n};
  return solver_.solve(sub, K, T, &s->refine);
}

bool PnpRansac::refine(const Correspondences& c, const Pinhole& K, SE3* T, Summary* s) {
  SE3 T_refined = *T;
  bool refined = false;
  for (int pass = 0; pass < options_.refine_passes; ++pass) {
    if (!refine_once(c, K, &T_refined, s)) break;
    const auto bytes = static_cast<std::size_t>(c.count);
    std::memcpy(previous_inlier_.data(), inlier_.data(), bytes);
    s->num_inliers = classify(c, K, T_refined);
    refined = true;
    if (std::memcmp(previous_inlier_.data(), inlier_.data(), bytes) == 0) break;
  }
  if (!refined || s->num_inliers < options_.min_inliers) {
    s->num_inliers = classify(c, K, *T);  // back to the hypothesis and its flags
    return false;
  }
  *T = T_refined;
  return true;
}

bool PnpRansac::solve(const Correspondences& c, const Pinhole& K, SE3* T_camera_model,
                      Summary* summary) {
  Summary local;
  Summary& s = summary ? *summary : local;
  s = Summary{};
  last_count_ = 0;
  if (!configured_) return (s.status = PnpRansacStatus::kNotConfigured), false;
  if (c.count > capacity()) return (s.status = PnpRansacStatus::kTooManyPoints), false;
  if (c.count < 4 || !c.p_model || !c.px_ideal || !T_camera_model)
    return (s.status = PnpRansacStatus::kTooFewPoints), false;
  if (!pinhole_is_usable(K)) return (s.status = PnpRansacStatus::kInvalidCamera), false;
  last_count_ = c.count;
  std::memset(inlier_.data(), 0, static_cast<std::size_t>(c.count));
  s.num_valid = prepare(c, K);
  if (s.num_valid < std::max(4, options_.min_inliers))
    return (s.status = PnpRansacStatus::kTooFewPoints), false;
  SE3 T;
  if (!sample_and_score(c, K, &T, &s)) return (s.status = PnpRansacStatus::kNoConsensus), false;
  s.num_inliers = classify(c, K, T);
  if (options_.refine) {
    s.refined = refine(c, K, &T, &s);
  }
  *T_camera_model = T;
  s.status = PnpRansacStatus::kOk;
  return true;
}

}  // namespace st
