#include "core/contour/outline_search.h"

#include <algorithm>
#include <cmath>


namespace st {

namespace {

constexpr int kMinTemplateCells = 12;   // a silhouette smaller than this on the grid is not matched
constexpr double kRoundShape = 1.3;     // principal moments closer than this: the axis is not trusted
constexpr double kMinScale = 0.25, kMaxScale = 8.0;

}  // namespace

void OutlineSearch::Moments::add(int x, int y) {
  m00 += 1;
  m10 += x;
  m01 += y;
  m20 += static_cast<double>(x) * x;
  m11 += static_cast<double>(x) * y;
  m02 += static_cast<double>(y) * y;
}

OutlineSearch::Shape OutlineSearch::Moments::shape() const {
  Shape s;
  s.area = m00;
  s.cx = m10 / m00;
  s.cy = m01 / m00;
  s.mu20 = m20 / m00 - s.cx * s.cx;
  s.mu11 = m11 / m00 - s.cx * s.cy;
  s.mu02 = m02 / m00 - s.cy * s.cy;
  return s;
}

double OutlineSearch::Shape::angle() const { return 0.5 * std::atan2(2.0 * mu11, mu20 - mu02); }

double OutlineSearch::Shape::elongation() const {
  const double mean = 0.5 * (mu20 + mu02);
  const double d = std::sqrt(0.25 * (mu20 - mu02) * (mu20 - mu02) + mu11 * mu11);
  const double lo = mean - d;
  return lo > 1e-12 ? (mean + d) / lo : 1e12;
}

Status OutlineSearch::configure(const Mesh& mesh, const Pinhole& K) {
  configured_ = false;
  if (mesh.vertex_count() < 3 || mesh.triangle_count() < 1) return make_error("outline search: the mesh is empty");
  if (!(K.fx > 0) || !(K.fy > 0) || !std::isfinite(K.fx) || !std::isfinite(K.fy) || K.width <= 0 || K.height <= 0)
    return make_error("outline search: the camera needs positive focal lengths and size");
  K_ = K;
  w_ = kGridWidth;
  h_ = std::max(8, static_cast<int>(std::lround(static_cast<double>(K.height) * w_ / K.width)));
  K_grid_ = K.scaled(static_cast<double>(w_) / K.width, static_cast<double>(h_) / K.height, w_, h_);
  words_ = (w_ * h_ + 63) / 64;

  Vec3 lo = mesh.vertex(0), hi = lo;
  for (int i = 1; i < mesh.vertex_count(); ++i) {
    lo = lo.cwiseMin(mesh.vertex(i));
    hi = hi.cwiseMax(mesh.vertex(i));
  }
  centre_ = 0.5 * (lo + hi);
  double radius = 0;
  for (int i = 0; i < mesh.vertex_count(); ++i) radius = std::max(radius, (mesh.vertex(i) - centre_).norm());
  if (!(radius > 0) || !std::isfinite(radius)) return make_error("outline search: the mesh has no extent");
  // The whole bounding sphere in view, with a margin, at the reference distance.
  const double half_fov = std::min({std::atan(K.cx / K.fx), std::atan((K.width - K.cx) / K.fx),
                                    std::atan(K.cy / K.fy), std::atan((K.height - K.cy) / K.fy)});
  if (!(half_fov > 0.01)) return make_error("outline search: the principal point lies outside the image");
  d_ref_ = 1.05 * radius / std::sin(half_fov);

  RasterConfig rc;
  rc.width = w_;
  rc.height = h_;
  rc.downscale = 1;
  rc.near_mm = 1.0;
  rc.cull_backfaces = true;
  MeshRasterizer raster;  // start-up only: the templates keep what it draws
  if (Status s = raster.configure(mesh, rc); !s.ok()) return make_error("outline search: raster: " + s.message());
  R_dir_.assign(kDirections, Mat3::Identity());
  dirs_.assign(kDirections, Vec3::Zero());
  kept_.assign(kDirections, Kept{});
  shapes_.assign(kDirections, Shape{});
  bits_.assign(static_cast<std::size_t>(kDirections) * static_cast<std::size_t>(words_), 0);
  const auto cells = static_cast<std::size_t>(w_) * static_cast<std::size_t>(h_);
  l_in_.assign(cells, 0.f);
  l_out_.assign(cells, 0.f);
  fg_.assign(RegionModality::kBins, 0.f);
  bg_.assign(RegionModality::kBins, 0.f);
  fg_new_.assign(RegionModality::kBins, 0.f);
  bg_new_.assign(RegionModality::kBins, 0.f);
  model_ready_ = false;
  const double golden = M_PI * (3.0 - std::sqrt(5.0));
  for (int d = 0; d < kDirections; ++d) {
    const double z = 1.0 - 2.0 * (d + 0.5) / kDirections, r = std::sqrt(std::max(0.0, 1.0 - z * z));
    const Vec3 dir(r * std::cos(golden * d), r * std::sin(golden * d), z);  // centre -> camera
    const Vec3 zc = -dir;
    const Vec3 a = std::abs(zc.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY();
    const Vec3 xc = zc.cross(a).normalized();
    const Vec3 yc = zc.cross(xc);
    Mat3 R;
    R.row(0) = xc.transpose();
    R.row(1) = yc.transpose();
    R.row(2) = zc.transpose();
    R_dir_[static_cast<std::size_t>(d)] = R;
    dirs_[static_cast<std::size_t>(d)] = dir;
    raster.render(template_pose(d), K_grid_);
    const ImageView<const std::uint8_t> mask = raster.mask();
    Moments m;
    std::uint64_t* b = bits_.data() + static_cast<std::size_t>(d) * static_cast<std::size_t>(words_);
    for (int y = 0; y < h_; ++y)
      for (int x = 0; x < w_; ++x) {
        if (!mask(x, y)) continue;
        const int i = y * w_ + x;
        b[i >> 6] |= std::uint64_t{1} << (i & 63);
        m.add(x, y);
      }
    if (m.m00 >= kMinTemplateCells) shapes_[static_cast<std::size_t>(d)] = m.shape();  // else area 0: never matched
  }
  configured_ = true;
  return Status::Ok();
}

void OutlineSearch::reset() {
  model_ready_ = false;
  std::fill(fg_.begin(), fg_.end(), 0.f);
  std::fill(bg_.begin(), bg_.end(), 0.f);
}

template <class F>
void OutlineSearch::for_cell_samples(int x, int y, GrayView valid, F&& f) const {
  const double sx = static_cast<double>(K_.width) / w_, sy = static_cast<double>(K_.height) / h_;
  const double vsx = valid.empty() ? 0.0 : static_cast<double>(valid.width) / K_.width;
  const double vsy = valid.empty() ? 0.0 : static_cast<double>(valid.height) / K_.height;
  for (int j = 0; j < 2; ++j)
    for (int i = 0; i < 2; ++i) {
      const int fx = std::min(static_cast<int>((x + 0.25 + 0.5 * i) * sx), K_.width - 1);
      const int fy = std::min(static_cast<int>((y + 0.25 + 0.5 * j) * sy), K_.height - 1);
      if (!valid.empty() && !valid(std::min(static_cast<int>(fx * vsx), valid.width - 1),
                                   std::min(static_cast<int>(fy * vsy), valid.height - 1)))
        continue;
      f(fx, fy);
    }
}

void OutlineSearch::learn(GrayView luma, ChromaView chroma, GrayView valid, const MeshRasterizer& raster,
                          float rate) {
  if (!configured_ || luma.width != K_.width || luma.height != K_.height) return;
  const ImageView<const std::uint8_t> mask = raster.mask();
  if (mask.empty()) return;
  const double msx = static_cast<double>(mask.width) / K_.width, msy = static_cast<double>(mask.height) / K_.height;
  std::fill(fg_new_.begin(), fg_new_.end(), 0.f);
  std::fill(bg_new_.begin(), bg_new_.end(), 0.f);
  int nf = 0, nb = 0;
  for (int y = 0; y < h_; ++y)
    for (int x = 0; x < w_; ++x) {
      // A cell counts only when all its samples are on one side of the outline.
      int inside = 0, n = 0;
      for_cell_samples(x, y, valid, [&](int fx, int fy) {
        inside += mask(std::min(static_cast<int>(fx * msx), mask.width - 1),
                       std::min(static_cast<int>(fy * msy), mask.height - 1)) != 0;
        ++n;
      });
      if (n == 0 || (inside != 0 && inside != n)) continue;
      std::vector<float>& hist = inside ? fg_new_ : bg_new_;
      for_cell_samples(x, y, valid, [&](int fx, int fy) {
        hist[static_cast<std::size_t>(RegionModality::colour_bin(luma, chroma, fx, fy))] += 1.f;
      });
      (inside ? nf : nb) += n;
    }
  constexpr int kMinSamples = 200;
  if (nf < kMinSamples || nb < kMinSamples) return;
  const float r = model_ready_ ? std::clamp(rate, 0.f, 1.f) : 1.f;
  const float f_scale = 1.f / static_cast<float>(nf), b_scale = 1.f / static_cast<float>(nb);
  for (std::size_t b = 0; b < fg_.size(); ++b) {
    fg_[b] = (1.f - r) * fg_[b] + r * fg_new_[b] * f_scale;
    bg_[b] = (1.f - r) * bg_[b] + r * bg_new_[b] * b_scale;
  }
  model_ready_ = true;
}

SE3 OutlineSearch::template_pose(int direction) const {
  const Mat3& R = R_dir_[static_cast<std::size_t>(direction)];
  return SE3(R, Vec3(0, 0, d_ref_) - R * centre_);
}

// Mean log-likelihood of the frame's cells under the template of
// `direction` brought onto the frame's organ by rotation and scale about
// the two centroids.
double OutlineSearch::score(int direction, double rotation, double scale) const {
  const Shape& t = shapes_[static_cast<std::size_t>(direction)];
  const std::uint64_t* b = bits_.data() + static_cast<std::size_t>(direction) * static_cast<std::size_t>(words_);
  // Every kScoreStride-th cell across and down, in 16.16 fixed point.
  constexpr double kOne = 65536.0;
  const double c = std::cos(rotation) / scale, s = std::sin(rotation) / scale;
  const auto step_x = static_cast<std::int32_t>(std::lround(kScoreStride * c * kOne));
  const auto step_y = static_cast<std::int32_t>(std::lround(-kScoreStride * s * kOne));
  const std::int32_t w_fixed = w_ << 16, h_fixed = h_ << 16;
  double sum = 0;
  for (int y = kScoreStride / 2; y < h_; y += kScoreStride) {
    const double dy = y - frame_.cy, dx = kScoreStride / 2 - frame_.cx;
    // Template coordinates of the row's first cell.
    auto xt = static_cast<std::int32_t>(std::lround((c * dx + s * dy + t.cx + 0.5) * kOne));
    auto yt = static_cast<std::int32_t>(std::lround((-s * dx + c * dy + t.cy + 0.5) * kOne));
    const float* li = l_in_.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(w_);
    const float* lo = l_out_.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(w_);
    float row = 0.f;
    for (int x = kScoreStride / 2; x < w_; x += kScoreStride, xt += step_x, yt += step_y) {
      bool inside = false;
      if (xt >= 0 && yt >= 0 && xt < w_fixed && yt < h_fixed) {
        const int i = (yt >> 16) * w_ + (xt >> 16);
        inside = (b[i >> 6] >> (i & 63)) & 1u;
      }
      row += inside ? li[x] : lo[x];
    }
    sum += static_cast<double>(row);
  }
  return sum / std::max(1, scored_cells_);
}

SE3 OutlineSearch::pose_of(const Kept& k) const {
  const Shape& t = shapes_[static_cast<std::size_t>(k.direction)];
  const double c = std::cos(k.rotation), s = std::sin(k.rotation);
  // Where the organ's centre (the template's principal point) lands on the frame's grid.
  const double px = K_grid_.cx - t.cx, py = K_grid_.cy - t.cy;
  const double gx = k.scale * (c * px - s * py) + frame_.cx, gy = k.scale * (s * px + c * py) + frame_.cy;
  const double ux = (gx + 0.5) * K_.width / w_ - 0.5, uy = (gy + 0.5) * K_.height / h_ - 0.5;
  const Vec3 ray = Vec3((ux - K_.cx) / K_.fx, (uy - K_.cy) / K_.fy, 1.0).normalized();
  const Mat3 R_ray = Eigen::Quaterniond::FromTwoVectors(Vec3::UnitZ(), ray).toRotationMatrix();
  Mat3 R_roll;
  R_roll << c, -s, 0, s, c, 0, 0, 0, 1;
  const Mat3 R = R_ray * R_roll * R_dir_[static_cast<std::size_t>(k.direction)];
  const double distance = d_ref_ / k.scale;
  return SE3(R, distance * ray - R * centre_);
}

int OutlineSearch::search(GrayView luma, ChromaView chroma, GrayView valid, OutlineCandidate* out, int capacity) {
  stats_ = OutlineSearchStats{};
  capacity = std::min(capacity, kMaxCandidates);
  if (!configured_ || capacity <= 0 || !model_ready_ || luma.width != K_.width || luma.height != K_.height) return 0;
  // The frame's P(organ) on the grid.
  Moments organ;
  int cells = 0;
  scored_cells_ = 0;
  for (int y = 0; y < h_; ++y)
    for (int x = 0; x < w_; ++x) {
      double p_sum = 0;
      int n = 0;
      for_cell_samples(x, y, valid, [&](int fx, int fy) {
        const auto b = static_cast<std::size_t>(RegionModality::colour_bin(luma, chroma, fx, fy));
        p_sum += RegionModality::organ_probability(fg_[b], bg_[b]);
        ++n;
      });
      const auto k = static_cast<std::size_t>(y * w_ + x);
      if (n < 2) {  // no evidence here
        l_in_[k] = l_out_[k] = 0.f;
        continue;
      }
      const double p = p_sum / n;
      l_in_[k] = static_cast<float>(std::log(p));
      l_out_[k] = static_cast<float>(std::log(1.0 - p));
      ++cells;
      scored_cells_ += x % kScoreStride == kScoreStride / 2 && y % kScoreStride == kScoreStride / 2;
      if (p > 0.5) organ.add(x, y);
    }
  stats_.valid_cells = cells;
  stats_.organ_fraction = cells > 0 ? organ.m00 / cells : 0.0;
  if (cells == 0 || stats_.organ_fraction < kMinAreaFraction || stats_.organ_fraction > kMaxAreaFraction) return 0;
  stats_.searched = true;
  frame_ = organ.shape();
  const double frame_angle = frame_.angle();
  const bool frame_round = frame_.elongation() < kRoundShape;

  for (int d = 0; d < kDirections; ++d) {
    Kept& k = kept_[static_cast<std::size_t>(d)];
    k = Kept{};
    const Shape& t = shapes_[static_cast<std::size_t>(d)];
    if (t.area <= 0) continue;
    const double scale = std::sqrt(frame_.area / t.area);
    if (scale < kMinScale || scale > kMaxScale) continue;
    const double base = frame_angle - t.angle();
    const int turns = frame_round || t.elongation() < kRoundShape ? 8 : 2;
    k.direction = d;
    for (int r = 0; r < turns; ++r) {
      const double rotation = base + r * (2.0 * M_PI / turns);
      const double sc = score(d, rotation, scale);
      ++stats_.candidates_scored;
      if (sc > k.score) {
        k.score = sc;
        k.rotation = rotation;
        k.scale = scale;
      }
    }
  }
  // The best, then the best of the directions kSeparationDeg away from
  // every one taken (a silhouette seen from the opposite side is the
  // mirror image: a near-symmetric organ scores both).
  Kept best[kMaxCandidates];
  const double min_dot = std::cos(kSeparationDeg * M_PI / 180.0);
  int taken = 0;
  for (; taken < capacity; ++taken) {
    Kept pick;
    for (const Kept& k : kept_) {
      if (k.direction < 0 || !(k.score > pick.score)) continue;
      bool near = false;
      for (int i = 0; i < taken && !near; ++i)
        near = direction(k.direction).dot(direction(best[i].direction)) > min_dot;
      if (!near) pick = k;
    }
    if (pick.direction < 0) break;
    best[taken] = pick;
  }
  int n = 0;
  for (int i = 0; i < taken; ++i) {
    out[n].T_camera_model = pose_of(best[i]);
    out[n].score = best[i].score;
    ++n;
  }
  return n;
}

}  // namespace st
