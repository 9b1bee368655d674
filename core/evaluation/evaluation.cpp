#include "core/evaluation/evaluation.h"

#include <algorithm>
#include <cmath>

namespace st {
namespace {

double percentile_sorted(const std::vector<double>& v, double p) {
  if (v.empty()) return 0.0;
  const double pos = p / 100.0 * static_cast<double>(v.size() - 1);
  const auto lo = static_cast<std::size_t>(std::floor(pos));
  const std::size_t hi = std::min(lo + 1, v.size() - 1);
  return v[lo] + (v[hi] - v[lo]) * (pos - static_cast<double>(lo));
}

double median_of(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return percentile_sorted(v, 50.0);
}

}  // namespace

bool project_marker(const CameraModel& cam, const SE3& T_model_camera, const Vec3& p_model,
                    Vec2* px) {
  const Vec3 p_camera = T_model_camera.inverse() * p_model;
  if (!(p_camera.z() > 1e-6)) return false;
  *px = cam.project(p_camera);
  return px->allFinite() && cam.pinhole().in_image(*px);
}

int frame_for_timestamp(double t_s, double fps, int frames) {
  if (!(fps > 0) || !std::isfinite(t_s)) return -1;
  const double f = t_s * fps;
  const long i = std::lround(f);
  if (i < 0 || i >= frames || std::abs(f - static_cast<double>(i)) > 0.25) return -1;
  return static_cast<int>(i);
}

EvalResult evaluate(const EvalInput& in) {
  EvalResult r;
  r.frames = in.frames;
  std::vector<double> tre_all, rot_err, trans_err, frame_tre;
  for (int i = 0; i < in.frames; ++i) {
    const bool has_est = i < static_cast<int>(in.estimated.size()) && in.estimated[i];
    if (!has_est) continue;
    ++r.reported_frames;
    if (i < kInitWindow) r.init_ok = true;
    const bool has_gt = i < static_cast<int>(in.groundtruth.size()) && in.groundtruth[i];
    if (!has_gt) continue;
    const SE3& est = *in.estimated[i];
    const SE3& gt = *in.groundtruth[i];
    ++r.pose_frames;
    const PoseDelta d = pose_delta(gt, est);
    rot_err.push_back(d.angle_deg);
    trans_err.push_back(d.distance_mm);
    frame_tre.clear();
    for (const Vec3& m : in.markers_model) {
      Vec2 px_gt;
      if (!project_marker(in.camera, gt, m, &px_gt)) continue;
      // The estimate may put the marker behind the camera: a wrong pose, not
      // a missing sample. Such a marker counts with kBehindCameraTrePx.
      const Vec3 p_camera_est = est.inverse() * m;
      double err = kBehindCameraTrePx;
      if (p_camera_est.z() > 1e-6) {
        const Vec2 px_est = in.camera.project(p_camera_est);
        if (px_est.allFinite()) err = std::min((px_est - px_gt).norm(), kBehindCameraTrePx);
      }
      frame_tre.push_back(err);
    }
    if (frame_tre.empty()) continue;
    ++r.tre_frames;
    tre_all.insert(tre_all.end(), frame_tre.begin(), frame_tre.end());
    if (median_of(frame_tre) > kWrongTrePx) ++r.wrong_frames;
  }
  if (r.frames > 0) {
    r.lost_pct = 100.0 * (r.frames - r.reported_frames) / r.frames;
    r.wrong_pct = 100.0 * r.wrong_frames / r.frames;
  }
  r.tre_samples = static_cast<int>(tre_all.size());
  if (!tre_all.empty()) {
    std::sort(tre_all.begin(), tre_all.end());
    double sum = 0;
    for (double e : tre_all) sum += e;
    r.tre_mean_px = sum / static_cast<double>(tre_all.size());
    r.tre_median_px = percentile_sorted(tre_all, 50.0);
    r.tre_p95_px = percentile_sorted(tre_all, 95.0);
    r.tre_max_px = tre_all.back();
  }
  r.rot_err_median_deg = median_of(rot_err);
  for (double e : rot_err) r.rot_err_max_deg = std::max(r.rot_err_max_deg, e);
  r.trans_err_median_mm = median_of(trans_err);
  return r;
}

}  // namespace st
