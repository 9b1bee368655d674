// AreaScaler: an 8-bit plane brought down to a smaller size by an area
// filter (each output pixel the mean of the input area it covers, partial
// pixels by their covered fraction), the tracker's working resolution from
// the tower's 1080p or 4K frame (TrackerConfig::working_width).
//
// Geometry: input pixel i covers [i, i + 1) and output pixel j covers
// [j / s, (j + 1) / s) of the input (s = out / in per axis), so with pixel
// centres at integers x_out = (x_in + 0.5) s - 0.5: Pinhole::scaled()'s
// convention, which the tracker's working camera uses.
//
// Separable, the rows first: an output row is the weighted sum of the 1-9
// input rows it covers (8-bit weights summing to 256, 8 lanes at a time,
// rounded to 8 bits), then each output pixel the weighted sum of the 1-9
// columns of that row it covers (weights summing to 256), 8 groups at a
// time where the pattern repeats every 2 or 3 inputs (2:1, 3:1, 3:2).
// Rounding to the nearest level twice: within 1 level of the exact area
// mean; a flat plane stays flat.
// Downscales up to 8x per axis (no upscaling: out <= in).
//
// configure() allocates (the weight tables, one row); scale() and
// scale_rows() allocate nothing. One scaler per thread.
#pragma once

#include <cstdint>
#include <vector>

#include "core/base/result.h"
#include "core/image/image.h"

namespace st {

class AreaScaler {
 public:
  static constexpr int kMaxRatio = 8;

  // in_w x in_h -> out_w x out_h, 1 <= out <= in, in <= out * kMaxRatio.
  Status configure(int in_w, int in_h, int out_w, int out_h);
  // False (out untouched) when the sizes differ from configure()'s.
  bool scale(GrayView in, ImageView<std::uint8_t> out);
  // The same output from the input in pieces (a frame read in bands, never
  // whole): output rows [j_begin, j_end) of out from band, whose row 0 is
  // input row band_y0 and which holds every input row they need (input
  // rows [input_row_begin(j_begin), input_row_end(j_end - 1))). Rows done
  // band by band equal scale()'s. False (out untouched) otherwise.
  bool scale_rows(GrayView band, int band_y0, int j_begin, int j_end, ImageView<std::uint8_t> out);
  // The input rows output row j reads: [begin, end), both nondecreasing in
  // j, at most max_rows_per_output() of them.
  int input_row_begin(int j) const;
  int input_row_end(int j) const;
  int max_rows_per_output() const { return y_.taps; }

  int in_width() const { return in_w_; }
  int in_height() const { return in_h_; }
  int out_width() const { return out_w_; }
  int out_height() const { return out_h_; }

 private:
  // One axis: output j takes taps_ weights from input first_[j] on.
  struct Axis {
    int taps = 0;
    std::vector<std::int32_t> first;
    std::vector<std::uint16_t> weight;  // taps per output, 8-bit fixed point (sum 256)
  };
  static void make_axis(int in, int out, Axis* axis);
  int row_taps(int j) const;  // output row j's input rows, trailing zero weights dropped

  int in_w_ = 0, in_h_ = 0, out_w_ = 0, out_h_ = 0;
  Axis x_, y_;
  int period_in_ = 0, period_out_ = 0;  // the columns' pattern repeats every period_in_ inputs
  std::vector<std::uint16_t> row_;  // one output row before the columns: in_w_ (+8 spare)
};

// A 4:2:0 frame to a smaller size: the luma by one AreaScaler, the two
// chroma planes ((w + 1) / 2 x (h + 1) / 2 of each size) by another. The
// caller owns the output planes. Same threading as AreaScaler.
class FrameScaler {
 public:
  Status configure(int in_w, int in_h, int out_w, int out_h);
  static int chroma_size(int luma_size) { return (luma_size + 1) / 2; }

  // y into out_y (false when a size differs from configure()'s); u and v
  // into out_u and out_v when both are given and of the configured chroma
  // size (*chroma: whether they were).
  bool scale(GrayView y, GrayView u, GrayView v, ImageView<std::uint8_t> out_y, ImageView<std::uint8_t> out_u,
             ImageView<std::uint8_t> out_v, bool* chroma);
  AreaScaler& luma() { return luma_; }
  AreaScaler& chroma() { return chroma_; }

 private:
  AreaScaler luma_, chroma_;
};

}  // namespace st
