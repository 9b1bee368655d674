#include "core/contour/region_modality.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

namespace st {

namespace {

// P(organ) of a sample is kept within [kMinP, 1 - kMinP]: one sample of a
// colour the models have never seen (or a stray one) cannot veto a split.
constexpr double kMinP = 0.05;
// A line is informative when its best split explains its samples better
// than "all organ" and "all background" by this much (nats): a line that
// never leaves the organ, or sees no difference, measures nothing.
constexpr double kMinSplitGain = 2.0;
// At least this share of a line's samples must be readable (inside the
// image and the valid mask).
constexpr double kMinValidShare = 0.6;
// Huber threshold on the whitened line residual.
constexpr double kHuber = 2.0;
// Lines are placed at least this many raster pixels from the raster's
// border: where the outline meets the image border it is the border's, not
// the organ's.
constexpr int kBorder = 3;

int choose_downscale(int width) {
  if (width / 4 >= 480) return 4;
  if (width / 2 >= 480) return 2;
  return 1;
}

double huber_rho(double e2) {
  const double e = std::sqrt(e2);
  return e <= kHuber ? 0.5 * e2 : kHuber * (e - 0.5 * kHuber);
}

}  // namespace

Status RegionModality::configure(const Mesh& mesh, int width, int height) {
  configured_ = false;
  if (width <= 0 || height <= 0) return make_error("contour: the frame size must be positive");
  RasterConfig rc;
  rc.width = width;
  rc.height = height;
  rc.downscale = choose_downscale(width);
  rc.near_mm = 1.0;
  rc.cull_backfaces = true;
  if (Status s = raster_.configure(mesh, rc); !s.ok()) return make_error("contour: raster: " + s.message());
  width_ = width;
  height_ = height;
  base_step_ = std::max(1.0, std::floor(width / 640.0));
  lines_.assign(kMaxLines, Line{});
  used_.assign(kMaxLines, 0);
  const auto raster_px = static_cast<std::size_t>(width / rc.downscale + 1) * static_cast<std::size_t>(height / rc.downscale + 1);
  silhouette_.assign(raster_px, 0);
  fg_.assign(kBins, 0.f);
  bg_.assign(kBins, 0.f);
  fg_new_.assign(kBins, 0.f);
  bg_new_.assign(kBins, 0.f);
  configured_ = true;
  reset();
  return Status::Ok();
}

void RegionModality::reset() {
  model_ready_ = false;
  placed_ = 0;
  separation_ = 0;
  std::fill(fg_.begin(), fg_.end(), 0.f);
  std::fill(bg_.begin(), bg_.end(), 0.f);
}

// Y at 8 levels; U and V as ratios to the luma above black (16 levels over
// [-0.75, 0.75]; the luma floor of 16 keeps the ratio of near-black
// pixels from being noise). With the chroma's own levels the organ's rim,
// darkened at grazing light, had the grey background's chroma: on the
// smooth orbit (seed 2) the lines measured at the true pose sat 4-10 px
// inside the outline (RMS) once the organ filled the view, and the
// outline's pose slid away with them; with the ratios, 1.0-1.4 px.
double RegionModality::organ_probability(double f, double g) {
  return std::clamp((f + 1e-6) / (f + g + 2e-6), kMinP, 1.0 - kMinP);
}

int RegionModality::colour_bin(GrayView luma, ChromaView chroma, int x, int y) {
  const int Y = luma(x, y) >> 5;
  if (chroma.empty()) return Y * 256 + 8 * 16 + 8;
  const int cx = std::min(x >> 1, chroma.u.width - 1), cy = std::min(y >> 1, chroma.u.height - 1);
  const int s = std::max(static_cast<int>(luma(x, y)) - 16, 16);
  const auto ratio_bin = [s](int c) { return std::clamp((((c - 128) * 64) / s + 48) / 6, 0, 15); };
  return Y * 256 + ratio_bin(chroma.u(cx, cy)) * 16 + ratio_bin(chroma.v(cx, cy));
}

namespace {

std::uint64_t load8(const std::uint8_t* p) {
  std::uint64_t v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

// No byte of v is zero.
bool all_nonzero(std::uint64_t v) {
  constexpr std::uint64_t kLow = 0x0101010101010101ull, kHigh = 0x8080808080808080ull;
  return ((v - kLow) & ~v & kHigh) == 0;
}

// An organ pixel with a non-organ 4-neighbour.
bool on_silhouette(const std::uint8_t* row, const std::uint8_t* up, const std::uint8_t* down, int x) {
  return row[x] && !(row[x - 1] && row[x + 1] && up[x] && down[x]);
}

}  // namespace

// Renders at T and places up to kMaxLines lines, evenly over the
// silhouette's pixels in scan order.
int RegionModality::place_lines(const CameraModel& camera, const SE3& T) {
  placed_ = 0;
  K_ = camera.pinhole();
  raster_.render(T, K_);
  const ImageView<const std::uint8_t> m = raster_.mask();
  const ImageView<const float> depth = raster_.depth();
  int count = 0;
  for (int y = kBorder; y < m.height - kBorder; ++y) {
    const std::uint8_t* row = m.row(y);
    const std::uint8_t* up = m.row(y - 1);
    const std::uint8_t* down = m.row(y + 1);
    int x = kBorder;
    // 8 pixels at a time where none can be on the silhouette: all
    // background, or all organ with organ above, below and on both ends.
    for (; x + 8 < m.width - kBorder; x += 8) {
      const std::uint64_t r = load8(row + x);
      if (r == 0) continue;
      if (all_nonzero(r) && all_nonzero(load8(up + x)) && all_nonzero(load8(down + x)) && row[x - 1] && row[x + 8])
        continue;
      for (int k = x; k < x + 8; ++k)
        if (on_silhouette(row, up, down, k)) silhouette_[static_cast<std::size_t>(count++)] = y * m.width + k;
    }
    for (; x < m.width - kBorder; ++x)
      if (on_silhouette(row, up, down, x)) silhouette_[static_cast<std::size_t>(count++)] = y * m.width + x;
  }
  if (count == 0) return 0;
  const bool distorted = !camera.distortion().is_zero();
  const int want = std::min(count, kMaxLines);
  for (int j = 0; j < want; ++j) {
    const int idx = silhouette_[static_cast<std::size_t>((static_cast<long>(2 * j + 1) * count) / (2 * want))];
    const int x = idx % m.width, y = idx / m.width;
    // Outward normal: minus the first moment of the organ over a 5x5 window.
    double gx = 0, gy = 0;
    for (int dy = -2; dy <= 2; ++dy)
      for (int dx = -2; dx <= 2; ++dx)
        if (m(x + dx, y + dy)) {
          gx += dx;
          gy += dy;
        }
    const double gn = std::hypot(gx, gy);
    const float d = depth(x, y);
    if (gn < 1.0 || !(d > 0.f)) continue;
    const Vec2 n(-gx / gn, -gy / gn);
    Line& l = lines_[static_cast<std::size_t>(placed_)];
    l.p_model = raster_.model_point(Vec2(x + 0.5 * n.x(), y + 0.5 * n.y()), d);
    const Vec3 pc = T * l.p_model;
    if (!(pc.z() > 1.0)) continue;
    l.centre = K_.project(pc);
    l.normal = n;
    if (distorted) {
      l.centre_d = camera.distort_pixel(l.centre);
      const Vec2 dir = camera.distort_pixel(l.centre + n) - l.centre_d;
      l.scale_d = dir.norm();
      if (!(l.scale_d > 1e-6)) continue;
      l.dir_d = dir / l.scale_d;
    } else {
      l.centre_d = l.centre;
      l.dir_d = n;
      l.scale_d = 1.0;
    }
    if (!l.centre_d.allFinite()) continue;
    ++placed_;
  }
  return placed_;
}

void RegionModality::sample_lines(GrayView luma, ChromaView chroma, GrayView valid, double step) {
  last_step_ = step;
  const bool have_valid = !valid.empty();
  const double vsx = have_valid ? static_cast<double>(valid.width) / width_ : 0.0;
  const double vsy = have_valid ? static_cast<double>(valid.height) / height_ : 0.0;
  for (int i = 0; i < placed_; ++i) {
    Line& l = lines_[static_cast<std::size_t>(i)];
    l.valid_bits = 0;
    for (int s = 0; s < kSamples; ++s) {
      const double t = (s - kHalfLength) * step;
      const long x = std::lround(l.centre_d.x() + t * l.dir_d.x());
      const long y = std::lround(l.centre_d.y() + t * l.dir_d.y());
      if (x < 0 || y < 0 || x >= width_ || y >= height_) continue;
      const int xi = static_cast<int>(x), yi = static_cast<int>(y);
      if (have_valid && !valid(std::min(static_cast<int>(xi * vsx), valid.width - 1),
                               std::min(static_cast<int>(yi * vsy), valid.height - 1)))
        continue;
      l.bin[static_cast<std::size_t>(s)] = static_cast<std::uint16_t>(colour_bin(luma, chroma, xi, yi));
      l.valid_bits |= 1u << s;
    }
  }
}

// The outline's posterior position on every line from the colour models.
int RegionModality::measure_lines(double step) {
  int used = 0;
  double sep_sum = 0;
  int sep_n = 0;
  for (int i = 0; i < placed_; ++i) {
    Line& l = lines_[static_cast<std::size_t>(i)];
    used_[static_cast<std::size_t>(i)] = 0;
    std::array<double, kSamples> diff{};  // log P(organ) - log P(background) per sample
    double all_bg = 0;
    int valid = 0;
    for (int s = 0; s < kSamples; ++s) {
      if (!(l.valid_bits & (1u << s))) continue;
      const auto b = static_cast<std::size_t>(l.bin[static_cast<std::size_t>(s)]);
      const double p = organ_probability(fg_[b], bg_[b]);
      sep_sum += std::abs(p - 0.5) * 2.0;
      ++sep_n;
      diff[static_cast<std::size_t>(s)] = std::log(p) - std::log(1.0 - p);
      all_bg += std::log(1.0 - p);
      ++valid;
    }
    if (valid < kMinValidShare * kSamples) continue;
    // Split k: samples 0..k organ, k+1.. background (k = -1: all
    // background, k = kSamples - 1: all organ).
    std::array<double, kSamples - 1> L{};
    double run = all_bg, best = -1e300;
    for (int k = 0; k < kSamples - 1; ++k) {
      run += diff[static_cast<std::size_t>(k)];
      L[static_cast<std::size_t>(k)] = run;
      best = std::max(best, run);
    }
    const double all_fg = run + diff[kSamples - 1];
    if (best - std::max(all_bg, all_fg) < kMinSplitGain) continue;
    double w_sum = 0, m1 = 0, m2 = 0;
    for (int k = 0; k < kSamples - 1; ++k) {
      const double w = std::exp(L[static_cast<std::size_t>(k)] - best);
      const double pos = k - kHalfLength + 0.5;  // in steps from the centre
      w_sum += w;
      m1 += w * pos;
      m2 += w * pos * pos;
    }
    const double mean = m1 / w_sum;
    const double var = std::max(0.0, m2 / w_sum - mean * mean) + 1.0 / 12.0;  // + the step's quantisation
    l.mean = mean * step / l.scale_d;
    l.var = var * step * step / (l.scale_d * l.scale_d);
    used_[static_cast<std::size_t>(i)] = 1;
    ++used;
  }
  separation_ = sep_n > 0 ? sep_sum / sep_n : 0.0;
  return used;
}

int RegionModality::measure(GrayView luma, ChromaView chroma, GrayView valid, const CameraModel& camera,
                            const SE3& T, int step_factor) {
  if (!configured_ || !model_ready_ || luma.width != width_ || luma.height != height_ || !T.all_finite()) {
    placed_ = 0;
    return 0;
  }
  if (place_lines(camera, T) == 0) return 0;
  const double step = base_step_ * std::max(1, step_factor);
  sample_lines(luma, chroma, valid, step);
  return measure_lines(step);
}

double RegionModality::offset_of(const Line& l, const SE3& T, Eigen::Matrix<double, 1, 6>* J) const {
  const Vec3 pc = T * l.p_model;
  if (!(pc.z() > 1.0)) return std::numeric_limits<double>::quiet_NaN();
  const double iz = 1.0 / pc.z();
  const Vec2 px(K_.fx * pc.x() * iz + K_.cx, K_.fy * pc.y() * iz + K_.cy);
  if (J) {
    // n^T d(pixel)/d(camera point), then d(camera point)/d[omega; v] =
    // [-[pc]x, I].
    const double a = l.normal.x() * K_.fx * iz, b = l.normal.y() * K_.fy * iz;
    const double c = -(a * pc.x() + b * pc.y()) * iz;
    const Vec3 dp(a, b, c);
    const Vec3 rot = pc.cross(dp);  // dp^T (-[pc]x) = (pc x dp)^T
    *J << rot.x(), rot.y(), rot.z(), dp.x(), dp.y(), dp.z();
  }
  return l.normal.dot(px - l.centre);
}

double RegionModality::linearize(const SE3& T, Mat6* H, Vec6* g) const {
  double c = 0;
  Eigen::Matrix<double, 1, 6> J;
  for (int i = 0; i < placed_; ++i) {
    if (!used_[static_cast<std::size_t>(i)]) continue;
    const Line& l = lines_[static_cast<std::size_t>(i)];
    const double x = offset_of(l, T, &J);
    if (!std::isfinite(x)) continue;
    const double r = x - l.mean, info = 1.0 / l.var;
    const double e2 = r * r * info;
    const double w = e2 <= kHuber * kHuber ? 1.0 : kHuber / std::sqrt(e2);
    *H += (w * info) * J.transpose() * J;
    *g += (w * info * r) * J.transpose();
    c += huber_rho(e2);
  }
  return c;
}

double RegionModality::cost(const SE3& T) const {
  double c = 0;
  for (int i = 0; i < placed_; ++i) {
    if (!used_[static_cast<std::size_t>(i)]) continue;
    const Line& l = lines_[static_cast<std::size_t>(i)];
    const double x = offset_of(l, T, nullptr);
    if (!std::isfinite(x)) continue;
    c += huber_rho((x - l.mean) * (x - l.mean) / l.var);
  }
  return c;
}

void RegionModality::evaluate(const SE3& T, ContourFit* fit) const {
  *fit = ContourFit{};
  fit->candidates = placed_;
  fit->separation = separation_;
  double r2 = 0, chi2 = 0;
  for (int i = 0; i < placed_; ++i) {
    if (!used_[static_cast<std::size_t>(i)]) continue;
    const Line& l = lines_[static_cast<std::size_t>(i)];
    const double x = offset_of(l, T, nullptr);
    if (!std::isfinite(x)) continue;
    const double r = x - l.mean;
    r2 += r * r;
    chi2 += r * r / l.var;
    ++fit->lines;
  }
  if (fit->lines > 0) {
    fit->rms_px = std::sqrt(r2 / fit->lines);
    fit->chi2_per_line = chi2 / fit->lines;
  }
}

bool RegionModality::estimate(GrayView luma, ChromaView chroma, GrayView valid, const CameraModel& camera, SE3* T,
                              ContourFit* fit, int min_lines) {
  if (!model_ready_ || !T->all_finite()) return false;
  SE3 Tc = *T;
  for (const int factor : {8, 4, 2, 1, 1}) {
    if (measure(luma, chroma, valid, camera, Tc, factor) < min_lines) return false;
    double lambda = 1e-4;
    double c = cost(Tc);
    for (int it = 0; it < 5; ++it) {
      Mat6 H = Mat6::Zero();
      Vec6 g = Vec6::Zero();
      linearize(Tc, &H, &g);
      Mat6 A = H;
      for (int k = 0; k < 6; ++k) A(k, k) += lambda * std::max(H(k, k), 1e-9);
      const Vec6 delta = A.ldlt().solve(-g);
      if (!delta.allFinite()) return false;
      const SE3 Tn = SE3::exp(delta) * Tc;
      const double cn = cost(Tn);
      if (cn < c) {
        Tc = Tn;
        c = cn;
        lambda = std::max(lambda * 0.1, 1e-8);
        if (delta.head<3>().norm() < 1e-6 && delta.tail<3>().norm() < 1e-4) break;
      } else {
        lambda *= 10;
      }
    }
  }
  if (!Tc.all_finite()) return false;
  if (fit) evaluate(Tc, fit);
  *T = Tc;
  return true;
}

void RegionModality::learn(GrayView luma, ChromaView chroma, GrayView valid, const CameraModel& camera,
                           const SE3& T, float rate) {
  if (!configured_ || luma.width != width_ || luma.height != height_ || !T.all_finite()) return;
  if (place_lines(camera, T) == 0) return;
  sample_lines(luma, chroma, valid, base_step_);
  std::fill(fg_new_.begin(), fg_new_.end(), 0.f);
  std::fill(bg_new_.begin(), bg_new_.end(), 0.f);
  double nf = 0, nb = 0;
  for (int i = 0; i < placed_; ++i) {
    const Line& l = lines_[static_cast<std::size_t>(i)];
    const double x = offset_of(l, T, nullptr);
    if (!std::isfinite(x)) continue;
    const double x_steps = x * l.scale_d / last_step_;  // the outline on the line, in steps
    for (int s = 0; s < kSamples; ++s) {
      if (!(l.valid_bits & (1u << s))) continue;
      const double pos = s - kHalfLength;
      const auto b = static_cast<std::size_t>(l.bin[static_cast<std::size_t>(s)]);
      if (pos < x_steps - 1.5) {
        fg_new_[b] += 1.f;
        nf += 1;
      } else if (pos > x_steps + 1.5) {
        bg_new_[b] += 1.f;
        nb += 1;
      }
    }
  }
  if (nf < 50 || nb < 50) return;
  const float r = model_ready_ ? std::clamp(rate, 0.f, 1.f) : 1.f;
  const auto f_scale = static_cast<float>(1.0 / nf), b_scale = static_cast<float>(1.0 / nb);
  for (int b = 0; b < kBins; ++b) {
    const auto k = static_cast<std::size_t>(b);
    fg_[k] = (1.f - r) * fg_[k] + r * fg_new_[k] * f_scale;
    bg_[k] = (1.f - r) * bg_[k] + r * bg_new_[k] * b_scale;
  }
  model_ready_ = true;
}

}  // namespace st
