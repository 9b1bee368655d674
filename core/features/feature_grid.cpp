#include "core/features/feature_grid.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "core/base/capacity.h"

#if ST_HAVE_AVX512
#include <immintrin.h>
#endif

namespace st {

Status FeatureGrid::configure(int width, int height, int cell_px) {
  if (width < 1 || height < 1 || width > kMaxImageWidth || height > kMaxImageHeight)
    return make_error("FeatureGrid: image size outside [1, kMaxImageWidth/Height]");
  if (cell_px < 4 || cell_px > 512) return make_error("FeatureGrid: cell_px must be in [4, 512]");
  cell_px_ = cell_px;
  cells_x_ = (width + cell_px - 1) / cell_px;
  cells_y_ = (height + cell_px - 1) / cell_px;
  const std::size_t n = static_cast<std::size_t>(cells_x_) * cells_y_;
  cell_start_.assign(n + 1, 0);
  cell_fill_.assign(n, 0);
  item_x_.assign(kMaxKeypoints, 0.f);
  item_y_.assign(kMaxKeypoints, 0.f);
  item_octave_.assign(kMaxKeypoints, 0);
  item_index_.assign(kMaxKeypoints, 0);
  use_avx512_ = cpu_has_avx512f();
  return Status::Ok();
}

int FeatureGrid::cell_of(float x, float y) const {
  const int cx = std::clamp(static_cast<int>(std::floor(x / static_cast<float>(cell_px_))), 0, cells_x_ - 1);
  const int cy = std::clamp(static_cast<int>(std::floor(y / static_cast<float>(cell_px_))), 0, cells_y_ - 1);
  return cy * cells_x_ + cx;
}

void FeatureGrid::build(const FeatureSet& f) {
  std::fill(cell_start_.begin(), cell_start_.end(), 0);
  const int n = std::min(f.count, kMaxKeypoints);
  for (int i = 0; i < n; ++i) {
    const Keypoint& k = f.keypoints[static_cast<std::size_t>(i)];
    ++cell_start_[static_cast<std::size_t>(cell_of(k.x, k.y)) + 1];
  }
  for (std::size_t c = 1; c < cell_start_.size(); ++c) cell_start_[c] += cell_start_[c - 1];
  std::copy(cell_start_.begin(), cell_start_.end() - 1, cell_fill_.begin());
  for (int i = 0; i < n; ++i) {
    const Keypoint& k = f.keypoints[static_cast<std::size_t>(i)];
    const auto slot = static_cast<std::size_t>(cell_fill_[static_cast<std::size_t>(cell_of(k.x, k.y))]++);
    item_x_[slot] = k.x;
    item_y_[slot] = k.y;
    item_octave_[slot] = k.octave;
    item_index_[slot] = i;
  }
}

namespace {

// The grid's arrays and one query's window and tests.
struct GridView {
  const float *x, *y;
  const std::int32_t *octave, *index, *cell_start;
  int cells_x;
};
struct Window {
  int cx0, cx1, cy0, cy1;
  float x, y, r2;
  int lo;         // octave window as one unsigned compare: octave - lo <= span
  unsigned span;  // (any octave: the whole int range)
};

// Item j lies within the window's radius and octave range.
inline bool is_hit(const GridView& g, const Window& w, int j) {
  const float dx = g.x[j] - w.x, dy = g.y[j] - w.y;
  return (static_cast<unsigned>(g.octave[j] - w.lo) <= w.span) & (dx * dx + dy * dy <= w.r2);
}

// The hits among items begin..end-1, in order, to out, which has room for
// all of them. The tests are random per keypoint (octaves mix), so the loop
// is branch-free: every item is written and the count advances only for a
// hit.
struct PortableRun {
  int operator()(const GridView& g, const Window& w, int begin, int end, int* out) const {
    int n = 0;
    for (int j = begin; j < end; ++j) {
      out[n] = g.index[j];
      n += is_hit(g, w, j) ? 1 : 0;
    }
    return n;
  }
};

// The cells cx0..cx1 of one row are consecutive in the counting sort: one
// run per row, through run() where its items surely fit, else checked.
// Always inlined, so that the AVX-512 caller gets its own copy with its run
// inlined.
template <typename Run>
[[gnu::always_inline]] inline int scan_rows(const GridView& g, const Window& w, int* out,
                                            int capacity, Run run) {
  int n = 0;
  for (int cy = w.cy0; cy <= w.cy1; ++cy) {
    const int row = cy * g.cells_x;
    const int begin = g.cell_start[row + w.cx0], end = g.cell_start[row + w.cx1 + 1];
    if (capacity - n >= end - begin) {
      n += run(g, w, begin, end, out + n);
      continue;
    }
    for (int j = begin; j < end; ++j) {  // may not fit: the checked loop
      if (!is_hit(g, w, j)) continue;
      if (n >= capacity) return n;
      out[n++] = g.index[j];
    }
  }
  return n;
}

#if ST_HAVE_AVX512
// PortableRun, 16 items a step: the same float tests (this file is built
// without floating-point contraction), hits packed in order by a register
// compress. A struct, not a lambda, so that its call operator carries the
// target.
struct Avx512Run {
  ST_AVX512 int operator()(const GridView& g, const Window& w, int begin, int end, int* out) const {
    const __m512 qx = _mm512_set1_ps(w.x), qy = _mm512_set1_ps(w.y), rr = _mm512_set1_ps(w.r2);
    const __m512i lo = _mm512_set1_epi32(w.lo), span = _mm512_set1_epi32(static_cast<int>(w.span));
    int n = 0;
    for (int j = begin; j < end; j += 16) {
      const int left = end - j;
      const __mmask16 live = left >= 16 ? __mmask16(0xFFFF) : __mmask16((1u << left) - 1);
      const __m512 dx = _mm512_sub_ps(_mm512_maskz_loadu_ps(live, g.x + j), qx);
      const __m512 dy = _mm512_sub_ps(_mm512_maskz_loadu_ps(live, g.y + j), qy);
      const __m512 d2 = _mm512_add_ps(_mm512_mul_ps(dx, dx), _mm512_mul_ps(dy, dy));
      const __m512i octave = _mm512_maskz_loadu_epi32(live, g.octave + j);
      const __mmask16 hit = _mm512_mask_cmp_ps_mask(live, d2, rr, _CMP_LE_OQ) &
                            _mm512_mask_cmple_epu32_mask(live, _mm512_sub_epi32(octave, lo), span);
      const int count = __builtin_popcount(static_cast<unsigned>(hit));
      const __m512i index = _mm512_maskz_loadu_epi32(live, g.index + j);
      _mm512_mask_storeu_epi32(out + n, static_cast<__mmask16>((1u << count) - 1),
                               _mm512_maskz_compress_epi32(hit, index));
      n += count;
    }
    return n;
  }
};

ST_AVX512 int scan_rows_avx512(const GridView& g, const Window& w, int* out, int capacity) {
  return scan_rows(g, w, out, capacity, Avx512Run{});
}
#endif

}  // namespace

int FeatureGrid::query(float x, float y, float radius, int min_octave, int max_octave, int* out,
                       int capacity) const {
  if (!(radius >= 0.f) || !std::isfinite(x) || !std::isfinite(y) || cells_x_ == 0) return 0;
  const float cp = static_cast<float>(cell_px_);
  Window w;
  w.cx0 = std::max(0, static_cast<int>(std::floor((x - radius) / cp)));
  w.cy0 = std::max(0, static_cast<int>(std::floor((y - radius) / cp)));
  w.cx1 = std::min(cells_x_ - 1, static_cast<int>(std::floor((x + radius) / cp)));
  w.cy1 = std::min(cells_y_ - 1, static_cast<int>(std::floor((y + radius) / cp)));
  w.x = x;
  w.y = y;
  w.r2 = radius * radius;
  const bool any_octave = min_octave < 0 && max_octave < 0;
  w.lo = any_octave ? 0 : min_octave;
  w.span = any_octave ? ~0u : static_cast<unsigned>(max_octave - min_octave);
  const GridView g{item_x_.data(),     item_y_.data(),     item_octave_.data(),
                   item_index_.data(), cell_start_.data(), cells_x_};
#if ST_HAVE_AVX512
  if (use_avx512_) return scan_rows_avx512(g, w, out, capacity);
#endif
  return scan_rows(g, w, out, capacity, PortableRun{});
}

}  // namespace st
