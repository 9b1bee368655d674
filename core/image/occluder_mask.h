// OccluderMaskBuilder: where a surgical instrument may lie in front of the
// organ, from colour. The organ mask (the mesh projected) cannot exclude an
// instrument: it lies inside the organ's outline. On smooth tissue its
// strong edges give many keypoints, keyframes turn them into map points
// with the mesh's depth behind them, and the pose follows the instrument
// (docs/design-notes.md, "The occluder mask").
//
// Physics: instruments are steel or black/grey plastic, so their colour is
// near-neutral; tissue (liver red-brown, fat yellow, muscle red) is
// strongly coloured. In gamma-encoded Y'CbCr the chroma vector of a surface
// scales with its luma when the light changes (both are differences of the
// same gamma-encoded R'G'B'), so the ratio
//     |chroma| / (Y' - black) = sqrt((U - 128)^2 + (V - 128)^2) / (Y' - black)
// describes the surface, not the light. A chroma pixel is an occluder
// candidate when
//  - that ratio is at most max_chroma_ratio;
//  - |chroma| itself is at most max_chroma: a specular reflection adds the
//    light's white to a coloured surface, which lowers its ratio (more luma)
//    but keeps most of its chroma, so a glow on tissue passes the ratio and
//    fails this, where a grey surface passes both;
//  - its 2x2 luma block is bright enough for the chroma to be more than
//    noise (mean >= min_luma; this also keeps the black field-stop border
//    out) and holds no saturated highlight (max_luma; white whatever the
//    surface, and core/image/valid_mask removes highlights already).
// Calibrated on the real frame of shared/data (docs/design-notes.md): liver and fat have
// ratios of 0.21-0.34 at their 1st percentile, 0.39-0.51 median, so 0.12
// leaves them unflagged with a factor ~2 to spare, while a grey surface
// tinted by the tissue around it (ratio ~0.06-0.1) stays below. The
// simulator's organ glows have |chroma| 8-20 at ratios under 0.12, its
// steel instrument 0-6.
//
// In integers (every path computes exactly this; m = block mean luma):
//   du^2 + dv^2 <= max_chroma^2, m >= max(min_luma, black_luma), block max
//   < max_luma, (du^2 + dv^2) * 65536 <= round(ratio^2 * 65536) * (m - black)^2.
//
// Neutral tissue exists (a whitish gallbladder, grey-blue abdominal wall,
// white connective tissue): it is flagged too. That costs features there,
// never a wrong map point. Colourful instruments (blue or green plastic)
// are not flagged; a video without chroma (Cmono) gives no mask.
//
// The candidates are cleaned at chroma resolution: an opening by
// open_radius (removes specks: noise, glints, thin white vessels) and a
// dilation by margin_px (frame pixels) so that keypoints near the
// instrument's edge, whose descriptor patches would straddle it, go too.
// Cost at 1280x720: scopetrack-bench occluder (16 chroma pixels per SIMD
// step for the colour test; the morphology only over the rows that hold
// candidates).
//
// Resolution: 4:2:0 chroma, (width + 1) / 2 x (height + 1) / 2; luma is
// averaged over each chroma pixel's 2x2 block (JPEG/MPEG-2 siting alike at
// this resolution). Non-zero = occluder.
//
// configure() allocates; build() allocates nothing. Tracking thread.
#pragma once

#include <cstdint>
#include <vector>

#include "core/image/image.h"
#include "core/image/mask_morphology.h"
#include "core/base/result.h"

namespace st {

struct OccluderMaskConfig {
  float max_chroma_ratio = 0.12f;  // |chroma| / (Y' - black_luma) at most this: near-neutral (< 1)
  int max_chroma = 10;             // and |chroma| at most this (8-bit Cb/Cr units, <= 127): a
                                   // specular glow on tissue lowers the ratio, not the chroma
  int black_luma = 16;             // Y' of black: 16 in limited-range video (most); for full
                                   // range 16 only makes dark pixels look more coloured (safe)
  int min_luma = 40;               // darker blocks (mean): chroma is mostly noise, never flagged
  int max_luma = 230;              // a block with a luma pixel at or above this is a highlight
  int open_radius = 1;             // opening radius, chroma pixels (0: no speck removal)
  int margin_px = 8;               // dilation after the opening, frame pixels
};

class OccluderMaskBuilder {
 public:
  // Frame size in luma pixels (the chroma planes are expected at half of it,
  // rounded up). Sizes every buffer.
  Status configure(const OccluderMaskConfig& config, int width, int height);

  // The occluder mask of one frame at chroma resolution, valid until the next
  // build(). Empty view (no mask, nothing flagged) if either chroma plane is
  // empty (a Cmono video, a caller without chroma) or any plane's size does
  // not match the configuration. Allocates nothing.
  GrayView build(GrayView luma, GrayView u, GrayView v);

  GrayView mask() const { return GrayView(mask_.data(), mask_w_, mask_h_, mask_w_); }
  int mask_width() const { return mask_w_; }
  int mask_height() const { return mask_h_; }
  // Last build(): chroma pixels that passed the colour test (before the
  // cleaning) and that the returned mask flags (after the opening and the
  // margin). 0 when build() gave no mask.
  int candidate_pixels() const { return candidates_; }
  int flagged_pixels() const;  // counts (not for the hot path)

 private:
  struct RowPointers {
    const std::uint8_t *r0, *r1, *u, *v;  // luma rows 2y and 2y + 1, chroma row y
    std::uint8_t* out;
  };
  int test_span(const RowPointers& p, int x0, int x1) const;
  // The same test 16 pixels at a time (SIMD) from x = 0 while their blocks
  // lie inside the frame; *x_end: where it stopped (0 without SIMD).
  int test_row_simd(const RowPointers& p, int* x_end) const;
  void mark_candidates(GrayView luma, GrayView u, GrayView v);
  OccluderMaskConfig config_;
  int width_ = 0, height_ = 0, mask_w_ = 0, mask_h_ = 0;
  std::uint32_t ratio2_q16_ = 0;  // round(max_chroma_ratio^2 * 65536)
  int max_chroma2_ = 0;           // max_chroma^2
  int min_luma_ = 0;              // max(min_luma, black_luma)
  std::vector<std::uint8_t> candidates_buf_, eroded_, mask_;
  MorphBuffers morph_;
  int candidates_ = 0;
  int first_row_ = 0, last_row_ = -1;  // last build(): rows holding candidates
};

// out = valid where occluder is zero, else 0, over valid's size (out must be
// at least as large); occluder is read at the same pixel indices and may be
// larger (the chroma resolution rounds up) or smaller (then the rest is
// copied). Used by the tracker at the valid mask's resolution (1/2, the
// chroma's). Returns how many valid pixels it removed. Allocates nothing.
int remove_occluders(GrayView valid, GrayView occluder, ImageView<std::uint8_t> out);

}  // namespace st
