#include "core/features/orb_extractor.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <initializer_list>
#include <string>

#include <opencv2/core/hal/intrin.hpp>

namespace st {
namespace {

constexpr int kBlock = 16;  // level-0 block size of the coarse mask map (= FAST chunk width)

int ceil_div(int a, int b) { return (a + b - 1) / b; }

// Level pixel -> level-0 pixel (pixel centres at integers).
inline float to_level0(float v, float scale) { return (v + 0.5f) * scale - 0.5f; }

// Level-0 pixel -> mask pixel for a mask of mask_n pixels over image_n.
inline int to_mask(float v0, int mask_n, int image_n) {
  const int m = static_cast<int>(std::floor((v0 + 0.5f) * static_cast<float>(mask_n) /
                                            static_cast<float>(image_n)));
  return m;
}

// For every 16-pixel block along one axis: the first and last mask index
// whose pixel (covering image pixels [m * image_n / mask_n, ((m + 1) *
// image_n - 1) / mask_n]) touches it; lo > hi if none does.
void block_spans(int mask_n, int image_n, int blocks, std::int32_t* lo, std::int32_t* hi) {
  std::fill(lo, lo + blocks, mask_n);
  std::fill(hi, hi + blocks, -1);
  for (int m = 0; m < mask_n; ++m) {
    const int b0 = static_cast<int>(static_cast<std::int64_t>(m) * image_n / mask_n) / kBlock;
    const int b1 = static_cast<int>((static_cast<std::int64_t>(m + 1) * image_n - 1) / mask_n) / kBlock;
    for (int b = b0; b <= std::min(b1, blocks - 1); ++b) {
      lo[b] = std::min(lo[b], m);
      hi[b] = std::max(hi[b], m);
    }
  }
}

// Spreading takes every cell's best, then every cell's second best, ...:
// rank r holds the cells with more than r corners (hist[s] = cells holding
// s). Returns how many ranks fit whole into target and their corners in
// *taken. The cells must hold more than target corners in all.
int ranks_taken_whole(const std::int32_t* hist, int ncells, int target, int* taken) {
  int cells_above = ncells - hist[0];
  int full_ranks = 0;
  *taken = 0;
  while (*taken + cells_above <= target) {
    *taken += cells_above;
    ++full_ranks;
    cells_above -= hist[full_ranks];
  }
  return full_ranks;
}

}  // namespace

// Per 16x16 level-0 block: any[b] = some mask pixel touching it is set,
// all[b] = every one is (1 if none touches it). Rows of a block are reduced
// first (max / min over contiguous rows vectorise), then the columns.
void OrbExtractor::block_any_all(GrayView mask, std::uint8_t* any, std::uint8_t* all) {
  std::int32_t* ylo = span_rows_.data();
  std::int32_t* yhi = ylo + blocks_y_;
  std::int32_t* xlo = span_cols_.data();
  std::int32_t* xhi = xlo + blocks_x_;
  block_spans(mask.height, height_, blocks_y_, ylo, yhi);
  block_spans(mask.width, width_, blocks_x_, xlo, xhi);
  std::uint8_t* rmax = row_max_.data();
  std::uint8_t* rmin = row_min_.data();
  const int w = mask.width;
  for (int by = 0; by < blocks_y_; ++by) {
    std::uint8_t* a = any + static_cast<std::ptrdiff_t>(by) * blocks_x_;
    std::uint8_t* l = all + static_cast<std::ptrdiff_t>(by) * blocks_x_;
    if (ylo[by] > yhi[by]) {
      std::fill(a, a + blocks_x_, 0);
      std::fill(l, l + blocks_x_, 1);
      continue;
    }
    std::memcpy(rmax, mask.row(ylo[by]), static_cast<std::size_t>(w));
    std::memcpy(rmin, mask.row(ylo[by]), static_cast<std::size_t>(w));
    for (int y = ylo[by] + 1; y <= yhi[by]; ++y) {
      const std::uint8_t* r = mask.row(y);
      for (int x = 0; x < w; ++x) {
        rmax[x] = std::max(rmax[x], r[x]);
        rmin[x] = std::min(rmin[x], r[x]);
      }
    }
    for (int bx = 0; bx < blocks_x_; ++bx) {
      std::uint8_t mx = 0, mn = 255;
      for (int x = xlo[bx]; x <= xhi[bx]; ++x) {
        mx = std::max(mx, rmax[x]);
        mn = std::min(mn, rmin[x]);
      }
      a[bx] = mx ? 1 : 0;
      l[bx] = mn ? 1 : 0;
    }
  }
}

Status OrbExtractor::configure(const OrbConfig& c, int width, int height) {
  if (c.n_features < 1 || c.n_features > kMaxKeypoints)
    return make_error("OrbConfig.n_features " + std::to_string(c.n_features) + " outside [1, " +
                      std::to_string(kMaxKeypoints) + "] (core/base/capacity.h kMaxKeypoints)");
  if (c.fast_threshold_relaxed < 1 || c.fast_threshold_strict > 254 ||
      c.fast_threshold_relaxed > c.fast_threshold_strict)
    return make_error("OrbConfig: need 1 <= fast_threshold_relaxed <= fast_threshold_strict <= 254");
  if (c.threshold_cell_px < 8 || c.min_spread_cell_px < 2 || c.spread_cell_keypoints < 1 ||
      c.spread_cell_keypoints > 1024)
    return make_error("OrbConfig: threshold_cell_px must be >= 8, min_spread_cell_px >= 2, "
                      "spread_cell_keypoints in [1, 1024]");
  if (c.edge_border_px < kOrbPatchRadius + 1 || c.edge_border_px > 64)
    return make_error("OrbConfig.edge_border_px must be in [16, 64] (descriptor patch radius 15)");
  if (c.organ_margin_px < -256 || c.organ_margin_px > 256)
    return make_error("OrbConfig.organ_margin_px must be in [-256, 256]");
  if (Status s = pyramid_.configure(width, height, c.levels, c.scale_factor); !s) return s;
  if (Status s = fast_.configure(width); !s) return s;
  // false (the slower (dx, dy) path) only for frames beyond 2340 px wide
  descriptor_.set_stride(pyramid_.smoothed(0).stride);
  config_ = c;
  width_ = width;
  height_ = height;
  // Targets per level fall geometrically with 1/scale_factor (as cv::ORB).
  const double f = 1.0 / static_cast<double>(c.scale_factor);
  double per_level = c.n_features * (1.0 - f) / (1.0 - std::pow(f, c.levels));
  int total = 0;
  for (int k = 0; k < c.levels - 1; ++k) {
    level_target_[k] = static_cast<int>(std::lround(per_level));
    total += level_target_[k];
    per_level *= f;
  }
  level_target_[c.levels - 1] = std::max(c.n_features - total, 0);
  // 3x3 suppression keeps at most one corner per 2x2 pixels; frames keep
  // far fewer (kMaxLevelCorners).
  const std::size_t cap = std::min(static_cast<std::size_t>(width) * height / 4 + 64,
                                   static_cast<std::size_t>(kMaxLevelCorners));
  fast_out_.assign(cap, FastCorner{});
  cand_.assign(cap, Candidate{});
  cand_tmp_.assign(cap, Candidate{});
  cell_has_strict_.assign(static_cast<std::size_t>(ceil_div(width, c.threshold_cell_px) + 1) *
                              (ceil_div(height, c.threshold_cell_px) + 1), 0);
  organ_margined_.assign(static_cast<std::size_t>(width) * height, 0);
  organ_morph_.configure(width, height);
  blocks_x_ = ceil_div(width, kBlock);
  blocks_y_ = ceil_div(height, kBlock);
  block_ok_.assign(static_cast<std::size_t>(blocks_x_) * blocks_y_ * 5, 0);
  organ_depth_.assign(static_cast<std::size_t>(blocks_x_) * blocks_y_, 0);
  span_rows_.assign(static_cast<std::size_t>(blocks_y_) * 2, 0);
  span_cols_.assign(static_cast<std::size_t>(blocks_x_) * 2, 0);
  row_max_.assign(static_cast<std::size_t>(kMaxImageWidth), 0);  // masks up to kMaxImageWidth wide
  row_min_.assign(static_cast<std::size_t>(kMaxImageWidth), 0);
  chunk_ok_.assign(static_cast<std::size_t>(height) * (ceil_div(width, kBlock) + 1), 0);
  chunk_relaxed_.assign(chunk_ok_.size(), 0);
  smooth_tiles_.assign(static_cast<std::size_t>(ceil_div(width, ImagePyramid::kSmoothTilePx)) *
                           ceil_div(height, ImagePyramid::kSmoothTilePx), 0);
  rank_count_.assign(cap + 1, 0);
  set_threshold_scale(1.f);
  {
    const std::size_t scells = static_cast<std::size_t>(ceil_div(width, c.min_spread_cell_px)) *
                               ceil_div(height, c.min_spread_cell_px);
    spread_count_.assign(scells, 0);
    spread_begin_.assign(scells + 1, 0);
    spread_open_.assign(scells, 0);
  }
  spread_open_chunks_.assign(static_cast<std::size_t>(ceil_div(width, kBlock)) + 1, 0);
  cell_need_.assign(static_cast<std::size_t>(ceil_div(height, c.threshold_cell_px) + 1) *
                        (ceil_div(width, kBlock) + 1), 0);
  return Status::Ok();
}

void OrbExtractor::set_threshold_scale(float s) {
  threshold_scale_ = std::isnan(s) ? 1.f : std::clamp(s, 0.f, 1.f);  // 0: the floors
  const auto scaled = [&](int t, int floor) {
    return std::min(t, std::max(floor, static_cast<int>(std::lround(static_cast<float>(t) * threshold_scale_))));
  };
  strict_threshold_ = scaled(config_.fast_threshold_strict, kMinStrictThreshold);
  relaxed_threshold_ = std::min(strict_threshold_, scaled(config_.fast_threshold_relaxed, kMinRelaxedThreshold));
  // Relaxed cascade: halfway between strict and relaxed, then relaxed.
  relaxed_cascade_ = {(strict_threshold_ + relaxed_threshold_) / 2, relaxed_threshold_};
}

void OrbExtractor::prepare_masks(GrayView organ, GrayView valid) {
  organ_ = GrayView();
  valid_ = valid.empty() ? GrayView() : valid;
  if (!organ.empty()) {
    const int m = config_.organ_margin_px;
    const int r = m >= 0 ? ceil_div(m * organ.width, width_) : -ceil_div(-m * organ.width, width_);
    if (r != 0 && organ.width <= width_ && organ.height <= height_) {
      const ImageView<std::uint8_t> margined(organ_margined_.data(), organ.width, organ.height);
      morph_square(organ, r, margined, organ_morph_.scratch(organ.width, organ.height));
      organ_ = margined;
    } else {
      organ_ = organ;
    }
  }
  use_chunks_ = !organ_.empty() || !valid_.empty();
  allowed_fraction_ = 1.f;
  if (!use_chunks_) return;
  // block_ok_: [0] allowed (some pixel inside both masks, by block), [1]
  // all inside both, [2] full (see below), [3..4] per-mask scratch.
  const std::size_t nb = static_cast<std::size_t>(blocks_x_) * blocks_y_;
  std::uint8_t* ok = block_ok_.data();
  std::uint8_t* all = ok + nb;
  std::uint8_t* any2 = ok + 3 * nb;
  std::uint8_t* all2 = ok + 4 * nb;
  std::fill(ok, ok + 2 * nb, 1);
  for (GrayView m : {organ_, valid_}) {
    if (m.empty()) continue;
    block_any_all(m, any2, all2);
    for (std::size_t i = 0; i < nb; ++i) {
      ok[i] &= any2[i];
      all[i] &= all2[i];
    }
    if (m.data == organ_.data) organ_block_depths(all2);
  }
  int allowed = 0;
  for (std::size_t i = 0; i < nb; ++i) allowed += ok[i];
  allowed_fraction_ = static_cast<float>(allowed) / static_cast<float>(nb);
  mark_full_blocks();
}

// Full blocks: whose 3x3 block neighbourhood is entirely inside both masks.
// A FAST circle (radius <= 3 * scale < 16 px for scale < 5.3) centred in
// such a block lies inside, so inside_masks() can answer at once.
void OrbExtractor::mark_full_blocks() {
  const std::size_t nb = static_cast<std::size_t>(blocks_x_) * blocks_y_;
  const std::uint8_t* all = block_ok_.data() + nb;
  std::uint8_t* full = block_ok_.data() + 2 * nb;
  std::fill(full, full + nb, 0);
  if (pyramid_.scale(pyramid_.levels() - 1) * 3.f >= static_cast<float>(kBlock)) return;
  for (int by = 1; by + 1 < blocks_y_; ++by)
    for (int bx = 1; bx + 1 < blocks_x_; ++bx) {
      std::uint8_t a = 1;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) a &= all[(by + dy) * blocks_x_ + bx + dx];
      full[by * blocks_x_ + bx] = a;
    }
}

void OrbExtractor::build_chunk_map(int level) {
  const GrayView img = pyramid_.level(level);
  const float s = pyramid_.scale(level);
  const int chunks = ceil_div(img.width, kBlock);
  const std::uint8_t* blocks = block_ok_.data();
  int prev_by = -1;
  for (int y = 0; y < img.height; ++y) {
    const int by = std::clamp(static_cast<int>(to_level0(static_cast<float>(y), s)) / kBlock, 0,
                              blocks_y_ - 1);
    std::uint8_t* row = chunk_ok_.data() + static_cast<std::ptrdiff_t>(y) * chunks;
    if (by == prev_by) {  // same block row as the row above: same chunks
      std::memcpy(row, row - chunks, static_cast<std::size_t>(chunks));
      continue;
    }
    prev_by = by;
    const std::uint8_t* brow = blocks + static_cast<std::ptrdiff_t>(by) * blocks_x_;
    for (int cx = 0; cx < chunks; ++cx) {
      const int bx0 = std::clamp(static_cast<int>(to_level0(static_cast<float>(cx * kBlock), s)) / kBlock, 0, blocks_x_ - 1);
      const int bx1 = std::clamp(static_cast<int>(to_level0(static_cast<float>(cx * kBlock + kBlock - 1), s)) / kBlock, 0, blocks_x_ - 1);
      std::uint8_t any = 0;
      for (int bx = bx0; bx <= bx1; ++bx) any |= brow[bx];
      row[cx] = any;
    }
  }
}

// organ_depth_: per block, the Chebyshev distance in blocks to the nearest
// block not wholly on the (margined) organ, 0 for such a block itself;
// blocks beyond the image count as on the organ (the patch test ignores
// points off the image). Two passes over the block grid; capped at 255.
void OrbExtractor::organ_block_depths(const std::uint8_t* organ_all) {
  const int bw = blocks_x_, bh = blocks_y_;
  std::uint8_t* d = organ_depth_.data();
  for (int i = 0; i < bw * bh; ++i) d[i] = organ_all[i] ? 255 : 0;
  const auto relax = [&](int bx, int by, int from_x, int from_y) {
    if (from_x < 0 || from_y < 0 || from_x >= bw || from_y >= bh) return;
    std::uint8_t& v = d[by * bw + bx];
    v = std::min<std::uint8_t>(v, static_cast<std::uint8_t>(std::min(d[from_y * bw + from_x] + 1, 255)));
  };
  for (int by = 0; by < bh; ++by)
    for (int bx = 0; bx < bw; ++bx) {
      relax(bx, by, bx - 1, by);
      relax(bx, by, bx - 1, by - 1);
      relax(bx, by, bx, by - 1);
      relax(bx, by, bx + 1, by - 1);
    }
  for (int by = bh - 1; by >= 0; --by)
    for (int bx = bw - 1; bx >= 0; --bx) {
      relax(bx, by, bx + 1, by);
      relax(bx, by, bx + 1, by + 1);
      relax(bx, by, bx, by + 1);
      relax(bx, by, bx - 1, by + 1);
    }
}

// The centre and 8 points on the patch's circle (level-0 coordinates) in
// the organ mask: the descriptor describes tissue, not the organ's outline.
bool OrbExtractor::patch_on_organ(float X, float Y, float scale) const {
  static constexpr float kC = 0.70710678f;
  static constexpr float kDx[9] = {0, 1, kC, 0, -kC, -1, -kC, 0, kC};
  static constexpr float kDy[9] = {0, 0, kC, 1, kC, 0, -kC, -1, -kC};
  const float r = static_cast<float>(kOrbPatchRadius + 1) * scale;
  // Deep inside the organ, the blocks around answer at once: points within
  // (depth - 1) blocks of the centre's block lie on wholly organ blocks, and
  // one block more covers the mask's rounding at block edges.
  const int bx = std::clamp(static_cast<int>(X) / kBlock, 0, blocks_x_ - 1);
  const int by = std::clamp(static_cast<int>(Y) / kBlock, 0, blocks_y_ - 1);
  if (static_cast<float>((organ_depth_[static_cast<std::size_t>(by * blocks_x_ + bx)] - 2) * kBlock) >= r)
    return true;
  for (int i = 0; i < 9; ++i) {
    const int mx = to_mask(X + kDx[i] * r, organ_.width, width_);
    const int my = to_mask(Y + kDy[i] * r, organ_.height, height_);
    // Off the image is not off the organ: the frame's edge is no outline.
    if (!organ_.contains(mx, my)) {
      if (i == 0) return false;
      continue;
    }
    if (!organ_(mx, my)) return false;
  }
  return true;
}

bool OrbExtractor::inside_masks(int level, int x, int y) const {
  const float s = pyramid_.scale(level);
  const float X = to_level0(static_cast<float>(x), s), Y = to_level0(static_cast<float>(y), s);
  const int bx = std::clamp(static_cast<int>(X) / kBlock, 0, blocks_x_ - 1);
  const int by = std::clamp(static_cast<int>(Y) / kBlock, 0, blocks_y_ - 1);
  const std::size_t nb = static_cast<std::size_t>(blocks_x_) * blocks_y_;
  const bool patch_test = config_.organ_patch_inside && !organ_.empty();
  if (patch_test && !patch_on_organ(X, Y, s)) return false;
  if (block_ok_[2 * nb + static_cast<std::size_t>(by * blocks_x_ + bx)]) return true;
  if (!organ_.empty() && !patch_test) {  // (the patch test covered the centre)
    const int mx = to_mask(X, organ_.width, width_), my = to_mask(Y, organ_.height, height_);
    if (!organ_.contains(mx, my) || !organ_(mx, my)) return false;
  }
  if (!valid_.empty()) {
    // The centre and the 16 pixels of the FAST circle must all be valid.
    static constexpr int kDx[17] = {0, 0, 1, 2, 3, 3, 3, 2, 1, 0, -1, -2, -3, -3, -3, -2, -1};
    static constexpr int kDy[17] = {0, -3, -3, -2, -1, 0, 1, 2, 3, 3, 3, 2, 1, 0, -1, -2, -3};
    for (int i = 0; i < 17; ++i) {
      const int mx = to_mask(X + static_cast<float>(kDx[i]) * s, valid_.width, width_);
      const int my = to_mask(Y + static_cast<float>(kDy[i]) * s, valid_.height, height_);
      if (!valid_.contains(mx, my) || !valid_(mx, my)) return false;
    }
  }
  return true;
}

// FAST corners of a level at threshold into fast_out_; a scan that fills
// the array is redone at a higher threshold (kMaxLevelCorners), so that the
// corners kept are the strongest over the whole level, not the first rows'.
// A cascade step below the threshold used then finds nothing new.
int OrbExtractor::detect_bounded(GrayView img, int threshold, const std::uint8_t* allowed, int chunks) {
  const int capacity = static_cast<int>(fast_out_.size());
  for (int t = threshold;; t = std::min(kMaxScanThreshold, t + std::max(2, t / 2))) {
    const int n = fast_.detect(img, t, config_.edge_border_px, allowed, chunks, fast_out_.data(), capacity);
    if (n < capacity || t >= kMaxScanThreshold) return n;
    ++stats_.threshold_raises;
  }
}

// Pass 1 (strict threshold): corners inside the masks; marks their cells.
int OrbExtractor::filter_strict(int level, int n_fast) {
  const GrayView img = pyramid_.level(level);
  const int cell = config_.threshold_cell_px;
  const int cells_x = ceil_div(img.width, cell);
  const std::size_t ncells = static_cast<std::size_t>(cells_x) * ceil_div(img.height, cell);
  std::fill(cell_has_strict_.begin(), cell_has_strict_.begin() + static_cast<std::ptrdiff_t>(ncells), 0);
  int n = 0;
  for (int i = 0; i < n_fast; ++i) {
    const FastCorner& c = fast_out_[static_cast<std::size_t>(i)];
    if (use_chunks_ && !inside_masks(level, c.x, c.y)) continue;
    const std::uint32_t ci = static_cast<std::uint32_t>((c.y / cell) * cells_x + c.x / cell);
    cell_has_strict_[ci] = 1;
    cand_[static_cast<std::size_t>(n++)] = Candidate{ci, static_cast<float>(c.score), c.x, c.y, c.score};
  }
  return n;
}

// Chunks for pass 2: allowed by the masks and overlapping a threshold cell
// without a strict corner (cells need not align with the 16-pixel chunks).
void OrbExtractor::build_relaxed_chunk_map(int level) {
  const GrayView img = pyramid_.level(level);
  const int cell = config_.threshold_cell_px;
  const int cells_x = ceil_div(img.width, cell);
  const int chunks = ceil_div(img.width, kBlock);
  const int cells_y = ceil_div(img.height, cell);
  std::uint8_t* need = cell_need_.data();
  for (int cy = 0; cy < cells_y; ++cy) {  // per cell row: chunks touching a cell without strict
    const std::uint8_t* has = cell_has_strict_.data() + static_cast<std::ptrdiff_t>(cy) * cells_x;
    for (int cx = 0; cx < chunks; ++cx) {
      const int c0 = cx * kBlock / cell, c1 = std::min((cx * kBlock + kBlock - 1) / cell, cells_x - 1);
      std::uint8_t n = 0;
      for (int c = c0; c <= c1; ++c) n |= static_cast<std::uint8_t>(!has[c]);
      need[static_cast<std::ptrdiff_t>(cy) * chunks + cx] = n;
    }
  }
  const int scell = relaxed_cell_px_;
  const int scells_x = scell > 0 ? ceil_div(img.width, scell) : 0;
  std::uint8_t* open_chunk = spread_open_chunks_.data();
  int open_row = -1;
  for (int y = 0; y < img.height; ++y) {
    const std::uint8_t* nrow = need + static_cast<std::ptrdiff_t>(y / cell) * chunks;
    std::uint8_t* out = chunk_relaxed_.data() + static_cast<std::ptrdiff_t>(y) * chunks;
    std::memcpy(out, nrow, static_cast<std::size_t>(chunks));
    if (use_chunks_) {
      const std::uint8_t* in = chunk_ok_.data() + static_cast<std::ptrdiff_t>(y) * chunks;
      for (int cx = 0; cx < chunks; ++cx) out[cx] &= in[cx];
    }
    if (scell == 0) continue;
    if (y / scell != open_row) {  // chunks touching an open spreading cell of this row
      open_row = y / scell;
      const std::uint8_t* open = spread_open_.data() + static_cast<std::ptrdiff_t>(open_row) * scells_x;
      for (int cx = 0; cx < chunks; ++cx) {
        const int s0 = cx * kBlock / scell, s1 = std::min((cx * kBlock + kBlock - 1) / scell, scells_x - 1);
        std::uint8_t any = 0;
        for (int sx = s0; sx <= s1; ++sx) any |= open[sx];
        open_chunk[cx] = any;
      }
    }
    for (int cx = 0; cx < chunks; ++cx) out[cx] &= open_chunk[cx];
  }
}

// Pass 2 (relaxed threshold, only where needed): appends corners scoring
// in (min_score, max_score] that lie in a cell without a strict corner, in
// an open spreading cell and inside the masks.
int OrbExtractor::filter_relaxed(int level, int n_fast, int n, int min_score, int max_score) {
  const GrayView img = pyramid_.level(level);
  const int cell = config_.threshold_cell_px;
  const int cells_x = ceil_div(img.width, cell);
  for (int i = 0; i < n_fast; ++i) {
    const FastCorner& c = fast_out_[static_cast<std::size_t>(i)];
    if (c.score > max_score || c.score <= min_score) continue;  // an earlier or a later step's
    const std::uint32_t ci = static_cast<std::uint32_t>((c.y / cell) * cells_x + c.x / cell);
    if (cell_has_strict_[ci]) continue;
    if (relaxed_cell_px_ > 0) {  // closed spreading cell: it could not be kept
      const int sc = relaxed_cell_px_;
      if (!spread_open_[static_cast<std::size_t>((c.y / sc) * ceil_div(img.width, sc) + c.x / sc)]) continue;
    }
    if (use_chunks_ && !inside_masks(level, c.x, c.y)) continue;
    if (n == static_cast<int>(cand_.size())) break;  // the strict and relaxed corners together filled it
    cand_[static_cast<std::size_t>(n++)] = Candidate{ci, static_cast<float>(c.score), c.x, c.y, c.score};
  }
  return n;
}

// Spreading cells hold about spread_cell_keypoints of the target over the
// allowed area (see OrbConfig).
int OrbExtractor::spread_cell_px(int level, int target) const {
  const GrayView img = pyramid_.level(level);
  const float area = static_cast<float>(img.width) * static_cast<float>(img.height) * allowed_fraction_;
  return std::max(config_.min_spread_cell_px,
                  static_cast<int>(std::sqrt(area * static_cast<float>(config_.spread_cell_keypoints) /
                                             static_cast<float>(std::max(target, 1)))));
}

// Keeps target of the n candidates: every cell's best first, then every
// cell's second best, ... (rank r of a cell = its r-th best key); the last,
// partly taken rank goes to the strongest keys. O(n): candidates are
// bucketed by cell (counting sort), the ranks taken whole follow from the
// histogram of cell counts, and each cell only partitions its best ones.
int OrbExtractor::spread(int level, int n, int target) {
  if (n <= target) return n;
  const GrayView img = pyramid_.level(level);
  const int cell = spread_cell_px(level, target);
  const int cells_x = ceil_div(img.width, cell);
  const int ncells = cells_x * ceil_div(img.height, cell);
  Candidate* c = cand_.data();
  const auto stronger = [](const Candidate& a, const Candidate& b) { return a.key > b.key; };
  if (ncells == 1) {  // one cell: the strongest
    std::nth_element(c, c + target, c + n, stronger);
    return target;
  }
  // Bucket by cell into cand_tmp_: begin[i] .. begin[i + 1] is cell i.
  std::int32_t* begin = spread_begin_.data();
  std::fill(begin, begin + ncells + 1, 0);
  for (int i = 0; i < n; ++i) {
    c[i].cell = static_cast<std::uint32_t>((c[i].y / cell) * cells_x + c[i].x / cell);
    ++begin[c[i].cell + 1];
  }
  int max_count = 0;
  for (int i = 0; i < ncells; ++i) {
    max_count = std::max(max_count, begin[i + 1]);
    begin[i + 1] += begin[i];
  }
  std::int32_t* fill_pos = spread_count_.data();
  std::copy(begin, begin + ncells, fill_pos);
  Candidate* b = cand_tmp_.data();
  for (int i = 0; i < n; ++i) b[fill_pos[c[i].cell]++] = c[i];
  std::int32_t* hist = rank_count_.data();
  std::fill(hist, hist + max_count + 1, 0);
  for (int i = 0; i < ncells; ++i) ++hist[begin[i + 1] - begin[i]];
  int taken = 0;
  const int full_ranks = ranks_taken_whole(hist, ncells, target, &taken);
  // Ranks < full_ranks of every cell go to the front of cand_, the rank
  // full_ranks candidates (one per fuller cell) after them.
  int out = 0, n_next = 0;
  Candidate* rank_next = c + taken;
  for (int i = 0; i < ncells; ++i) {
    Candidate* cb = b + begin[i];
    const int count = begin[i + 1] - begin[i];
    if (count > full_ranks) {
      std::nth_element(cb, cb + full_ranks, cb + count, stronger);
      rank_next[n_next++] = cb[full_ranks];
    }
    const int keep = std::min(count, full_ranks);
    std::copy(cb, cb + keep, c + out);
    out += keep;
  }
  const int fill = std::min(target - taken, n_next);
  if (fill > 0 && fill < n_next) std::nth_element(rank_next, rank_next + fill, rank_next + n_next, stronger);
  return taken + std::max(fill, 0);
}

// Which spreading cells (of spread(level, .., target)) a relaxed corner could
// still survive in, given the n strict candidates. A relaxed corner ranks
// below every strict corner of its cell (its FAST score is <= the strict
// threshold < theirs), so in a cell with s strict corners its rank is >= s.
// Adding corners never raises the number of ranks spread() takes whole, so
// that number computed from the strict corners alone (R) bounds it: cells
// with s > R are closed, and skipping relaxed corners there changes nothing.
// Returns false if every cell is closed (no relaxed pass needed).
bool OrbExtractor::close_spread_cells(int level, int n, int target) {
  relaxed_cell_px_ = 0;
  if (n <= target) return true;  // all open: every corner could be kept
  const GrayView img = pyramid_.level(level);
  const int cell = spread_cell_px(level, target);
  const int cells_x = ceil_div(img.width, cell);
  const int ncells = cells_x * ceil_div(img.height, cell);
  std::int32_t* count = spread_count_.data();
  std::fill(count, count + ncells, 0);
  int max_count = 0;
  for (int i = 0; i < n; ++i) {
    const Candidate& c = cand_[static_cast<std::size_t>(i)];
    const int ci = (c.y / cell) * cells_x + c.x / cell;
    max_count = std::max(max_count, ++count[ci]);
  }
  // hist[s] = cells holding s strict corners; cells with rank r = cells with s > r.
  std::int32_t* hist = rank_count_.data();
  std::fill(hist, hist + max_count + 1, 0);
  for (int i = 0; i < ncells; ++i) ++hist[count[i]];
  int taken = 0;
  const int full_ranks = ranks_taken_whole(hist, ncells, target, &taken);
  bool any_open = false;
  for (int i = 0; i < ncells; ++i) {
    spread_open_[static_cast<std::size_t>(i)] = count[i] <= full_ranks ? 1 : 0;
    any_open |= count[i] <= full_ranks;
  }
  relaxed_cell_px_ = cell;
  return any_open;
}

// Harris corner response (k = 0.04) over a 7x7 window of central-difference
// gradients on the level image; candidates are >= 16 pixels inside.
// Integer sums (<= 7 * 7 * 255^2 < 2^31) are exact, so the SIMD path (one
// row of 7 gradients per vector, the 8th lane zeroed) equals the scalar one.
void OrbExtractor::harris_keys(int level, int n) {
  const GrayView img = pyramid_.level(level);
  const std::ptrdiff_t st = img.stride;
  for (int i = 0; i < n; ++i) {
    Candidate& c = cand_[static_cast<std::size_t>(i)];
    std::int64_t sxx = 0, syy = 0, sxy = 0;
#if CV_SIMD128
    const cv::v_int16x8 keep7 = cv::v_int16x8(-1, -1, -1, -1, -1, -1, -1, 0);
    cv::v_int32x4 axx = cv::v_setzero_s32(), ayy = cv::v_setzero_s32(), axy = cv::v_setzero_s32();
    for (int dy = -3; dy <= 3; ++dy) {
      const std::uint8_t* p = img.row(c.y + dy) + c.x - 3;  // lanes dx = -3 .. 4
      const cv::v_int16x8 gx = (cv::v_reinterpret_as_s16(cv::v_load_expand(p + 1)) -
                                cv::v_reinterpret_as_s16(cv::v_load_expand(p - 1))) &
                               keep7;
      const cv::v_int16x8 gy = (cv::v_reinterpret_as_s16(cv::v_load_expand(p + st)) -
                                cv::v_reinterpret_as_s16(cv::v_load_expand(p - st))) &
                               keep7;
      axx += cv::v_dotprod(gx, gx);
      ayy += cv::v_dotprod(gy, gy);
      axy += cv::v_dotprod(gx, gy);
    }
    sxx = cv::v_reduce_sum(axx);
    syy = cv::v_reduce_sum(ayy);
    sxy = cv::v_reduce_sum(axy);
#else
    for (int dy = -3; dy <= 3; ++dy) {
      const std::uint8_t* p = img.row(c.y + dy) + c.x;
      for (int dx = -3; dx <= 3; ++dx) {
        const int gx = p[dx + 1] - p[dx - 1];
        const int gy = p[dx + st] - p[dx - st];
        sxx += gx * gx;
        syy += gy * gy;
        sxy += gx * gy;
      }
    }
#endif
    const double a = static_cast<double>(sxx), b = static_cast<double>(syy), d = static_cast<double>(sxy);
    c.key = static_cast<float>(a * b - d * d - 0.04 * (a + b) * (a + b));
  }
}

// Smooths only the tiles of the level that the kept keypoints' patches
// (radius kOrbPatchRadius) reach.
void OrbExtractor::smooth_patches(int level, int n) {
  const GrayView img = pyramid_.level(level);
  constexpr int kTile = ImagePyramid::kSmoothTilePx;
  const int tiles_x = ceil_div(img.width, kTile), tiles_y = ceil_div(img.height, kTile);
  std::fill(smooth_tiles_.begin(), smooth_tiles_.begin() + tiles_x * tiles_y, 0);
  for (int i = 0; i < n; ++i) {
    const Candidate& c = cand_[static_cast<std::size_t>(i)];
    const int tx0 = std::max(c.x - kOrbPatchRadius, 0) / kTile;
    const int tx1 = std::min(c.x + kOrbPatchRadius, img.width - 1) / kTile;
    const int ty0 = std::max(c.y - kOrbPatchRadius, 0) / kTile;
    const int ty1 = std::min(c.y + kOrbPatchRadius, img.height - 1) / kTile;
    for (int ty = ty0; ty <= ty1; ++ty)
      for (int tx = tx0; tx <= tx1; ++tx) smooth_tiles_[static_cast<std::size_t>(ty * tiles_x + tx)] = 1;
  }
  pyramid_.smooth_tiles(level, smooth_tiles_.data(), tiles_x);
}

void OrbExtractor::describe(int level, int n, FeatureSet& out) {
  smooth_patches(level, n);
  const GrayView img = pyramid_.level(level);
  const GrayView smooth = pyramid_.smoothed(level);
  const float s = pyramid_.scale(level);
  for (int i = 0; i < n && out.count < kMaxKeypoints; ++i) {
    const Candidate& c = cand_[static_cast<std::size_t>(i)];
    Keypoint& kp = out.keypoints[static_cast<std::size_t>(out.count)];
    kp.x = to_level0(static_cast<float>(c.x), s);
    kp.y = to_level0(static_cast<float>(c.y), s);
    kp.octave = level;
    kp.response = static_cast<float>(c.score);
    kp.angle_deg = OrbDescriptor::orientation_deg(img, c.x, c.y);
    descriptor_.compute(smooth, c.x, c.y, kp.angle_deg,
                        out.descriptors[static_cast<std::size_t>(out.count)].data());
    ++out.count;
    ++out.per_level[static_cast<std::size_t>(level)];
  }
}

bool OrbExtractor::extract(GrayView image, GrayView organ_mask, GrayView valid_mask, FeatureSet& out) {
  out.clear();
  stats_ = OrbFrameStats{};
  for (GrayView m : {organ_mask, valid_mask})
    if (m.width > kMaxImageWidth || m.height > kMaxImageHeight) return false;
  if (!pyramid_.build_levels(image, config_.denoise)) return false;  // smoothing: per level, kept patches only
  out.width = width_;
  out.height = height_;
  prepare_masks(organ_mask, valid_mask);
  for (int k = 0; k < pyramid_.levels(); ++k) {
    const GrayView img = pyramid_.level(k);
    if (img.width <= 2 * config_.edge_border_px || img.height <= 2 * config_.edge_border_px) continue;
    if (use_chunks_) build_chunk_map(k);
    // Strict threshold everywhere, the relaxed one only in threshold cells
    // where the strict one kept nothing: most of the frame is scored once,
    // at the threshold where few pixels pass the cheap pre-test.
    const int chunks = ceil_div(img.width, kBlock);
    const int n_strict = detect_bounded(img, strict_threshold_, use_chunks_ ? chunk_ok_.data() : nullptr, chunks);
    int n_kept = filter_strict(k, n_strict);
    // Relaxed corners only where they could survive the first spreading,
    // in a cascade of descending thresholds: each step adds the corners
    // scoring in (its threshold, the previous one] in the spreading cells
    // the corners found so far leave open. One FAST scan serves every step:
    // at the lowest threshold, over the chunks open at the first step (the
    // open cells only shrink as corners are added). A corner's score does
    // not depend on the threshold, nor does its suppression by neighbours
    // scoring as high, so each step gets the corners a scan at its own
    // threshold would; a later step's scan over its own, smaller chunk map
    // scored fewer neighbours, so it kept a few more corners at the edges
    // of its chunks, which suppression by their true neighbours now drops.
    // Scanning each step separately scored ~24,000 chunk rows a frame on
    // orbit 1280x720 (13,000 at threshold 13, then 11,000 at 7); this
    // scores the 13,000 once.
    int n_relaxed = 0;
    bool scanned = false;
    int prev_threshold = strict_threshold_;
    for (const int t : relaxed_cascade_) {
      if (t >= prev_threshold) continue;
      if (!close_spread_cells(k, n_kept, 2 * level_target_[k])) break;
      if (!scanned) {
        build_relaxed_chunk_map(k);
        n_relaxed = detect_bounded(img, relaxed_threshold_, chunk_relaxed_.data(), chunks);
        scanned = true;
      }
      n_kept = filter_relaxed(k, n_relaxed, n_kept, t, prev_threshold);
      prev_threshold = t;
    }
    stats_.fast_corners += n_strict + n_relaxed;
    stats_.masked_corners += n_kept;
    stats_.kept_corners += n_kept;
    const int n_pre = spread(k, n_kept, 2 * level_target_[k]);
    harris_keys(k, n_pre);
    const int n_spread = spread(k, n_pre, level_target_[k]);
    describe(k, n_spread, out);
  }
  return true;
}

}  // namespace st
