// OrbExtractor: the ORB frontend of the tracking thread.
//
//   OrbExtractor orb;
//   orb.configure(config, 1280, 720);            // allocates everything, once
//   per frame:
//   orb.extract(luma, organ_mask, valid_mask, features);  // allocates nothing
//
// Pipeline per frame: pyramid (levels x scale_factor) -> FAST-9 per level at
// the strict threshold with scores -> keep corners inside the organ mask
// (grown or shrunk by organ_margin_px) and the valid mask (centre and all 16 FAST
// circle pixels) -> FAST at the relaxed threshold only in threshold cells
// without a strict corner (ORB-SLAM2's rule), as a cascade (halfway
// threshold, then relaxed) over the spreading cells where a weaker corner
// could still be kept, all its steps served by one FAST scan at the
// relaxed threshold
// -> spread to twice the level's target count
// with a grid (best FAST score per cell first, then second best, ...) ->
// Harris response (7x7) of those -> spread again by Harris response to the
// target (cv::ORB also ranks by Harris: it is more repeatable) -> intensity
// centroid angle -> 256-bit steered BRIEF on the smoothed level.
//
// Masks: any resolution whose size divides into the image size by an
// integer-or-not factor (1, 1/2, 1/4 of the image are the expected ones);
// non-zero = inside. Empty view = no restriction.
// Thread: the tracking thread; one instance per thread.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "core/features/fast9.h"
#include "core/features/feature_set.h"
#include "core/image/image.h"
#include "core/image/image_pyramid.h"
#include "core/image/mask_morphology.h"
#include "core/features/orb_descriptor.h"
#include "core/base/result.h"

namespace st {

struct OrbConfig {
  int n_features = 1500;          // total over levels, <= kMaxKeypoints
  int levels = 8;                 // <= kMaxPyramidLevels
  float scale_factor = 1.2f;
  int fast_threshold_strict = 20; // |I(circle) - I(centre)| on 8-bit luma
  int fast_threshold_relaxed = 7; // used in threshold cells where strict found nothing
  int threshold_cell_px = 32;     // threshold cell size, level pixels
  int edge_border_px = 16;        // no keypoint closer to a level's edge (patch radius 15 + 1)
  int organ_margin_px = 8;        // organ mask dilation (> 0) or erosion (< 0), level-0 pixels
  // Keep a keypoint only if its descriptor patch lies on the organ: 8
  // points on the circle of radius (kOrbPatchRadius + 1) x its level's
  // scale, in the organ mask (after the margin), besides the centre.
  bool organ_patch_inside = false;
  int min_spread_cell_px = 8;     // smallest spreading cell, level pixels
  // Spreading cells are sized to hold about this many of the level's target
  // over the allowed area. 1 = ORB-SLAM-like evenness (one per cell first),
  // larger = stronger corners win. Measured on warps of the real frame
  // (scopetrack-bench features): 1 -> repeatability 0.52, 8 -> 0.63, 400 -> 0.75 (cv::ORB 0.78);
  // the default keeps repeatability; the relaxed-threshold cells still give
  // weak areas some corners.
  int spread_cell_keypoints = 400;
  // Detect and describe on the frame through a 3x3 binomial filter
  // (ImagePyramid::build_levels): sensor noise and compression blocks make
  // corners of their own that no other frame repeats.
  bool denoise = false;
};

// Per-frame result counters (diagnostics; no allocation).
struct OrbFrameStats {
  int fast_corners = 0;     // after non-maximum suppression, all levels
  int masked_corners = 0;   // after the organ/valid masks
  int kept_corners = 0;     // after the strict/relaxed cell rule
  int threshold_raises = 0; // scans redone at a higher threshold: the level's corners filled the arrays
};

class OrbExtractor {
 public:
  // Allocates the pyramid, FAST row buffers, candidate arrays (capacity from
  // the level-0 size, at most kMaxLevelCorners) and mask scratch. Checks
  // the config against capacity.h.
  Status configure(const OrbConfig& config, int width, int height);

  // Detects and describes keypoints of image (width x height as configured)
  // into out (keypoints in level-0 pixels). Allocates nothing. Returns false
  // (and out.count = 0) if the image size does not match the configuration
  // or a mask is larger than kMaxImageWidth x kMaxImageHeight.
  bool extract(GrayView image, GrayView organ_mask_or_empty, GrayView valid_mask_or_empty,
               FeatureSet& out);

  // Scales the FAST thresholds of the next extract() calls by s (clamped to
  // [0, 1]; NaN: 1): the strict and relaxed thresholds become round(t * s), at least
  // kMinStrictThreshold and kMinRelaxedThreshold. For dim frames, where every
  // intensity difference shrinks with the light (see TrackerConfig::
  // fast_reference_luma). 1 (the default) = the configured thresholds.
  void set_threshold_scale(float s);
  // Turns OrbConfig::denoise on or off for the next extract() calls (no
  // allocation: the filter's buffer is made by configure() either way).
  void set_denoise(bool on) { config_.denoise = on; }
  float threshold_scale() const { return threshold_scale_; }
  int strict_threshold() const { return strict_threshold_; }    // in use
  int relaxed_threshold() const { return relaxed_threshold_; }  // in use
  static constexpr int kMinStrictThreshold = 5;
  static constexpr int kMinRelaxedThreshold = 2;
  // Corners one FAST scan of a level may hold (the candidate arrays' size,
  // 38 bytes a corner). 3x3 suppression leaves at most one corner per 2x2
  // pixels (230,464 at 1280x720: 8.8 MB), but frames hold far fewer: at
  // most 20,081 in a level's scan over the simulator's scenarios, photo
  // texture, smoke and smooth tissue at 1280x720. A scan that fills it
  // (noise, heavy compression blocks) is redone at a higher threshold
  // (OrbFrameStats::threshold_raises), so the level's corners never come
  // from its top rows alone.
  static constexpr int kMaxLevelCorners = 65536;
  static constexpr int kMaxScanThreshold = 200;

  const OrbConfig& config() const { return config_; }
  const ImagePyramid& pyramid() const { return pyramid_; }
  const OrbFrameStats& stats() const { return stats_; }
  int level_target(int level) const { return level_target_[level]; }
  float scale(int level) const { return pyramid_.scale(level); }

 private:
  struct Candidate {
    std::uint32_t cell;   // threshold cell, then spreading cell index
    float key;            // what spreading ranks by (FAST score, then Harris response)
    std::uint16_t x, y;   // level pixels
    std::uint8_t score;   // FAST score
  };
  void prepare_masks(GrayView organ, GrayView valid);
  bool patch_on_organ(float x0, float y0, float scale) const;
  void block_any_all(GrayView mask, std::uint8_t* any, std::uint8_t* all);
  void mark_full_blocks();
  void organ_block_depths(const std::uint8_t* organ_all);
  void build_chunk_map(int level);
  bool inside_masks(int level, int x, int y) const;
  int detect_bounded(GrayView img, int threshold, const std::uint8_t* allowed, int chunks);
  int filter_strict(int level, int n_fast);
  int spread_cell_px(int level, int target) const;
  bool close_spread_cells(int level, int n, int target);
  void build_relaxed_chunk_map(int level);
  int filter_relaxed(int level, int n_fast, int n, int min_score, int max_score);
  int spread(int level, int n, int target);
  void harris_keys(int level, int n);
  void smooth_patches(int level, int n);
  void describe(int level, int n, FeatureSet& out);

  OrbConfig config_;
  ImagePyramid pyramid_;
  Fast9Detector fast_;
  OrbDescriptor descriptor_;
  std::array<int, kMaxPyramidLevels> level_target_{};
  std::vector<FastCorner> fast_out_;
  std::vector<Candidate> cand_;
  std::vector<Candidate> cand_tmp_;          // spread(): candidates bucketed by cell
  std::vector<std::uint8_t> cell_has_strict_;
  std::vector<std::uint8_t> organ_margined_;  // organ mask grown or shrunk by the margin (mask resolution)
  MorphBuffers organ_morph_;
  std::vector<std::uint8_t> block_ok_;       // per 16x16 level-0 block: [0] any allowed pixel,
                                             // [1] all allowed, [2] neighbourhood fully allowed, [3..4] scratch
  std::vector<std::uint8_t> organ_depth_;    // per block: blocks to the nearest one not wholly organ
  std::vector<std::int32_t> span_rows_, span_cols_;  // block_any_all(): mask span per block row / column
  std::vector<std::uint8_t> row_max_, row_min_;      // block_any_all(): one block row of the mask reduced
  std::vector<std::uint8_t> chunk_ok_;       // per level: rows x 16-pixel chunks
  std::vector<std::uint8_t> chunk_relaxed_;  // chunks the relaxed pass scores (same layout)
  std::vector<std::uint8_t> smooth_tiles_;   // per level: 32x32 tiles that need smoothing
  std::vector<std::uint8_t> cell_need_;      // per threshold-cell row x chunk: any cell without strict
  std::vector<std::int32_t> rank_count_;     // spread(), close_spread_cells(): cells per corner count
  std::vector<std::int32_t> spread_count_;   // per spreading cell: strict corners (spread(): bucket fill)
  std::vector<std::int32_t> spread_begin_;   // spread(): first bucket index per cell, + end
  std::vector<std::uint8_t> spread_open_;    // per spreading cell: a relaxed corner could still be kept
  std::vector<std::uint8_t> spread_open_chunks_;  // per 16-pixel chunk of one row: touches an open cell
  std::array<int, 2> relaxed_cascade_{};     // thresholds of the relaxed passes, descending
  float threshold_scale_ = 1.f;
  int strict_threshold_ = 20, relaxed_threshold_ = 7;  // the configured ones, scaled
  int relaxed_cell_px_ = 0;                  // spreading cell size of the closed map (0: all open)
  GrayView organ_;                           // organ mask of this frame with the margin (or empty)
  GrayView valid_;                           // valid mask of this frame (or empty)
  int blocks_x_ = 0, blocks_y_ = 0;
  float allowed_fraction_ = 1.f;             // share of level-0 blocks allowed this frame
  bool use_chunks_ = false;                  // any mask given this frame
  int width_ = 0, height_ = 0;
  OrbFrameStats stats_;
};

}  // namespace st
