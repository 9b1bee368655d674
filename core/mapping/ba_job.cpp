#include "core/mapping/ba_job.h"

#include <cmath>
#include <string>

namespace st {

void pose_to_params(const SE3& T_camera_model, double* params) {
  const Quat q = T_camera_model.quaternion();
  params[0] = q.x();
  params[1] = q.y();
  params[2] = q.z();
  params[3] = q.w();
  params[4] = T_camera_model.translation().x();
  params[5] = T_camera_model.translation().y();
  params[6] = T_camera_model.translation().z();
}

SE3 pose_from_params(const double* params) {
  return SE3(Quat(params[3], params[0], params[1], params[2]), Vec3(params[4], params[5], params[6]));
}

const char* ba_refusal_text(BaRefusal refusal) {
  switch (refusal) {
    case BaRefusal::kNone: return "not refused";
    case BaRefusal::kNotConfigured: return "bundle adjustment: configure() the adjuster before solving";
    case BaRefusal::kEmpty: return "bundle adjustment: the job has no keyframe or no point";
    case BaRefusal::kTooBig:
      return "bundle adjustment: the job has more keyframes, points or observations than configured "
             "(raise the adjuster's maxima to the job buffer's capacities)";
    case BaRefusal::kBadIndex: return "bundle adjustment: an observation names a keyframe or point out of range";
    case BaRefusal::kNotFinite: return "bundle adjustment: a pose, point, pixel or information is NaN or infinite";
    case BaRefusal::kBadPrior: return "bundle adjustment: the pose prior's keyframe, pose or sigmas are not usable";
    case BaRefusal::kNothingToSolve: return "bundle adjustment: no observation passes the caps and the depth test";
  }
  return "bundle adjustment: unknown refusal";
}

Status BaJob::configure(int max_keyframes, int max_points, int max_observations) {
  if (max_keyframes < 1 || max_points < 1 || max_observations < 1)
    return make_error("BA job: capacities must be >= 1 (got " + std::to_string(max_keyframes) + " keyframes, " +
                      std::to_string(max_points) + " points, " + std::to_string(max_observations) + " observations)");
  keyframes.assign(static_cast<std::size_t>(max_keyframes), BaKeyframe{});
  points.assign(static_cast<std::size_t>(max_points), BaPoint{});
  observations.assign(static_cast<std::size_t>(max_observations), BaObservation{});
  clear();
  return Status::Ok();
}

void BaJob::clear() {
  keyframe_count = point_count = observation_count = 0;
  prior = BaPosePrior{};
  test_focal = false;
  summary = BaSummary{};
}

bool pose_prior_sigmas_usable(double sigma_rad, double sigma_mm) {
  return sigma_rad > 0 && std::isfinite(sigma_rad) && sigma_mm > 0 && std::isfinite(sigma_mm);
}

bool BaJob::set_prior(int keyframe_index, const SE3& T_camera_model, double sigma_rad,
                      double sigma_mm) {
  if (keyframe_index < 0 || keyframe_index >= keyframe_count || !T_camera_model.all_finite() ||
      !pose_prior_sigmas_usable(sigma_rad, sigma_mm))
    return false;
  prior.keyframe = keyframe_index;
  pose_to_params(T_camera_model, prior.pose);
  prior.sigma_rad = sigma_rad;
  prior.sigma_mm = sigma_mm;
  return true;
}

int BaJob::add_keyframe(int id, int frame, const SE3& T_camera_model, bool fixed) {
  if (keyframe_count >= keyframe_capacity()) return -1;
  BaKeyframe& k = keyframes[static_cast<std::size_t>(keyframe_count)];
  k.id = id;
  k.frame = frame;
  k.fixed = fixed;
  pose_to_params(T_camera_model, k.pose);
  return keyframe_count++;
}

int BaJob::add_point(int id, int created_frame, const Vec3& p_model) {
  if (point_count >= point_capacity()) return -1;
  BaPoint& p = points[static_cast<std::size_t>(point_count)];
  p.id = id;
  p.created_frame = created_frame;
  for (int k = 0; k < 3; ++k) p.p_model[k] = p.p_initial[k] = p_model[k];
  return point_count++;
}

bool BaJob::add_observation(int keyframe_index, int point_index, const Vec2& px_ideal, double info) {
  if (observation_count >= observation_capacity()) return false;
  BaObservation& o = observations[static_cast<std::size_t>(observation_count++)];
  o.keyframe = keyframe_index;
  o.point = point_index;
  o.x_ideal = px_ideal.x();
  o.y_ideal = px_ideal.y();
  o.info = info;
  return true;
}

Vec3 BaJob::point(int i) const {
  const double* p = points[static_cast<std::size_t>(i)].p_model;
  return {p[0], p[1], p[2]};
}

}  // namespace st
