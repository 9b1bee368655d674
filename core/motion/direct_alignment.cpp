#include "core/motion/direct_alignment.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <Eigen/Cholesky>

#include "core/base/capacity.h"

namespace st {
namespace {

using Vec8 = Eigen::Matrix<double, 8, 1>;
using Mat8 = Eigen::Matrix<double, 8, 8>;

constexpr int kMaxIterations = 15;
// A level has converged when a step moves the points by less than this
// many of its pixels (the motion, not the parameters: 1e-6 on the twist,
// the earlier test, took ~40 iterations over the levels where ~20 give the
// same poses within 0.005 px on the fast swing's frames).
constexpr double kConvergedPx = 0.01;
constexpr double kHuber = 1.345;     // in robust sigmas
constexpr double kOutCostSigmas = 3; // a point that left the image costs like a 3-sigma residual

double huber_cost(double r, double k) {
  const double a = std::abs(r);
  return a <= k ? 0.5 * r * r : k * (a - 0.5 * k);
}

// Bilinear sample at (x, y), 0 <= x < w - 1, 0 <= y < h - 1.
inline double bilinear(const float* img, int w, double x, double y) {
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const double fx = x - x0, fy = y - y0;
  const float* p = img + static_cast<std::ptrdiff_t>(y0) * w + x0;
  return (1.0 - fy) * ((1.0 - fx) * static_cast<double>(p[0]) + fx * static_cast<double>(p[1])) +
         fy * ((1.0 - fx) * static_cast<double>(p[w]) + fx * static_cast<double>(p[w + 1]));
}

}  // namespace

int DirectAligner::choose_level(const int* widths, int levels) {
  int best = 0;
  for (int k = 1; k < levels; ++k)
    if (std::abs(widths[k] - kTargetWidth) < std::abs(widths[best] - kTargetWidth)) best = k;
  return best;
}

namespace {

// The level sizes every aligner of width x height uses (halving, at least 1).
template <class Visit>
void for_each_level_size(int width, int height, int levels, Visit&& visit) {
  int w = width, h = height;
  for (int k = 0; k < levels; ++k) {
    visit(k, w, h);
    w = std::max(w / 2, 1);
    h = std::max(h / 2, 1);
  }
}

}  // namespace

Status DirectAlignScratch::configure(int width, int height) {
  width_ = height_ = 0;
  if (width < 1 || height < 1 || width > kMaxImageWidth || height > kMaxImageHeight)
    return make_error("DirectAlignScratch: images of " + std::to_string(width) + "x" + std::to_string(height));
  std::size_t n = 0;
  for_each_level_size(width, height, DirectAligner::kLevels,
                      [&](int, int w, int h) { n += static_cast<std::size_t>(w) * static_cast<std::size_t>(h); });
  planes_.assign(4 * n, 0.f);
  masks_.assign(n, 0);
  width_ = width;
  height_ = height;
  return Status::Ok();
}

Status DirectAligner::configure(int width, int height, double scale, DirectAlignScratch* shared) {
  configured_ = have_reference_ = false;
  if (width < kMinLevelWidth || height < 16 || width > kMaxImageWidth || height > kMaxImageHeight ||
      !(scale >= 1.0) || !std::isfinite(scale))
    return make_error("DirectAligner: images of " + std::to_string(width) + "x" + std::to_string(height) +
                      " at scale " + std::to_string(scale) + ": need at least " + std::to_string(kMinLevelWidth) +
                      "x16, at most the frame size, and scale >= 1");
  levels_used_ = 1;
  while (levels_used_ < kLevels && (width >> levels_used_) >= kMinLevelWidth && (height >> levels_used_) >= 8)
    ++levels_used_;
  DirectAlignScratch* scratch = shared ? shared : &own_scratch_;
  if (!shared) {
    if (Status st = own_scratch_.configure(width, height); !st.ok()) return st;
  } else if (shared->width_ != width || shared->height_ != height) {
    return make_error("DirectAligner: a shared scratch of " + std::to_string(shared->width_) + "x" +
                      std::to_string(shared->height_) + " for images of " + std::to_string(width) + "x" +
                      std::to_string(height));
  }
  std::size_t offset = 0;
  const std::size_t total = scratch->masks_.size();
  double s = scale;
  for_each_level_size(width, height, kLevels, [&](int k, int w, int h) {
    Level& l = levels_[k];
    l.w = w;
    l.h = h;
    l.scale = s;
    s *= 2.0;
    const auto n = static_cast<std::size_t>(w) * static_cast<std::size_t>(h);
    l.ref.assign(n, 0.f);
    l.ref_mask.assign(n, 0);
    float* planes = scratch->planes_.data();
    l.cur = planes + offset;
    l.tmp = planes + total + offset;
    l.gx = planes + 2 * total + offset;
    l.gy = planes + 3 * total + offset;
    l.cur_mask = scratch->masks_.data() + offset;
    offset += n;
  });
  ref_image_.assign(static_cast<std::size_t>(width) * static_cast<std::size_t>(height), 0);
  // The reference's valid mask as sampled at the finest level (eroded when
  // the reference is built), not the frame's own: 0.9 MB less per aligner
  // at 1280x720. The frame's valid mask is at most the frame itself.
  ref_valid_.assign(static_cast<std::size_t>(width) * static_cast<std::size_t>(height), 0);
  const auto full_w = static_cast<std::size_t>(std::ceil(width * scale)) + 2;
  const auto full_h = static_cast<std::size_t>(std::ceil(height * scale)) + 2;
  max_valid_pixels_ = full_w * full_h;
  valid_col_.assign(static_cast<std::size_t>(width), 0);
  p_model_.assign(kMaxPoints, Vec3::Zero());
  intensity_.assign(kMaxPoints, 0.0);
  residuals_.assign(kMaxPoints, 0.0);
  configured_ = true;
  return Status::Ok();
}

// The finest level's mask from the frame's valid mask (sampled at each
// pixel's centre in its own pixels; empty: all valid), eroded by one pixel
// so that the edge of the field stop, which does not move with the scene,
// never pulls the alignment.
void DirectAligner::sample_valid(GrayView valid, std::uint8_t* mask) {
  sample_mask(valid, mask);
  erode_mask(mask);
}

// The valid mask at the finest level's pixels (1: valid), nearest sample.
void DirectAligner::sample_mask(GrayView valid, std::uint8_t* mask) {
  const Level& l = levels_[0];
  const int w = l.w, h = l.h;
  const double full_w = l.w * l.scale, full_h = l.h * l.scale;
  if (valid.empty()) {
    std::fill_n(mask, static_cast<std::size_t>(w) * static_cast<std::size_t>(h), std::uint8_t{1});
  } else {
    // The valid mask's column of each x and row of each y (full-resolution
    // centres, pixel-edge origin), once per call rather than per pixel.
    for (int x = 0; x < w; ++x)
      valid_col_[static_cast<std::size_t>(x)] =
          std::clamp(static_cast<int>((x + 0.5) * l.scale * valid.width / full_w), 0, valid.width - 1);
    for (int y = 0; y < h; ++y) {
      const int vy = std::clamp(static_cast<int>((y + 0.5) * l.scale * valid.height / full_h), 0, valid.height - 1);
      const std::uint8_t* vrow = valid.row(vy);
      std::uint8_t* out = mask + static_cast<std::size_t>(y) * w;
      for (int x = 0; x < w; ++x) out[x] = vrow[valid_col_[static_cast<std::size_t>(x)]] != 0 ? 1 : 0;
    }
  }
}

void DirectAligner::erode_mask(std::uint8_t* mask) {
  const int w = levels_[0].w, h = levels_[0].h;
  // Erode (a pixel stays valid only if its 4-neighbours are), in place:
  // bit 0 keeps each pixel's sampled value for the neighbours still to come,
  // bit 1 collects the result, shifted down at the end.
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * w + x;
      const bool inside = x > 0 && y > 0 && x + 1 < w && y + 1 < h;
      const bool keep = inside && (mask[i] & 1) && (mask[i - 1] & 1) && (mask[i + 1] & 1) && (mask[i - w] & 1) &&
                        (mask[i + w] & 1);
      mask[i] = static_cast<std::uint8_t>((mask[i] & 1) | (keep ? 2 : 0));
    }
  for (int i = 0; i < w * h; ++i) mask[i] = mask[i] >> 1;
}

// A level from the one below it, half the size: 2x2 means, valid where all four are.
void DirectAligner::build_half(Level* half, const Level& full, bool reference) {
  const float* src = reference ? full.ref.data() : full.cur;
  const std::uint8_t* src_mask = reference ? full.ref_mask.data() : full.cur_mask;
  float* dst = reference ? half->ref.data() : half->cur;
  std::uint8_t* dst_mask = reference ? half->ref_mask.data() : half->cur_mask;
  for (int y = 0; y < half->h; ++y)
    for (int x = 0; x < half->w; ++x) {
      const std::size_t a = static_cast<std::size_t>(2 * y) * full.w + 2 * x, b = a + full.w;
      const std::size_t o = static_cast<std::size_t>(y) * half->w + x;
      dst[o] = 0.25f * (src[a] + src[a + 1] + src[b] + src[b + 1]);
      dst_mask[o] = src_mask[a] & src_mask[a + 1] & src_mask[b] & src_mask[b + 1];
    }
}

// Subtracts the mean of the surrounding (2 kHighPassRadius + 1)^2 box
// (clamped at the border) from every pixel of the reference or current
// image: the light rides on the scope, so the shading of the organ changes
// as the scope moves, while the texture moves with the surface; only the
// texture should pull the alignment.
void DirectAligner::high_pass(Level* l, bool reference) {
  float* img = reference ? l->ref.data() : l->cur;
  const int w = l->w, h = l->h, r = kHighPassRadius;
  // Horizontal then vertical box sums through the scratch plane. Away from
  // the border the taps need no clamping; the sums keep the same order
  // there, so both forms give the same bits.
  const int x_in = std::min(r, w), x_out = std::max(x_in, w - r);  // [x_in, x_out): no tap clamps
  for (int y = 0; y < h; ++y) {
    const float* row = img + static_cast<std::ptrdiff_t>(y) * w;
    float* out = l->tmp + static_cast<std::ptrdiff_t>(y) * w;
    const auto clamped_sum = [&](int x) {
      float s = 0.f;
      for (int k = -r; k <= r; ++k) s += row[std::clamp(x + k, 0, w - 1)];
      return s;
    };
    int x = 0;
    for (; x < x_in; ++x) out[x] = clamped_sum(x);
    for (; x < x_out; ++x) {
      float s = 0.f;
      for (int k = -r; k <= r; ++k) s += row[x + k];
      out[x] = s;
    }
    for (; x < w; ++x) out[x] = clamped_sum(x);
  }
  const float inv = 1.f / static_cast<float>((2 * r + 1) * (2 * r + 1));
  for (int y = 0; y < h; ++y) {
    const float* taps[2 * kHighPassRadius + 1];
    for (int k = -r; k <= r; ++k) taps[k + r] = l->tmp + static_cast<std::ptrdiff_t>(std::clamp(y + k, 0, h - 1)) * w;
    float* out = l->gx + static_cast<std::ptrdiff_t>(y) * w;  // gx as a second scratch plane
    for (int x = 0; x < w; ++x) {
      float s = 0.f;
      for (int k = 0; k <= 2 * r; ++k) s += taps[k][x];
      out[x] = s * inv;
    }
  }
  const std::size_t n = static_cast<std::size_t>(w) * static_cast<std::size_t>(h);
  for (std::size_t i = 0; i < n; ++i) img[i] -= l->gx[i];
}

// Central differences of the current image (0 on the border).
void DirectAligner::gradients(Level* l) {
  const int w = l->w, h = l->h;
  const std::size_t n = static_cast<std::size_t>(w) * static_cast<std::size_t>(h);
  std::fill(l->gx, l->gx + n, 0.f);
  std::fill(l->gy, l->gy + n, 0.f);
  for (int y = 1; y + 1 < h; ++y)
    for (int x = 1; x + 1 < w; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * w + x;
      l->gx[i] = 0.5f * (l->cur[i + 1] - l->cur[i - 1]);
      l->gy[i] = 0.5f * (l->cur[i + w] - l->cur[i - w]);
    }
}

void DirectAligner::keep_reference(GrayView image, GrayView valid, const SE3& T_camera_model) {
  have_reference_ = false;
  const Level& l0 = levels_[0];
  if (!configured_ || image.width != l0.w || image.height != l0.h || !T_camera_model.all_finite() ||
      static_cast<std::size_t>(valid.width) * static_cast<std::size_t>(valid.height) > max_valid_pixels_)
    return;
  // A copy and the mask's sampling only (this runs on every tracked
  // frame); the levels are built when align() needs them, which most
  // references never are.
  for (int y = 0; y < l0.h; ++y)
    std::copy_n(image.row(y), l0.w, ref_image_.data() + static_cast<std::ptrdiff_t>(y) * l0.w);
  sample_mask(valid, ref_valid_.data());
  T_reference_ = T_camera_model;
  have_reference_ = true;
  reference_built_ = false;
}

// The reference's levels from its copies; false if none of it is valid.
bool DirectAligner::build_reference() {
  Level& l0 = levels_[0];
  std::copy(ref_valid_.begin(), ref_valid_.end(), l0.ref_mask.begin());
  erode_mask(l0.ref_mask.data());
  // Intensities are kept relative to the reference's mean over its valid
  // pixels (the current image gets the same factor, so a brightness change
  // stays visible to the gain parameter).
  std::int64_t sum = 0;
  std::int64_t n = 0;
  for (std::size_t i = 0; i < ref_image_.size(); ++i) {
    sum += l0.ref_mask[i] ? ref_image_[i] : 0;
    n += l0.ref_mask[i];
  }
  if (n == 0 || sum == 0) return false;
  inv_scale_ = static_cast<float>(static_cast<double>(n) / static_cast<double>(sum));
  for (std::size_t i = 0; i < ref_image_.size(); ++i) l0.ref[i] = static_cast<float>(ref_image_[i]) * inv_scale_;
  for (int li = 1; li < levels_used_; ++li) build_half(&levels_[li], levels_[li - 1], true);
  for (int li = 0; li < levels_used_; ++li) high_pass(&levels_[li], true);
  reference_built_ = true;
  return true;
}

// Reference points of level l: per cell (as small as kMaxPoints allows)
// the valid pixel with the largest gradient (above a floor),
// back-projected with the render's depth. Returns how many.
int DirectAligner::select_points(const Level& l, const MeshRasterizer& raster, const CameraModel& camera) {
  const int w = l.w, h = l.h;
  int cell = 1;  // the finest grid whose cells fit kMaxPoints
  while (((w - 2 + cell - 1) / cell) * ((h - 2 + cell - 1) / cell) > kMaxPoints) ++cell;
  const Pinhole& K = camera.pinhole();
  const bool distorted = !camera.distortion().is_zero();
  const SE3 T_model_camera = T_reference_.inverse();
  const double offset = 0.5 * (l.scale - 1);
  constexpr float kMinGradient = 0.004f;  // relative to the mean intensity (images are normalised)
  int n = 0;
  for (int by = 1; by + 1 < h && n < kMaxPoints; by += cell)
    for (int bx = 1; bx + 1 < w && n < kMaxPoints; bx += cell) {
      float best = kMinGradient;
      int best_x = -1, best_y = -1;
      for (int y = by; y < std::min(by + cell, h - 1); ++y)
        for (int x = bx; x < std::min(bx + cell, w - 1); ++x) {
          const std::size_t i = static_cast<std::size_t>(y) * w + x;
          if (!l.ref_mask[i]) continue;
          const float g = std::abs(l.ref[i + 1] - l.ref[i - 1]) + std::abs(l.ref[i + w] - l.ref[i - w]);
          if (g > best) {
            best = g;
            best_x = x;
            best_y = y;
          }
        }
      if (best_x < 0) continue;
      const Vec2 px(l.scale * best_x + offset, l.scale * best_y + offset);
      Vec2 ideal = px;
      if (distorted && !camera.undistort_pixel(px, &ideal)) continue;
      float depth = 0.f;
      if (!raster.depth_at(raster.full_to_raster(ideal), &depth) || !(depth > 0.f)) continue;
      p_model_[static_cast<std::size_t>(n)] = T_model_camera * K.unproject(ideal, depth);
      intensity_[static_cast<std::size_t>(n)] = l.ref[static_cast<std::size_t>(best_y) * w + best_x];
      ++n;
    }
  return n;
}

// Levenberg-Marquardt on (camera motion, gain a, offset b) over the n
// selected points of level l: residual I_cur(project(T p)) - (a I_ref + b),
// Huber-weighted at a robust scale taken from the starting residuals.
bool DirectAligner::solve_level(const Level& l, int n, const CameraModel& camera, SE3* T, double* a, double* b,
                                DirectAlignSummary* s) {
  const Pinhole& K = camera.pinhole();
  const bool distorted = !camera.distortion().is_zero();
  const double offset = 0.5 * (l.scale - 1), inv_scale = 1.0 / l.scale;
  const int w = l.w, h = l.h;
  // Projects point i at pose Tp: small-image position, or false if it left
  // the usable image.
  const auto project = [&](const SE3& Tp, int i, Vec3* pc, double* sx, double* sy) {
    *pc = Tp * p_model_[static_cast<std::size_t>(i)];
    if (!(pc->z() > 1.0)) return false;
    Vec2 px = K.project(*pc);
    if (distorted) px = camera.distort_pixel(px);
    *sx = (px.x() - offset) * inv_scale;
    *sy = (px.y() - offset) * inv_scale;
    if (!(*sx >= 0.0 && *sy >= 0.0 && *sx < w - 1 && *sy < h - 1)) return false;
    const int xi = static_cast<int>(*sx + 0.5), yi = static_cast<int>(*sy + 0.5);
    return l.cur_mask[static_cast<std::size_t>(yi) * w + xi] != 0;
  };
  // Point i's residual at pose Tp, gain ap, offset bp (false if it left the
  // usable image); its camera point and image position for the Jacobian.
  const auto residual = [&](const SE3& Tp, double ap, double bp, int i, double* r, Vec3* pc, double* sx,
                            double* sy) {
    if (!project(Tp, i, pc, sx, sy)) return false;
    *r = bilinear(l.cur, w, *sx, *sy) - (ap * intensity_[static_cast<std::size_t>(i)] + bp);
    return true;
  };
  // Median |residual| over the points in view at (Tp, ap, bp) into
  // *median; returns how many points were in view (0: *median untouched).
  const auto median_abs_residual = [&](const SE3& Tp, double ap, double bp, double* median) {
    int m = 0;
    for (int i = 0; i < n; ++i) {
      Vec3 pc;
      double r, sx, sy;
      if (residual(Tp, ap, bp, i, &r, &pc, &sx, &sy)) residuals_[static_cast<std::size_t>(m++)] = std::abs(r);
    }
    if (m > 0) {
      std::nth_element(residuals_.begin(), residuals_.begin() + m / 2, residuals_.begin() + m);
      *median = residuals_[static_cast<std::size_t>(m / 2)];
    }
    return m;
  };
  // Robust scale: median absolute residual at the start (MAD * 1.4826).
  double start_median = 0;
  if (median_abs_residual(*T, *a, *b, &start_median) < 20) return false;
  const double sigma = std::max(1.4826 * start_median, 1e-3);
  const double k = kHuber * sigma;
  const double out_cost = huber_cost(kOutCostSigmas * sigma, k);
  const auto cost_at = [&](const SE3& Tp, double ap, double bp, int* used) {
    double c = 0;
    *used = 0;
    for (int i = 0; i < n; ++i) {
      Vec3 pc;
      double r, sx, sy;
      if (!residual(Tp, ap, bp, i, &r, &pc, &sx, &sy)) {
        c += out_cost;
        continue;
      }
      c += huber_cost(r, k);
      ++*used;
    }
    return c;
  };
  int used = 0;
  double cost = cost_at(*T, *a, *b, &used);
  double lambda = 1e-3;
  // Converged when a step moves the points by less than kConvergedPx of
  // this level's pixels: rotation and translation (at the points' mean
  // depth) turned into image motion through the level's focal length.
  double z_sum = 0;
  int z_n = 0;
  for (int i = 0; i < n; ++i) {
    const double z = (*T * p_model_[static_cast<std::size_t>(i)]).z();
    if (z > 1.0) {
      z_sum += z;
      ++z_n;
    }
  }
  const double f_level = K.fx * inv_scale, inv_z = z_n > 0 ? z_n / z_sum : 0.0;
  Mat8 H_last = Mat8::Zero();
  for (int it = 0; it < kMaxIterations; ++it) {
    ++s->iterations;
    Mat8 H = Mat8::Zero();
    Vec8 g = Vec8::Zero();
    for (int i = 0; i < n; ++i) {
      Vec3 pc;
      double r, sx, sy;
      if (!residual(*T, *a, *b, i, &r, &pc, &sx, &sy)) continue;
      const double gx = bilinear(l.gx, w, sx, sy), gy = bilinear(l.gy, w, sx, sy);
      const double iz = 1.0 / pc.z();
      // d(small position)/d(camera point), distortion's own Jacobian left out.
      const double du = gx * K.fx * iz * inv_scale, dv = gy * K.fy * iz * inv_scale;
      const Vec3 dI(du, dv, -(du * pc.x() + dv * pc.y()) * iz);  // dI/dX
      Vec8 J;
      J.head<3>() = pc.cross(dI);  // dX/domega = -[X]x, so dI/domega = X x dI
      J.segment<3>(3) = dI;
      J(6) = -intensity_[static_cast<std::size_t>(i)];
      J(7) = -1.0;
      const double wgt = std::abs(r) <= k ? 1.0 : k / std::abs(r);
      // H += wgt J J^T, the lower half (all LDLT reads), written out:
      // Eigen's rankUpdate is a call per sample with a run-time size.
      for (int c = 0; c < 8; ++c) {
        const double t = wgt * J(c);
        for (int q = c; q < 8; ++q) H(q, c) += t * J(q);
      }
      g.noalias() += wgt * r * J;
    }
    H_last = H.selfadjointView<Eigen::Lower>();
    bool improved = false;
    for (int attempt = 0; attempt < 6 && !improved; ++attempt) {
      Mat8 A = H;
      A.diagonal() += lambda * H.diagonal().cwiseMax(1e-9);
      const Vec8 delta = A.ldlt().solve(-g);
      if (!delta.allFinite()) return false;
      const SE3 T_try = SE3::exp(delta.head<6>()) * *T;
      const double a_try = *a + delta(6), b_try = *b + delta(7);
      int used_try = 0;
      const double c_try = cost_at(T_try, a_try, b_try, &used_try);
      if (c_try < cost) {
        const bool converged =
            f_level * (delta.head<3>().norm() + delta.segment<3>(3).norm() * inv_z) < kConvergedPx;
        *T = T_try;
        *a = a_try;
        *b = b_try;
        cost = c_try;
        used = used_try;
        lambda = std::max(lambda / 4.0, 1e-7);
        improved = true;
        if (converged) it = kMaxIterations;
      } else {
        lambda *= 8.0;
      }
    }
    if (!improved) break;
  }
  s->used = used;
  // The pose's information: the brightness parameters eliminated (Schur
  // complement), whitened by the robust scale.
  const Eigen::Matrix2d C = H_last.bottomRightCorner<2, 2>();
  if (std::abs(C.determinant()) > 1e-12) {
    const Eigen::Matrix<double, 6, 2> B = H_last.topRightCorner<6, 2>();
    s->information = (H_last.topLeftCorner<6, 6>() - B * C.inverse() * B.transpose()) / (sigma * sigma);
  } else {
    s->information = Mat6::Zero();
  }
  // The fit at the end: the median absolute residual of the points still
  // in view (comparable between starts on the same reference and image).
  median_abs_residual(*T, *a, *b, &s->residual_median);
  return true;
}

bool DirectAligner::align(GrayView image, GrayView valid, const MeshRasterizer& raster,
                          const CameraModel& camera, SE3* T_camera_model,
                          DirectAlignSummary* summary, bool allow_coarser) {
  DirectAlignSummary s;
  if (summary) *summary = s;
  Level& l0 = levels_[0];
  if (!configured_ || !have_reference_ || image.width != l0.w || image.height != l0.h ||
      !T_camera_model->all_finite())
    return false;
  if (!reference_built_ && !build_reference()) {
    have_reference_ = false;
    return false;
  }
  sample_valid(valid, l0.cur_mask);
  for (int y = 0; y < l0.h; ++y) {
    const std::uint8_t* row = image.row(y);
    float* out = l0.cur + static_cast<std::ptrdiff_t>(y) * l0.w;
    for (int x = 0; x < l0.w; ++x) out[x] = static_cast<float>(row[x]) * inv_scale_;
  }
  for (int li = 1; li < levels_used_; ++li) build_half(&levels_[li], levels_[li - 1], false);
  for (int li = 0; li < levels_used_; ++li) high_pass(&levels_[li], false);
  SE3 T = *T_camera_model;
  double a = 1.0, b = 0.0;
  bool ok = true;
  // The estimate of the finest level so far that passed the checks: most
  // of the organ seen in the reference still in view, and a contrast gain
  // in range (a contrast that collapsed, or blew up, explains any image:
  // the points then sit on flat tissue or off the organ, not on their
  // texture). Without allow_coarser only the finest level's counts.
  bool have_passed = false;
  SE3 T_passed;
  DirectAlignSummary s_passed;
  for (int li = levels_used_ - 1; li >= 0 && ok; --li) {
    Level& l = levels_[li];
    gradients(&l);
    s.points = select_points(l, raster, camera);
    ok = s.points >= kMinPoints && solve_level(l, s.points, camera, &T, &a, &b, &s);
    s.gain = a;
    s.level = li;
    const bool passed = ok && s.used >= kMinPoints && 2 * s.used >= s.points && T.all_finite() &&
                        a >= kMinGain && a <= kMaxGain;
    if (passed && (li == 0 || allow_coarser)) {
      have_passed = true;
      T_passed = T;
      s_passed = s;
    }
  }
  if (summary) *summary = have_passed ? s_passed : s;
  if (!have_passed) return false;
  *T_camera_model = T_passed;
  return true;
}

}  // namespace st
