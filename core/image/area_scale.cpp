#include "core/image/area_scale.h"

#include <algorithm>
#include <numeric>
#include <string>

#include <opencv2/core/hal/intrin.hpp>

#include "core/base/capacity.h"

namespace st {

// Exact overlaps in units of 1 / (in * out): output j covers [j in, (j + 1) in),
// input i covers [i out, (i + 1) out); the weight is overlap / in, rounded to
// 1/256 with the rounding error put on the largest tap, so that every
// output's weights sum to exactly 256.
void AreaScaler::make_axis(int in, int out, Axis* axis) {
  const long long n = in, m = out;
  axis->taps = static_cast<int>((n + m - 1) / m) + 1;
  axis->first.assign(static_cast<std::size_t>(out), 0);
  axis->weight.assign(static_cast<std::size_t>(out) * static_cast<std::size_t>(axis->taps), 0);
  for (long long j = 0; j < m; ++j) {
    const long long start = j * n, end = (j + 1) * n;
    const long long i0 = start / m, i1 = (end - 1) / m;  // inputs i0..i1 overlap
    std::uint16_t* w = &axis->weight[static_cast<std::size_t>(j) * static_cast<std::size_t>(axis->taps)];
    int sum = 0, largest = 0;
    for (long long i = i0; i <= i1; ++i) {
      const long long overlap = std::min(end, (i + 1) * m) - std::max(start, i * m);
      const int k = static_cast<int>(i - i0);
      w[k] = static_cast<std::uint16_t>((overlap * 256 + n / 2) / n);
      sum += w[k];
      if (w[k] > w[largest]) largest = k;
    }
    w[largest] = static_cast<std::uint16_t>(w[largest] + 256 - sum);
    axis->first[static_cast<std::size_t>(j)] = static_cast<std::int32_t>(i0);
  }
}

Status AreaScaler::configure(int in_w, int in_h, int out_w, int out_h) {
  in_w_ = in_h_ = out_w_ = out_h_ = 0;
  const auto size = [](int w, int h) { return std::to_string(w) + "x" + std::to_string(h); };
  if (in_w < 1 || in_h < 1 || in_w > kMaxImageWidth || in_h > kMaxImageHeight)
    return make_error("area scale: input size " + size(in_w, in_h) + " outside [1, " + std::to_string(kMaxImageWidth) +
                      "]x[1, " + std::to_string(kMaxImageHeight) + "]");
  if (out_w < 1 || out_h < 1 || out_w > in_w || out_h > in_h)
    return make_error("area scale: output size " + size(out_w, out_h) + " is not within the input's " + size(in_w, in_h));
  if (in_w > out_w * kMaxRatio || in_h > out_h * kMaxRatio)
    return make_error("area scale: " + size(in_w, in_h) + " to " + size(out_w, out_h) + " is more than " +
                      std::to_string(kMaxRatio) + "x down");
  make_axis(in_w, out_w, &x_);
  const int g = std::gcd(in_w, out_w);
  period_in_ = in_w / g;
  period_out_ = out_w / g;
  make_axis(in_h, out_h, &y_);
  row_.assign(static_cast<std::size_t>(in_w) + 8, 0);
  in_w_ = in_w;
  in_h_ = in_h;
  out_w_ = out_w;
  out_h_ = out_h;
  return Status::Ok();
}

namespace {

// Output pixels [first, end) of one row from the 8-bit row (each output the
// rounded weighted sum of its taps).
inline void columns_scalar(const std::uint16_t* row, const std::int32_t* first, const std::uint16_t* weight, int taps,
                           int in_w, int begin, int end, std::uint8_t* out) {
  for (int i = begin; i < end; ++i) {
    const std::uint16_t* r = row + first[i];
    const std::uint16_t* w = weight + static_cast<std::ptrdiff_t>(i) * taps;
    const int n = std::min(taps, in_w - first[i]);
    unsigned s = 128u;
    for (int k = 0; k < n; ++k) s += static_cast<unsigned>(w[k]) * r[k];
    out[i] = static_cast<std::uint8_t>(s >> 8);
  }
}

}  // namespace

int AreaScaler::row_taps(int j) const {
  const std::uint16_t* wy = &y_.weight[static_cast<std::size_t>(j) * static_cast<std::size_t>(y_.taps)];
  int taps = std::min(y_.taps, in_h_ - y_.first[static_cast<std::size_t>(j)]);
  while (taps > 1 && wy[taps - 1] == 0) --taps;
  return taps;
}

int AreaScaler::input_row_begin(int j) const { return y_.first[static_cast<std::size_t>(j)]; }

int AreaScaler::input_row_end(int j) const { return input_row_begin(j) + row_taps(j); }

bool AreaScaler::scale(GrayView in, ImageView<std::uint8_t> out) {
  if (in_w_ == 0 || in.empty() || in.width != in_w_ || in.height != in_h_) return false;
  return scale_rows(in, 0, 0, out_h_, out);
}

bool AreaScaler::scale_rows(GrayView band, int band_y0, int j_begin, int j_end, ImageView<std::uint8_t> out) {
  if (in_w_ == 0 || band.empty() || band.width != in_w_ || out.width != out_w_ || out.height != out_h_ ||
      out.data == nullptr || j_begin < 0 || j_end > out_h_ || j_begin > j_end)
    return false;
  if (j_begin < j_end && (input_row_begin(j_begin) < band_y0 || input_row_end(j_end - 1) > band_y0 + band.height))
    return false;
  std::uint16_t* row = row_.data();
  const int ty = y_.taps, tx = x_.taps;
  const std::int32_t* first = x_.first.data();
  const std::uint16_t* wx = x_.weight.data();
  for (int j = j_begin; j < j_end; ++j) {
    const int y0 = y_.first[static_cast<std::size_t>(j)];
    const std::uint16_t* wy = &y_.weight[static_cast<std::size_t>(j) * static_cast<std::size_t>(ty)];
    const int taps = row_taps(j);
    // The rows: row[x] = round(sum_k wy[k] in(x, y0 + k) / 256), 8 bits in
    // 16 (the sum is at most 255 * 256 + 128).
    int x = 0;
#if CV_SIMD128
    const cv::v_uint16x8 half = cv::v_setall_u16(128);
    const std::uint8_t* src[kMaxRatio + 1];
    cv::v_uint16x8 wk[kMaxRatio + 1];
    for (int k = 0; k < taps; ++k) {
      src[k] = band.row(y0 - band_y0 + k);
      wk[k] = cv::v_setall_u16(wy[k]);
    }
    for (; x + 16 <= in_w_; x += 16) {
      cv::v_uint16x8 lo = half, hi = half;
      for (int k = 0; k < taps; ++k) {
        cv::v_uint16x8 a, b;
        cv::v_expand(cv::v_load(src[k] + x), a, b);
        lo = cv::v_add_wrap(lo, cv::v_mul_wrap(a, wk[k]));
        hi = cv::v_add_wrap(hi, cv::v_mul_wrap(b, wk[k]));
      }
      cv::v_store(row + x, cv::v_shr<8>(lo));
      cv::v_store(row + x + 8, cv::v_shr<8>(hi));
    }
#endif
    for (; x < in_w_; ++x) {
      unsigned s = 128u;
      for (int k = 0; k < taps; ++k) s += static_cast<unsigned>(wy[k]) * band.row(y0 - band_y0 + k)[x];
      row[x] = static_cast<std::uint16_t>(s >> 8);
    }
    std::uint8_t* o = out.row(j);
    int done = 0;
#if CV_SIMD128
    // The columns where the ratio repeats every 2 or 3 inputs (2:1, 3:1,
    // 3:2: 1080p or 4K to 1280 or 960 wide): 8 groups at a time, the
    // weights of the first group (the pattern is periodic).
    const auto w = [wx, tx](int output, int k) { return cv::v_setall_u16(wx[output * tx + k]); };
    if (period_in_ == 2 && period_out_ == 1) {
      const cv::v_uint16x8 w0 = w(0, 0), w1 = w(0, 1);
      for (; done + 8 <= out_w_ && 2 * (done + 8) <= in_w_; done += 8) {
        cv::v_uint16x8 a, b;
        cv::v_load_deinterleave(row + 2 * done, a, b);
        cv::v_pack_store(o + done, cv::v_shr<8>(cv::v_add_wrap(cv::v_add_wrap(cv::v_mul_wrap(a, w0), cv::v_mul_wrap(b, w1)), half)));
      }
    } else if (period_in_ == 3 && period_out_ == 1) {
      const cv::v_uint16x8 w0 = w(0, 0), w1 = w(0, 1), w2 = w(0, 2);
      for (; done + 8 <= out_w_ && 3 * (done + 8) <= in_w_; done += 8) {
        cv::v_uint16x8 a, b, c;
        cv::v_load_deinterleave(row + 3 * done, a, b, c);
        const cv::v_uint16x8 s = cv::v_add_wrap(cv::v_add_wrap(cv::v_mul_wrap(a, w0), cv::v_mul_wrap(b, w1)),
                                                cv::v_add_wrap(cv::v_mul_wrap(c, w2), half));
        cv::v_pack_store(o + done, cv::v_shr<8>(s));
      }
    } else if (period_in_ == 3 && period_out_ == 2) {
      // Output 2g from inputs 3g, 3g + 1; output 2g + 1 from 3g + 1, 3g + 2.
      const cv::v_uint16x8 w00 = w(0, 0), w01 = w(0, 1), w10 = w(1, 0), w11 = w(1, 1);
      for (; done + 16 <= out_w_ && 3 * (done + 16) / 2 <= in_w_; done += 16) {
        cv::v_uint16x8 a, b, c;
        cv::v_load_deinterleave(row + 3 * done / 2, a, b, c);
        const cv::v_uint16x8 even = cv::v_shr<8>(cv::v_add_wrap(cv::v_add_wrap(cv::v_mul_wrap(a, w00), cv::v_mul_wrap(b, w01)), half));
        const cv::v_uint16x8 odd = cv::v_shr<8>(cv::v_add_wrap(cv::v_add_wrap(cv::v_mul_wrap(b, w10), cv::v_mul_wrap(c, w11)), half));
        cv::v_uint16x8 lo, hi;
        cv::v_zip(even, odd, lo, hi);
        cv::v_store(o + done, cv::v_pack(lo, hi));
      }
    }
#endif
    columns_scalar(row, first, wx, tx, in_w_, done, out_w_, o);
  }
  return true;
}

Status FrameScaler::configure(int in_w, int in_h, int out_w, int out_h) {
  if (Status s = luma_.configure(in_w, in_h, out_w, out_h); !s.ok()) return s;
  return chroma_.configure(chroma_size(in_w), chroma_size(in_h), chroma_size(out_w), chroma_size(out_h));
}

bool FrameScaler::scale(GrayView y, GrayView u, GrayView v, ImageView<std::uint8_t> out_y,
                        ImageView<std::uint8_t> out_u, ImageView<std::uint8_t> out_v, bool* chroma) {
  *chroma = false;
  if (!luma_.scale(y, out_y)) return false;
  *chroma = !u.empty() && !v.empty() && chroma_.scale(u, out_u) && chroma_.scale(v, out_v);
  return true;
}

}  // namespace st
