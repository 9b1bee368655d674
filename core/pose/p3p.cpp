// P3P after Lambda Twist, derived here in our own notation.
//
// Unknowns: depths L = (l1, l2, l3) with camera points l_i * y_i (y_i unit
// bearings). Congruence with the model triangle gives, for each pair ij,
//   l_i^2 + l_j^2 + b_ij l_i l_j = a_ij,  b_ij = -2 y_i.y_j,  a_ij = |x_i - x_j|^2,
// i.e. L^T M_ij L = a_ij with M_ij symmetric. Eliminating the right-hand
// sides gives two homogeneous conics L^T D1 L = 0, L^T D2 L = 0 with
//   D1 = a23 M12 - a12 M23,  D2 = a23 M13 - a13 M23.
// Their pencil D1 + g D2 has a singular member for a real root g of the
// cubic det(D1 + g D2) = 0. A singular, indefinite D0 = e+ v+ v+^T + e- v- v-^T
// factors into two planes n.L = 0, n = sqrt|e+| v+ -/+ sqrt|e-| v-. On each
// plane, L = alpha p + beta q; the conic D1 (or D2) there is a quadratic form
// in (alpha, beta) with two real ray solutions at most; 2 planes x 2 rays = 4
// solutions. The scale follows from the sum of the three equations, whose
// form sum_ij |l_i y_i - l_j y_j|^2 is positive for any L != 0.
#include "core/pose/p3p.h"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>  // closed-form 3x3 inverse
#include <algorithm>
#include <cmath>

namespace st {

int solve_cubic_real(double a, double b, double c, double roots[3]) {
  // Depressed cubic t^3 + p t + q with x = t - a/3.
  const double a3 = a / 3.0;
  const double p = b - a * a3;
  const double q = 2.0 * a3 * a3 * a3 - a3 * b + c;
  const double disc = 0.25 * q * q + p * p * p / 27.0;
  int n = 0;
  if (disc > 0) {
    const double u = std::cbrt(-0.5 * q - std::copysign(std::sqrt(disc), q));
    roots[n++] = (u != 0.0 ? u - p / (3.0 * u) : 0.0) - a3;
  } else if (p == 0.0) {
    roots[n++] = -a3;
  } else {
    const double r = 2.0 * std::sqrt(-p / 3.0);
    const double phi = std::acos(std::clamp(3.0 * q / (p * r), -1.0, 1.0)) / 3.0;
    for (int k = 0; k < 3; ++k) roots[n++] = r * std::cos(phi - 2.0 * M_PI * k / 3.0) - a3;
  }
  for (int k = 0; k < n; ++k) {  // Newton polish on the original polynomial
    for (int it = 0; it < 2; ++it) {
      const double x = roots[k];
      const double f = ((x + a) * x + b) * x + c, df = (3.0 * x + 2.0 * a) * x + b;
      if (df != 0.0 && std::isfinite(f / df)) roots[k] = x - f / df;
    }
  }
  return n;
}

namespace {

struct Problem {
  Vec3 y[3];  // unit bearings
  Vec3 x[3];  // model points, scaled so that max a_ij = 1
  double b12, b13, b23, a12, a13, a23;
  Mat3 M12, M13, M23;
  Mat3 X_inverse;  // of [x1-x2, x1-x3, (x1-x2) x (x1-x3)]
};

Mat3 pair_form(int i, int j, double b) {
  Mat3 M = Mat3::Zero();
  M(i, i) = 1.0;
  M(j, j) = 1.0;
  M(i, j) = M(j, i) = 0.5 * b;
  return M;
}

// Coefficients of det(D1 + g D2) = c3 g^3 + c2 g^2 + c1 g + c0 by
// multilinearity of the determinant in the columns.
void pencil_cubic(const Mat3& D1, const Mat3& D2, double c[4]) {
  auto det3 = [](const Vec3& u, const Vec3& v, const Vec3& w) { return u.dot(v.cross(w)); };
  const Vec3 p0 = D1.col(0), p1 = D1.col(1), p2 = D1.col(2);
  const Vec3 q0 = D2.col(0), q1 = D2.col(1), q2 = D2.col(2);
  c[0] = det3(p0, p1, p2);
  c[1] = det3(q0, p1, p2) + det3(p0, q1, p2) + det3(p0, p1, q2);
  c[2] = det3(p0, q1, q2) + det3(q0, p1, q2) + det3(q0, q1, p2);
  c[3] = det3(q0, q1, q2);
}

// The singular pencil member whose two planes are best separated (most
// balanced positive/negative eigenvalues). False if none is indefinite.
bool degenerate_member(const Mat3& D1, const Mat3& D2, Eigen::SelfAdjointEigenSolver<Mat3>* best) {
  double c[4];
  pencil_cubic(D1, D2, c);
  double roots[3];
  int n;
  // Solve in g when |c3| dominates, else in m = 1/g (member m D1 + D2).
  const bool in_g = std::abs(c[3]) >= std::abs(c[0]);
  if (in_g) {
    if (c[3] == 0.0) return false;
    n = solve_cubic_real(c[2] / c[3], c[1] / c[3], c[0] / c[3], roots);
  } else {
    n = solve_cubic_real(c[1] / c[0], c[2] / c[0], c[3] / c[0], roots);
  }
  // A singular D0 has eigenvalues {0, e+, e-}: e+ e- is the sum m of its
  // principal 2x2 minors and e+ + e- its trace. It splits into two real
  // planes iff m < 0; the score -m / (e+^2 + e-^2) prefers well-separated
  // planes. One eigen-decomposition, for the chosen root only.
  double best_score = 1e-12, best_root = 0;
  for (int k = 0; k < n; ++k) {
    if (!std::isfinite(roots[k])) continue;
    const Mat3 D0 = in_g ? Mat3(D1 + roots[k] * D2) : Mat3(roots[k] * D1 + D2);
    const double m = D0(0, 0) * D0(1, 1) - D0(0, 1) * D0(1, 0) + D0(0, 0) * D0(2, 2) -
                     D0(0, 2) * D0(2, 0) + D0(1, 1) * D0(2, 2) - D0(1, 2) * D0(2, 1);
    const double tr = D0.trace();
    const double score = -m / (tr * tr - 2.0 * m + 1e-300);
    if (score > best_score) {
      best_score = score;
      best_root = roots[k];
    }
  }
  if (best_score <= 1e-12) return false;
  best->compute(in_g ? Mat3(D1 + best_root * D2) : Mat3(best_root * D1 + D2));
  if (best->info() != Eigen::Success) return false;
  const Vec3 e = best->eigenvalues();  // ascending: e- <= ~0 <= e+
  return e[0] < 0 && e[2] > 0;
}

// Residuals F_ij = L^T M_ij L - a_ij and their Jacobian.
Vec3 equations(const Problem& P, const Vec3& L, Mat3* J) {
  const Vec3 F(L.dot(P.M12 * L) - P.a12, L.dot(P.M13 * L) - P.a13, L.dot(P.M23 * L) - P.a23);
  if (J) {
    J->row(0) = 2.0 * (P.M12 * L).transpose();
    J->row(1) = 2.0 * (P.M13 * L).transpose();
    J->row(2) = 2.0 * (P.M23 * L).transpose();
  }
  return F;
}

// Gauss-Newton on the three equations; keeps the best iterate.
Vec3 refine_depths(const Problem& P, Vec3 L) {
  Mat3 J;
  double err = equations(P, L, &J).squaredNorm();
  for (int it = 0; it < 5 && err > 1e-30; ++it) {
    const Vec3 F = equations(P, L, &J);
    const double det = J.determinant();
    if (!(std::abs(det) > 1e-14 * std::pow(J.norm(), 3))) break;
    const Vec3 L_new = L - J.inverse() * F;
    const double err_new = equations(P, L_new, nullptr).squaredNorm();
    if (!(err_new < err)) break;
    L = L_new;
    err = err_new;
  }
  return L;
}

// Rigid transform taking the model triangle onto the camera points: with
// X = [x1-x2, x1-x3, (x1-x2) x (x1-x3)] and Y the same of the camera points,
// R = Y X^-1 exactly when the depths are exact (X is invertible for a
// non-collinear triangle); the quaternion re-normalisation removes the
// residual non-orthogonality of polished depths.
bool align(const Problem& P, const Vec3& L, SE3* T) {
  Vec3 cam[3];
  for (int i = 0; i < 3; ++i) cam[i] = L[i] * P.y[i];
  Mat3 Y;
  Y.col(0) = cam[0] - cam[1];
  Y.col(1) = cam[0] - cam[2];
  Y.col(2) = Y.col(0).cross(Y.col(1));
  const Mat3 R = Y * P.X_inverse;
  if (!R.allFinite()) return false;
  *T = SE3(Quat(R), Vec3::Zero());
  T->translation() = cam[0] - T->rotation() * P.x[0];
  return T->all_finite();
}

// Unit bearings, model points scaled to max a_ij = 1 (the cubic's
// coefficients are then O(1)), the pair forms. False for degenerate input.
bool set_up(const std::array<Vec3, 3>& bearing, const std::array<Vec3, 3>& p_model, Problem* P,
            double* scale) {
  for (int i = 0; i < 3; ++i) {
    const double norm = bearing[i].norm();
    if (!(norm > 0) || !std::isfinite(norm) || !p_model[i].allFinite()) return false;
    P->y[i] = bearing[i] / norm;
  }
  for (int i = 0; i < 3; ++i)
    if (P->y[i].cross(P->y[(i + 1) % 3]).squaredNorm() < 1e-20) return false;  // parallel rays
  const double a_max =
      std::max({(p_model[0] - p_model[1]).squaredNorm(), (p_model[0] - p_model[2]).squaredNorm(),
                (p_model[1] - p_model[2]).squaredNorm()});
  if (!(a_max > 0) || !std::isfinite(a_max)) return false;
  *scale = std::sqrt(a_max);
  for (int i = 0; i < 3; ++i) P->x[i] = p_model[i] / *scale;
  const Vec3 d12 = P->x[0] - P->x[1], d13 = P->x[0] - P->x[2], d23 = P->x[1] - P->x[2];
  P->a12 = d12.squaredNorm();
  P->a13 = d13.squaredNorm();
  P->a23 = d23.squaredNorm();
  if (d12.cross(d13).squaredNorm() <= 1e-12 * P->a12 * P->a13 + 1e-24) return false;  // collinear
  Mat3 X;
  X << d12, d13, d12.cross(d13);
  P->X_inverse = X.inverse();
  P->b12 = -2.0 * P->y[0].dot(P->y[1]);
  P->b13 = -2.0 * P->y[0].dot(P->y[2]);
  P->b23 = -2.0 * P->y[1].dot(P->y[2]);
  P->M12 = pair_form(0, 1, P->b12);
  P->M13 = pair_form(0, 2, P->b13);
  P->M23 = pair_form(1, 2, P->b23);
  return true;
}

// The (up to) two rays L = alpha p + beta q of the plane spanned by p, q
// on which the conic D vanishes: A alpha^2 + 2 B alpha beta + C beta^2 = 0,
// written in the cancellation-free form of the quadratic formula.
int plane_rays(const Mat3& D, const Vec3& p, const Vec3& q, Vec3 rays[2]) {
  const double A = p.dot(D * p), B = p.dot(D * q), C = q.dot(D * q);
  const double disc = B * B - A * C;
  const double coef = std::max({std::abs(A), std::abs(B), std::abs(C)});
  if (disc < -1e-12 * coef * coef) return 0;
  const double w = -(B + std::copysign(std::sqrt(std::max(disc, 0.0)), B));
  int n = 0;
  if (std::abs(w) + std::abs(A) > 0) rays[n++] = w * p + A * q;
  if (std::abs(C) + std::abs(w) > 0) rays[n++] = C * p + w * q;
  return n;
}

// Scales a ray onto the sum of the three equations, polishes it, and adds
// the pose if every depth is positive, the equations hold and it is new.
void add_solution(const Problem& P, const Vec3& ray, double scale, Vec3* found_L,
                  P3PSolutions* out) {
  const Mat3 M_sum = P.M12 + P.M13 + P.M23;
  const double den = ray.dot(M_sum * ray);
  if (!(den > 0)) return;
  Vec3 L = ray * std::sqrt((P.a12 + P.a13 + P.a23) / den);
  if (L.sum() < 0) L = -L;
  L = refine_depths(P, L);
  if (!(L.minCoeff() > 0) || !L.allFinite()) return;
  if (equations(P, L, nullptr).cwiseAbs().maxCoeff() > 1e-6) return;
  for (int k = 0; k < out->count; ++k)
    if ((found_L[k] - L).norm() <= 1e-7 * L.norm()) return;
  SE3 T;
  if (out->count >= 4 || !align(P, L, &T)) return;
  T.translation() *= scale;
  found_L[out->count] = L;
  out->T_camera_model[out->count++] = T;
}

}  // namespace

int solve_p3p(const std::array<Vec3, 3>& bearing, const std::array<Vec3, 3>& p_model,
              P3PSolutions* out) {
  out->count = 0;
  Problem P;
  double scale = 1.0;
  if (!set_up(bearing, p_model, &P, &scale)) return 0;
  const Mat3 D1 = P.a23 * P.M12 - P.a12 * P.M23;
  const Mat3 D2 = P.a23 * P.M13 - P.a13 * P.M23;
  Eigen::SelfAdjointEigenSolver<Mat3> eig;
  if (!degenerate_member(D1, D2, &eig)) return 0;
  const Vec3 e = eig.eigenvalues();
  const Vec3 v_null = eig.eigenvectors().col(1);
  Vec3 found_L[4];
  for (const double sign : {1.0, -1.0}) {
    const Vec3 n = std::sqrt(e[2]) * eig.eigenvectors().col(2) +
                   sign * std::sqrt(-e[0]) * eig.eigenvectors().col(0);
    const Vec3 q = n.cross(v_null).normalized();
    // D1 and D2 are proportional on the plane; use the better scaled one.
    const double s1 = std::abs(v_null.dot(D1 * v_null)) + std::abs(q.dot(D1 * q));
    const double s2 = std::abs(v_null.dot(D2 * v_null)) + std::abs(q.dot(D2 * q));
    Vec3 rays[2];
    const int n_rays = plane_rays(s1 >= s2 ? D1 : D2, v_null, q, rays);
    for (int r = 0; r < n_rays; ++r) add_solution(P, rays[r], scale, found_L, out);
  }
  return out->count;
}

}  // namespace st
