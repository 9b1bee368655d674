// Minimal absolute pose (P3P) from three bearing vectors and their model
// points, after Lambda Twist (Persson & Nordberg, ECCV 2018): the three
// law-of-cosines quadrics in the depths lambda are combined into a
// degenerate member of their pencil (one cubic root), which splits into two
// planes; each plane meets a second quadric in two rays, the depth follows
// from the sum of the three equations, Gauss-Newton polishes the depths and
// the rotation follows in closed form from the two triangles (R = Y X^-1).
// Derivation in p3p.cpp.
//
// Pure function, no allocation, no exceptions. Degenerate input (collinear
// or coincident model points, parallel or non-finite bearings) gives 0
// solutions; no NaN ever reaches the output.
#pragma once

#include <array>

#include "core/geometry/se3.h"

namespace st {

struct P3PSolutions {
  std::array<SE3, 4> T_camera_model;  // the first `count` are valid
  int count = 0;
};

// bearing[i]: direction of model point p_model[i] in the camera frame (need
// not be unit length; z > 0 is not required). Only solutions with all three
// points in front along their bearings (depth > 0) are returned. Returns
// out->count (0..4).
int solve_p3p(const std::array<Vec3, 3>& bearing, const std::array<Vec3, 3>& p_model,
              P3PSolutions* out);

// Real roots of x^3 + a x^2 + b x + c (Newton-polished). Returns 1..3.
int solve_cubic_real(double a, double b, double c, double roots[3]);

}  // namespace st
