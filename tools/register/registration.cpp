#include "registration.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "core/pose/correspondences.h"
#include "core/pose/p3p.h"
#include "core/pose/pose_solver.h"
#include "core/formats/text_scan.h"

namespace st {

Result<std::vector<RegistrationPair>> parse_registration_pairs(std::string_view text) {
  if (text.find('\0') != std::string_view::npos) return make_error("pairs: the file holds a NUL byte (not text)");
  std::vector<RegistrationPair> pairs;
  const Status s = for_each_data_line(text, [&](std::string_view line, int line_no) -> Status {
    line = line.substr(0, line.find('#'));  // a comment after the numbers
    TextScanner scan(line);
    std::array<double, 5> v{};
    int n = 0;
    for (std::string_view tok = scan.next_token(); !tok.empty(); tok = scan.next_token()) {
      if (n == 5) return make_error("pairs line " + std::to_string(line_no) + ": more than 5 fields (u v x y z)");
      if (!parse_double(tok, &v[static_cast<std::size_t>(n)]) || !std::isfinite(v[static_cast<std::size_t>(n)]))
        return make_error("pairs line " + std::to_string(line_no) + ": " + quote_bytes(tok) +
                          " is not a finite number");
      ++n;
    }
    if (n == 0) return Status::Ok();  // only blanks
    if (n != 5)
      return make_error("pairs line " + std::to_string(line_no) + ": " + std::to_string(n) +
                        " fields, want 5 (u v x y z: pixel, then model point in mm)");
    if (static_cast<int>(pairs.size()) == kMaxRegistrationPairs)
      return make_error("pairs: more than " + std::to_string(kMaxRegistrationPairs) + " pairs (line " +
                        std::to_string(line_no) + ")");
    pairs.push_back({Vec2(v[0], v[1]), Vec3(v[2], v[3], v[4]), line_no});
    return Status::Ok();
  });
  if (!s) return make_error(s.message());
  return pairs;
}

namespace {

// Sum over the pairs of min(|r|^2, tau^2) at T (ideal pixels); a point
// behind the camera costs tau^2.
double truncated_cost(const SE3& T, const std::vector<Vec3>& p, const std::vector<Vec2>& q, const Pinhole& K,
                      double tau2) {
  double cost = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    const Vec3 c = T * p[i];
    cost += c.z() > 1e-6 ? std::min((K.project(c) - q[i]).squaredNorm(), tau2) : tau2;
  }
  return cost;
}

}  // namespace

Result<RegistrationResult> register_first_frame(const std::vector<RegistrationPair>& pairs,
                                                const CameraModel& camera, const RegistrationOptions& options) {
  const Pinhole& K = camera.pinhole();
  if (Status s = CameraModel::validate(K, camera.distortion()); !s.ok()) return make_error("camera: " + s.message());
  const int n = static_cast<int>(pairs.size());
  if (n < kMinRegistrationPairs)
    return make_error("registration needs at least " + std::to_string(kMinRegistrationPairs) + " pairs, got " +
                      std::to_string(n));
  if (n > kMaxRegistrationPairs)
    return make_error("registration takes at most " + std::to_string(kMaxRegistrationPairs) + " pairs");
  if (!(options.inlier_px > 0.0) || !std::isfinite(options.inlier_px))
    return make_error("registration: inlier_px must be a positive number");
  std::vector<Vec3> p(static_cast<std::size_t>(n));
  std::vector<Vec2> q(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    const RegistrationPair& pr = pairs[static_cast<std::size_t>(i)];
    if (!pr.px.allFinite() || !pr.p_model.allFinite() || !K.in_image(pr.px))
      return make_error("pair on line " + std::to_string(pr.line) + ": pixel (" + std::to_string(pr.px.x()) + ", " +
                        std::to_string(pr.px.y()) + ") is outside the " + std::to_string(K.width) + "x" +
                        std::to_string(K.height) + " image");
    if (!camera.undistort_pixel(pr.px, &q[static_cast<std::size_t>(i)]))
      return make_error("pair on line " + std::to_string(pr.line) + ": the pixel does not undistort");
    p[static_cast<std::size_t>(i)] = pr.p_model;
  }
  const double tau = options.inlier_px, tau2 = tau * tau;
  RegistrationResult out;
  double best = std::numeric_limits<double>::infinity();
  bool have = false;
  const auto bearing = [&](int i) { return K.unproject(q[static_cast<std::size_t>(i)], 1.0); };
  for (int a = 0; a < n; ++a)
    for (int b = a + 1; b < n; ++b)
      for (int c = b + 1; c < n; ++c) {
        ++out.triples;
        P3PSolutions sol;
        const int k = solve_p3p({bearing(a), bearing(b), bearing(c)},
                                {p[static_cast<std::size_t>(a)], p[static_cast<std::size_t>(b)],
                                 p[static_cast<std::size_t>(c)]},
                                &sol);
        for (int s = 0; s < k; ++s) {
          ++out.hypotheses;
          const SE3& T = sol.T_camera_model[static_cast<std::size_t>(s)];
          const double cost = truncated_cost(T, p, q, K, tau2);
          if (cost < best) {  // strict: the first of equal costs stays (deterministic)
            best = cost;
            out.T_camera_model = T;
            have = true;
          }
        }
      }
  if (!have) return make_error("no triple of pairs gives a pose (model points coincident or collinear?)");
  // LM on all pairs, Huber at the inlier radius: information 5.991 / tau^2
  // makes the solver's chi2 inlier test |r| < tau.
  std::vector<double> info(static_cast<std::size_t>(n), kChi2Inlier2Dof / tau2);
  PoseSolverOptions so;
  so.min_inliers = kMinRegistrationPairs;
  so.max_iterations = 50;
  PoseSolver solver;
  if (Status s = solver.configure(kMaxRegistrationPairs, so); !s.ok()) return make_error(s.message());
  SE3 T = out.T_camera_model;
  PoseSolverSummary summary;
  const Correspondences corr{p.data(), q.data(), info.data(), n};
  if (solver.solve(corr, K, &T, &summary) && truncated_cost(T, p, q, K, tau2) <= best + 1e-9) {
    out.T_camera_model = T;
    out.refined = true;
  }
  // Residuals where the picks were made: distorted pixels.
  double sum2 = 0;
  for (int i = 0; i < n; ++i) {
    const Vec3 c = out.T_camera_model * p[static_cast<std::size_t>(i)];
    const double r = c.z() > 1e-6 ? (camera.project(c) - pairs[static_cast<std::size_t>(i)].px).norm()
                                  : std::numeric_limits<double>::infinity();
    out.residual_px.push_back(r);
    const bool in = r <= tau;
    out.inlier.push_back(in);
    if (in) {
      ++out.inliers;
      sum2 += r * r;
    }
  }
  if (out.inliers < kMinRegistrationPairs)
    return make_error("the picks do not agree on a pose: at best " + std::to_string(out.inliers) + " of " +
                      std::to_string(n) + " pairs within " + std::to_string(tau) + " px");
  out.rms_px = std::sqrt(sum2 / out.inliers);
  return out;
}

}  // namespace st
