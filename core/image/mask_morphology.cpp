#include "core/image/mask_morphology.h"

#include <algorithm>

namespace st {
namespace {

// Erosion: set iff every pixel of the window that lies inside the image is
// set. Dilation: set iff any is. count = set pixels, n = window pixels inside.
inline std::uint8_t decide(bool erode, int count, int n) {
  return (erode ? count == n : count > 0) ? 255 : 0;
}

void horizontal_pass(ImageView<const std::uint8_t> in, int r, bool erode,
                     ImageView<std::uint8_t> out, std::int32_t* prefix) {
  const int w = in.width;
  for (int y = 0; y < in.height; ++y) {
    const std::uint8_t* src = in.row(y);
    prefix[0] = 0;
    for (int x = 0; x < w; ++x) prefix[x + 1] = prefix[x] + (src[x] != 0);
    std::uint8_t* dst = out.row(y);
    for (int x = 0; x < w; ++x) {
      const int lo = std::max(0, x - r), hi = std::min(w - 1, x + r);
      dst[x] = decide(erode, prefix[hi + 1] - prefix[lo], hi - lo + 1);
    }
  }
}

void vertical_pass(ImageView<const std::uint8_t> in, int r, bool erode, ImageView<std::uint8_t> out,
                   std::int32_t* counts) {
  const int w = in.width, h = in.height;
  std::fill(counts, counts + w, 0);
  for (int y = 0; y < std::min(r, h); ++y)
    for (int x = 0; x < w; ++x) counts[x] += in(x, y) != 0;
  for (int y = 0; y < h; ++y) {
    if (y + r < h)
      for (int x = 0; x < w; ++x) counts[x] += in(x, y + r) != 0;
    if (y - r - 1 >= 0)
      for (int x = 0; x < w; ++x) counts[x] -= in(x, y - r - 1) != 0;
    const int n = std::min(h - 1, y + r) - std::max(0, y - r) + 1;
    std::uint8_t* dst = out.row(y);
    for (int x = 0; x < w; ++x) dst[x] = decide(erode, counts[x], n);
  }
}

// Small radii (the organ-mask margin, highlight dilation): the OR (AND for
// erosion) of the 2r shifted copies of the row, each a plain loop the
// compiler vectorises, beats the nearest-set-pixel scan and the running
// counts, whose loops carry a dependency (the tracker's 2-pixel erosion of
// its half-size organ mask: ~5 % of a frame by the counts).
constexpr int kShiftedOrMaxRadius = 16;

void dilate_rows_shifted(ImageView<const std::uint8_t> in, int r, ImageView<std::uint8_t> out) {
  const int w = in.width;
  for (int y = 0; y < in.height; ++y) {
    const std::uint8_t* s = in.row(y);
    std::uint8_t* t = out.row(y);
    std::copy(s, s + w, t);
    for (int d = 1; d <= std::min(r, w - 1); ++d) {
      for (int x = 0; x < w - d; ++x) t[x] |= s[x + d];
      for (int x = d; x < w; ++x) t[x] |= s[x - d];
    }
    for (int x = 0; x < w; ++x) t[x] = t[x] != 0 ? 255 : 0;
  }
}

// Dilation by nearest set pixel: horizontally, a pixel is set iff a set
// pixel lies within r on its row (one pass each way); vertically, the OR of
// the rows within r (contiguous rows: the inner loop vectorises). Cheaper
// than counts for the small radii masks use.
void dilate_rows(ImageView<const std::uint8_t> in, int r, ImageView<std::uint8_t> out) {
  const int w = in.width;
  if (r <= kShiftedOrMaxRadius) {
    dilate_rows_shifted(in, r, out);
    return;
  }
  for (int y = 0; y < in.height; ++y) {
    const std::uint8_t* s = in.row(y);
    std::uint8_t* t = out.row(y);
    int last = -r - 1;
    for (int x = 0; x < w; ++x) {
      if (s[x]) last = x;
      t[x] = (x - last <= r) ? 255 : 0;
    }
    int next = w + r + 1;
    for (int x = w - 1; x >= 0; --x) {
      if (s[x]) next = x;
      if (next - x <= r) t[x] = 255;
    }
  }
}

// Erosion with small radii, the dual of dilate_rows_shifted: the AND of the
// 2r shifted copies of the row, where a copy shifted past the row's end does
// not take part (the image border does not erode).
void erode_rows_shifted(ImageView<const std::uint8_t> in, int r, ImageView<std::uint8_t> out) {
  const int w = in.width;
  for (int y = 0; y < in.height; ++y) {
    const std::uint8_t* s = in.row(y);
    std::uint8_t* t = out.row(y);
    for (int x = 0; x < w; ++x) t[x] = s[x] != 0 ? 255 : 0;
    for (int d = 1; d <= std::min(r, w - 1); ++d) {
      for (int x = 0; x < w - d; ++x) t[x] &= s[x + d] != 0 ? 255 : 0;
      for (int x = d; x < w; ++x) t[x] &= s[x - d] != 0 ? 255 : 0;
    }
  }
}

// The AND (erosion) or the OR (dilation) of the rows within r; the rows
// hold 0 or 255 here.
template <bool kErode>
void combine_columns(ImageView<const std::uint8_t> in, int r, ImageView<std::uint8_t> out) {
  const int w = in.width, h = in.height;
  for (int y = 0; y < h; ++y) {
    std::uint8_t* d = out.row(y);
    const int y0 = std::max(0, y - r), y1 = std::min(h - 1, y + r);
    std::copy(in.row(y0), in.row(y0) + w, d);
    for (int yy = y0 + 1; yy <= y1; ++yy) {
      const std::uint8_t* t = in.row(yy);
      for (int x = 0; x < w; ++x) d[x] = kErode ? (d[x] & t[x]) : (d[x] | t[x]);
    }
  }
}

}  // namespace

void MorphBuffers::configure(int max_width, int max_height) {
  max_width_ = std::max(max_width, 0);
  max_height_ = std::max(max_height, 0);
  rows_.assign(static_cast<std::size_t>(max_width_) * static_cast<std::size_t>(max_height_), 0);
  counts_.assign(static_cast<std::size_t>(max_width_), 0);
  prefix_.assign(static_cast<std::size_t>(max_width_) + 1, 0);
}

MorphScratch MorphBuffers::scratch(int width, int height) {
  if (width < 0 || height < 0 || width > max_width_ || height > max_height_) return MorphScratch{{}, nullptr, nullptr};
  return MorphScratch{ImageView<std::uint8_t>(rows_.data(), width, height), counts_.data(), prefix_.data()};
}

void morph_square(ImageView<const std::uint8_t> in, int k, ImageView<std::uint8_t> out,
                  const MorphScratch& scratch) {
  if (in.width != out.width || in.height != out.height || scratch.rows.width < in.width ||
      scratch.rows.height < in.height || scratch.column_counts == nullptr || scratch.row_prefix == nullptr)
    return;  // a caller bug (MorphBuffers sized too small): out is left as it was
  const bool erode = k < 0;
  const int r = std::min(k < 0 ? -k : k, std::max(in.width, in.height));
  if (!erode) {
    dilate_rows(in, r, scratch.rows);
    combine_columns<false>(scratch.rows, r, out);
    return;
  }
  if (r <= kShiftedOrMaxRadius) {
    erode_rows_shifted(in, r, scratch.rows);
    combine_columns<true>(scratch.rows, r, out);
    return;
  }
  horizontal_pass(in, r, erode, scratch.rows, scratch.row_prefix);
  vertical_pass(scratch.rows, r, erode, out, scratch.column_counts);
}

}  // namespace st
