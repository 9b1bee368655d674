#include "core/motion/image_motion.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

namespace st {

namespace {
constexpr int kSearch = 12;      // coarse search window around the guess, small-image pixels (~96 level-0 px)
constexpr int kIterations = 15;  // Gauss-Newton iterations
constexpr double kRollStep = 1.5 * M_PI / 180.0;  // coarse roll search: guess +- kRollSteps steps
constexpr int kRollSteps = 4;
constexpr int kRollIterations = 8;  // Gauss-Newton iterations on (shift, roll)
constexpr double kMaxRoll = 0.5;  // rad; a frame-to-frame roll beyond this is no estimate
}  // namespace

Status ImageMotion::configure(int width, int height) {
  if (width < 16 * kShrink || height < 16 * kShrink) return make_error("ImageMotion: frame smaller than 128x128");
  w_ = width / kShrink;
  h_ = height / kShrink;
  const auto n = static_cast<std::size_t>(w_) * static_cast<std::size_t>(h_);
  prev_.assign(n, 0.f);
  cur_.assign(n, 0.f);
  scratch_.assign(n, 0.f);
  column_sums_.assign(static_cast<std::size_t>(w_ * kShrink), 0);
  prev_mask_.assign(n, 0);
  cur_mask_.assign(n, 0);
  have_previous_ = false;
  return Status::Ok();
}

// Block means (every other row of each 8x8 block: the blur hides the
// difference, the cost halves), a 3x3 box blur, and a mask eroded by one
// small pixel so the dark field-stop edge (which does not move with the
// scene) stays out of the alignment.
void ImageMotion::shrink(GrayView luma, GrayView valid, float* image, std::uint8_t* mask) {
  const auto at = [this](int x, int y) { return static_cast<std::size_t>(y) * static_cast<std::size_t>(w_) + static_cast<std::size_t>(x); };
  for (int sy = 0; sy < h_; ++sy) {
    // Column sums of the block's rows first (a plain widening add the
    // compiler vectorises), then kShrink columns per small pixel.
    std::uint16_t* col = column_sums_.data();
    const int n = w_ * kShrink;
    std::fill(col, col + n, std::uint16_t{0});
    for (int r = 0; r < kShrink; r += 2) {
      const std::uint8_t* row = luma.row(sy * kShrink + r);
      for (int x = 0; x < n; ++x) col[x] = static_cast<std::uint16_t>(col[x] + row[x]);
    }
    float* out = scratch_.data() + at(0, sy);
    for (int sx = 0; sx < w_; ++sx) {
      int s = 0;
      for (int k = 0; k < kShrink; ++k) s += col[sx * kShrink + k];
      out[sx] = static_cast<float>(s);
    }
    // The valid mask may be coarser than the frame (ValidMaskBuilder works
    // at 1/downscale): sample it at the block centre in its own pixels.
    for (int sx = 0; sx < w_; ++sx) {
      if (valid.empty()) {
        mask[at(sx, sy)] = 1;
        continue;
      }
      const int cx = sx * kShrink + kShrink / 2, cy = sy * kShrink + kShrink / 2;
      const int vx = std::min(cx * valid.width / luma.width, valid.width - 1);
      const int vy = std::min(cy * valid.height / luma.height, valid.height - 1);
      mask[at(sx, sy)] = valid(vx, vy) != 0 ? 1 : 0;
    }
  }
  for (int sy = 0; sy < h_; ++sy)
    for (int sx = 0; sx < w_; ++sx) {
      float s = 0.f;
      int n = 0;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int x = sx + dx, y = sy + dy;
          if (x < 0 || y < 0 || x >= w_ || y >= h_) continue;
          s += scratch_[at(x, y)];
          ++n;
        }
      image[at(sx, sy)] = s / static_cast<float>(n * kShrink * kShrink / 2);
    }
  // Erode: valid only with all 4 neighbours valid (inside the image).
  for (int sy = 0; sy < h_; ++sy)
    for (int sx = 0; sx < w_; ++sx) {
      const bool inner = sx > 0 && sy > 0 && sx < w_ - 1 && sy < h_ - 1;
      scratch_[at(sx, sy)] = inner && mask[at(sx, sy)] && mask[at(sx - 1, sy)] && mask[at(sx + 1, sy)] &&
                                     mask[at(sx, sy - 1)] && mask[at(sx, sy + 1)]
                                 ? 1.f
                                 : 0.f;
    }
  for (std::size_t i = 0; i < prev_mask_.size(); ++i) mask[i] = scratch_[i] > 0.f ? 1 : 0;
}

// Mean squared difference at an integer shift over every stride-th pixel
// in x and y (the x range that stays inside both images is found once per
// shift, so the inner loop only tests the masks).
double ImageMotion::ssd_at(int dx, int dy, int stride, int* n) const {
  double s = 0;
  int count = 0;
  int x_lo = std::max(0, -dx);
  x_lo = (x_lo + stride - 1) / stride * stride;  // on the stride grid, as the sampling is
  const int x_hi = std::min(w_, w_ - dx);
  for (int y = 0; y < h_; y += stride) {
    const int yc = y + dy;
    if (yc < 0 || yc >= h_) continue;
    const std::size_t ip = static_cast<std::size_t>(y * w_), ic = static_cast<std::size_t>(yc * w_ + dx);
    const float* p = prev_.data() + ip;
    const float* c = cur_.data() + ic;
    const std::uint8_t* pm = prev_mask_.data() + ip;
    const std::uint8_t* cm = cur_mask_.data() + ic;
    float row_sum = 0.f;
    for (int x = x_lo; x < x_hi; x += stride) {
      const bool both = (pm[x] & cm[x]) != 0;
      const float d = c[x] - p[x];
      row_sum += both ? d * d : 0.f;
      count += both ? 1 : 0;
    }
    s += static_cast<double>(row_sum);
  }
  *n = count;
  return count > 0 ? s / count : 1e30;
}

// The integer shift of least SSD in [c - radius, c + radius]^2 (every
// step-th), over pixels sampled every stride; 1e30 when no shift overlaps
// enough valid pixels.
double ImageMotion::search(int cx, int cy, int radius, int step, int stride, Vec2* t) const {
  const int needed = (w_ * h_) / (4 * stride * stride);
  double best = 1e30;
  for (int dy = cy - radius; dy <= cy + radius; dy += step)
    for (int dx = cx - radius; dx <= cx + radius; dx += step) {
      int n = 0;
      const double s = ssd_at(dx, dy, stride, &n);
      if (n >= needed && s < best) {
        best = s;
        *t = Vec2(dx, dy);
      }
    }
  return best;
}

// Gauss-Newton on the translation t (small-image pixels) with the mean of
// both images' gradients (ESM): converges from a few pixels off. Within one
// iteration every pixel moves by the same t, so the bilinear weights and
// the integer offset into the current image are the same for all of them.
bool ImageMotion::refine_shift(Vec2* t) const {
  const int needed = (w_ * h_) / 4;
  const std::ptrdiff_t w = w_;
  double last_step = 1e9;
  for (int it = 0; it < kIterations; ++it) {
    const int ix = static_cast<int>(std::floor(t->x())), iy = static_cast<int>(std::floor(t->y()));
    const float fx = static_cast<float>(t->x() - ix), fy = static_cast<float>(t->y() - iy);
    // The mask is tested at the nearest pixel of the shifted position.
    const std::ptrdiff_t mask_offset = (fy >= 0.5f ? iy + 1 : iy) * w + (fx >= 0.5f ? ix + 1 : ix);
    const float w00 = (1.f - fx) * (1.f - fy), w01 = fx * (1.f - fy), w10 = (1.f - fx) * fy, w11 = fx * fy;
    // Rows and columns whose shifted position and its +1 neighbour are inside.
    const int y_lo = std::max(1, -iy), y_hi = std::min(h_ - 1, h_ - 1 - iy);
    const int x_lo = std::max(1, -ix), x_hi = std::min(w_ - 1, w_ - 1 - ix);
    double h00 = 0, h01 = 0, h11 = 0, g0 = 0, g1 = 0;
    int n = 0;
    for (int y = y_lo; y < y_hi; ++y) {
      const std::ptrdiff_t row = y * w;
      const std::ptrdiff_t shifted = (y + iy) * w + ix;
      for (int x = x_lo; x < x_hi; ++x) {
        const std::ptrdiff_t ip = row + x;
        if (!prev_mask_[static_cast<std::size_t>(ip)] || !cur_mask_[static_cast<std::size_t>(ip + mask_offset)]) continue;
        const float* r0 = cur_.data() + shifted + x;
        const float* r1 = r0 + w;
        const float c = w00 * r0[0] + w01 * r0[1] + w10 * r1[0] + w11 * r1[1];
        const float cgx = (1.f - fy) * (r0[1] - r0[0]) + fy * (r1[1] - r1[0]);
        const float cgy = (1.f - fx) * (r1[0] - r0[0]) + fx * (r1[1] - r0[1]);
        const float* p = prev_.data() + ip;
        const double jx = static_cast<double>(0.25f * (p[1] - p[-1]) + 0.5f * cgx);
        const double jy = static_cast<double>(0.25f * (p[w] - p[-w]) + 0.5f * cgy);
        const double r = static_cast<double>(c - p[0]);
        h00 += jx * jx;
        h01 += jx * jy;
        h11 += jy * jy;
        g0 += jx * r;
        g1 += jy * r;
        ++n;
      }
    }
    const double det = h00 * h11 - h01 * h01;
    if (n < needed || !(det > 1e-9 * (h00 + h11) * (h00 + h11))) return false;
    // r(t + d) ~ r + J d = 0 -> d = -H^-1 g.
    const Vec2 d(-(h11 * g0 - h01 * g1) / det, -(h00 * g1 - h01 * g0) / det);
    *t += d;
    if (!t->allFinite() || t->norm() > w_) return false;
    if (d.norm() < 0.02) return true;
    last_step = d.norm();
  }
  return last_step < 0.1;  // slow final steps (a blurred frame): close enough
}

// Mean squared difference with the current image warped by (t, roll)
// about centre (small-image pixels), nearest-neighbour, over every
// stride-th pixel; 1e30 when too few valid pixels overlap. Compares rolls
// at one translation (the coarse roll search).
double ImageMotion::ssd_rolled(const Vec2& t, double roll, const Vec2& centre, int stride) const {
  const int needed = (w_ * h_) / (4 * stride * stride);
  const float c = static_cast<float>(std::cos(roll)), s = static_cast<float>(std::sin(roll));
  const float ox = static_cast<float>(centre.x() + t.x()) + 0.5f, oy = static_cast<float>(centre.y() + t.y()) + 0.5f;
  const float cx = static_cast<float>(centre.x()), cy = static_cast<float>(centre.y());
  double sum = 0;
  int n = 0;
  for (int y = 0; y < h_; y += stride) {
    const float py = static_cast<float>(y) - cy;
    float row_sum = 0.f;
    for (int x = 0; x < w_; x += stride) {
      const std::size_t ip = static_cast<std::size_t>(y * w_ + x);
      if (!prev_mask_[ip]) continue;
      const float px = static_cast<float>(x) - cx;
      const int qx = static_cast<int>(std::floor(ox + c * px - s * py));
      const int qy = static_cast<int>(std::floor(oy + s * px + c * py));
      if (qx < 0 || qy < 0 || qx >= w_ || qy >= h_) continue;
      const std::size_t iq = static_cast<std::size_t>(qy * w_ + qx);
      if (!cur_mask_[iq]) continue;
      const float d = cur_[iq] - prev_[ip];
      row_sum += d * d;
      ++n;
    }
    sum += static_cast<double>(row_sum);
  }
  return n >= needed ? sum / n : 1e30;
}

// Gauss-Newton on the shift t and the roll about centre (small-image
// pixels, radians) with the mean of both images' gradients (ESM; the
// previous image's gradient turned by the roll), on every second pixel in
// x and y (each pixel has its own bilinear weights here): converges from a
// few pixels off, and starts close (shift refined, roll searched).
bool ImageMotion::refine_roll(const Vec2& centre, Vec2* t, double* roll) const {
  const int needed = (w_ * h_) / 16;
  const std::ptrdiff_t w = w_;
  const float cx = static_cast<float>(centre.x()), cy = static_cast<float>(centre.y());
  // A roll step moves the farthest pixel by step * reach: the convergence
  // test is in pixels for both parameters.
  const double reach = 0.5 * std::hypot(static_cast<double>(w_), static_cast<double>(h_));
  double last_step = 1e9;
  for (int it = 0; it < kRollIterations; ++it) {
    const float c = static_cast<float>(std::cos(*roll)), s = static_cast<float>(std::sin(*roll));
    const float ox = cx + static_cast<float>(t->x()), oy = cy + static_cast<float>(t->y());
    Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
    Eigen::Vector3d g = Eigen::Vector3d::Zero();
    int n = 0;
    for (int y = 1; y < h_ - 1; y += 2) {
      const float py = static_cast<float>(y) - cy;
      // Per row: sums in float over one row, then into the double totals.
      float a00 = 0, a01 = 0, a02 = 0, a11 = 0, a12 = 0, a22 = 0, b0 = 0, b1 = 0, b2 = 0;
      for (int x = 1; x < w_ - 1; x += 2) {
        const std::ptrdiff_t ip = y * w + x;
        if (!prev_mask_[static_cast<std::size_t>(ip)]) continue;
        const float px = static_cast<float>(x) - cx;
        const float rx = c * px - s * py, ry = s * px + c * py;  // the offset from the centre, turned
        const float qx = ox + rx, qy = oy + ry;
        const float fqx = std::floor(qx), fqy = std::floor(qy);
        const int ix = static_cast<int>(fqx), iy = static_cast<int>(fqy);
        if (ix < 0 || iy < 0 || ix >= w_ - 1 || iy >= h_ - 1) continue;
        const float fx = qx - fqx, fy = qy - fqy;
        // The mask is tested at the nearest pixel of the warped position.
        const std::ptrdiff_t im = (fy >= 0.5f ? iy + 1 : iy) * w + (fx >= 0.5f ? ix + 1 : ix);
        if (!cur_mask_[static_cast<std::size_t>(im)]) continue;
        const float* r0 = cur_.data() + iy * w + ix;
        const float* r1 = r0 + w;
        const float cv = (1.f - fy) * ((1.f - fx) * r0[0] + fx * r0[1]) + fy * ((1.f - fx) * r1[0] + fx * r1[1]);
        const float cgx = (1.f - fy) * (r0[1] - r0[0]) + fy * (r1[1] - r1[0]);
        const float cgy = (1.f - fx) * (r1[0] - r0[0]) + fx * (r1[1] - r0[1]);
        const float* p = prev_.data() + ip;
        const float pgx = 0.5f * (p[1] - p[-1]), pgy = 0.5f * (p[w] - p[-w]);
        const float jx = 0.5f * (c * pgx - s * pgy + cgx);
        const float jy = 0.5f * (s * pgx + c * pgy + cgy);
        const float jr = jy * rx - jx * ry;  // d(position)/d(roll) = (-ry, rx)
        const float r = cv - p[0];
        a00 += jx * jx; a01 += jx * jy; a02 += jx * jr;
        a11 += jy * jy; a12 += jy * jr; a22 += jr * jr;
        b0 += jx * r; b1 += jy * r; b2 += jr * r;
        ++n;
      }
      const auto d = [](float v) { return static_cast<double>(v); };
      H(0, 0) += d(a00); H(0, 1) += d(a01); H(0, 2) += d(a02);
      H(1, 1) += d(a11); H(1, 2) += d(a12); H(2, 2) += d(a22);
      g(0) += d(b0); g(1) += d(b1); g(2) += d(b2);
    }
    if (n < needed) return false;
    H(1, 0) = H(0, 1); H(2, 0) = H(0, 2); H(2, 1) = H(1, 2);
    // The roll column in pixels of reach, so that the conditioning test
    // compares like with like.
    const Eigen::Vector3d unit(1.0, 1.0, 1.0 / reach);
    const Eigen::Matrix3d Hs = unit.asDiagonal() * H * unit.asDiagonal();
    const Eigen::LDLT<Eigen::Matrix3d> ldlt(Hs);
    const Eigen::Vector3d pivots = ldlt.vectorD();
    if (ldlt.info() != Eigen::Success || !(pivots.minCoeff() > 1e-6 * pivots.maxCoeff())) return false;
    // r(p + d) ~ r + J d = 0 -> d = -H^-1 g (solved in the scaled unknowns).
    const Eigen::Vector3d d = unit.asDiagonal() * ldlt.solve(-(unit.asDiagonal() * g));
    *t += d.head<2>();
    *roll += d(2);
    if (!t->allFinite() || !std::isfinite(*roll) || t->norm() > w_ || std::abs(*roll) > kMaxRoll) return false;
    const double step = d.head<2>().norm() + std::abs(d(2)) * reach;
    if (step < 0.02) return true;
    last_step = step;
  }
  return last_step < 0.1;  // slow final steps (a blurred frame): close enough
}

bool ImageMotion::update(GrayView luma, GrayView valid, const Vec2& centre_px, const ViewMotion& guess,
                         ViewMotion* motion) {
  if (luma.width / kShrink != w_ || luma.height / kShrink != h_ || w_ == 0) return false;
  shrink(luma, valid, cur_.data(), cur_mask_.data());
  bool ok = false;
  if (have_previous_ && guess.shift_px.allFinite() && std::isfinite(guess.roll_rad) && centre_px.allFinite()) {
    const int gx = static_cast<int>(std::lround(std::clamp(guess.shift_px.x() / kShrink, -1.0 * w_, 1.0 * w_)));
    const int gy = static_cast<int>(std::lround(std::clamp(guess.shift_px.y() / kShrink, -1.0 * h_, 1.0 * h_)));
    // Small pixel s covers level-0 pixels [8 s, 8 s + 7]: its centre is at 8 s + 3.5.
    const Vec2 centre = (centre_px - Vec2::Constant(0.5 * (kShrink - 1))) / static_cast<double>(kShrink);
    // Coarse: every second shift on a sparse pixel set; fine: the 3x3
    // shifts around the coarse best on a denser one; Gauss-Newton on the
    // shift (the shift of the centre hardly depends on the roll).
    Vec2 t(gx, gy);
    double best = search(gx, gy, kSearch, 2, 4, &t);
    if (best < 1e30) best = search(static_cast<int>(t.x()), static_cast<int>(t.y()), 1, 1, 2, &t);
    // A shift refinement that fails (under a large roll, say) keeps the
    // search's integer shift and lets the roll refinement decide.
    const Vec2 t_search = t;
    const bool shift_ok = best < 1e30 && refine_shift(&t);
    if (!shift_ok) t = t_search;
    // The roll: from the guess in steps while the next step is better (at
    // most kRollSteps each way); only if that moved it, Gauss-Newton on
    // shift and roll. A roll within half a step of the guess is reported
    // as the guess: whole-image alignment cannot tell a fraction of a
    // degree of roll from parallax (near organ, far abdominal wall).
    double roll = guess.roll_rad;
    ok = shift_ok;
    if (best < 1e30) {
      double e0 = ssd_rolled(t, roll, centre, 2);
      for (const double dir : {1.0, -1.0}) {
        int k = 0;
        for (; k < kRollSteps; ++k) {
          const double e = ssd_rolled(t, roll + dir * kRollStep, centre, 2);
          if (!(e < e0)) break;
          e0 = e;
          roll += dir * kRollStep;
        }
        if (k > 0) break;  // went this way: the other way is uphill
      }
      if (roll != guess.roll_rad) ok = refine_roll(centre, &t, &roll);
    }
    if (ok) {
      motion->shift_px = t * static_cast<double>(kShrink);
      motion->roll_rad = roll;
    }
  }
  prev_.swap(cur_);
  prev_mask_.swap(cur_mask_);
  have_previous_ = true;
  return ok;
}

}  // namespace st
