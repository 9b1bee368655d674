// DirectAligner: 6-DoF dead reckoning from image intensities and the
// organ mesh's depth, for the frames that feature tracking cannot use.
//
// Why: under a fast swing the frames are smeared over tens of pixels and
// ORB matching finds nothing (the features, not the prediction, fail), so
// the tracker is lost. If its guess drifts by more than the search radius
// while the swing lasts, it cannot pick the organ up again where the swing
// stops, and a swing into tissue no keyframe has seen is never recovered
// (fast seed 2: 69 % lost). The small blurred images of ImageMotion (1/8
// of the frame) barely change under that smear, and the mesh rendered at
// the reference frame's pose gives every small pixel on the organ a metric
// depth: direct image alignment (as in direct visual odometry) of the
// current small image against the reference one then measures the full
// camera motion, translation included (a shift-and-roll model does not).
//
// Method: the reference keeps a copy of its frame at about 320 pixels
// wide (an ORB pyramid level), its valid mask and its pose. align() builds
// a pyramid of both images (halving while at least 32 pixels wide, up to 4
// levels); every level loses its local mean (a 5x5 box):
// the light rides on the scope, so the organ's shading changes as it moves
// while the texture moves with the surface, and shading alone pulled the
// alignment off by tens of pixels. It picks the reference pixels on the
// organ with the strongest gradient (one per cell, the cell sized so that
// at most kMaxPoints remain), back-projects them with the render's depth,
// and minimises the Huber-weighted intensity differences in the current
// image over the camera motion plus an affine brightness change (auto
// exposure) by Levenberg-Marquardt, coarse to fine. Measured on the
// simulator's fast swing at 640x360 (tests/test_direct_alignment.cpp): a
// 320-pixel image aligns each smeared frame to its predecessor within
// 0.4 px, a 1/8 image (80 pixels) only within 3-10 px.
// The result is a pose estimate for dead reckoning, never a reported pose:
// the tracker stays `lost` until features confirm it.
//
// configure() allocates; keep_reference() and align() allocate nothing.
// Tracking thread.
#pragma once

#include <cstdint>
#include <vector>

#include "core/geometry/camera.h"
#include "core/image/image.h"
#include "core/raster/rasterizer.h"
#include "core/base/result.h"
#include "core/geometry/se3.h"

namespace st {

struct DirectAlignSummary {
  int points = 0;        // reference points with depth at the returned level
  int used = 0;          // of those, inside the current image at the end
  int iterations = 0;    // over all levels
  // Median |residual| of the points in view at the estimate, on the
  // returned level (intensity / the reference's mean, after the local mean
  // is taken out): how well the estimate explains the image. Comparable
  // between alignments of the same image to the same reference from
  // different starts at the same level (a wrong basin leaves larger
  // residuals).
  double residual_median = 0;
  double gain = 1;  // the estimate's contrast change (current ~ gain * reference + offset)
  int level = 0;    // the level whose estimate was returned (0: the finest)
  // The pose's information at the estimate: J^T W J of the pose over the
  // points (the brightness change eliminated), divided by the squared
  // robust residual scale, in the tangent [omega (rad); v (mm)] of the
  // left perturbation. Pixels of the small blurred image are not
  // independent: a caller that fuses it scales it down.
  Mat6 information = Mat6::Zero();
};

// The planes an alignment works in besides its reference's: the current
// image's levels and valid masks, their gradients and a scratch plane.
// Nothing in them outlives one align() or one reference build, so aligners
// used one after another on one thread share one (the tracker's three at
// 1280x720: one of 1.6 MB instead of three). configure() allocates.
class DirectAlignScratch {
 public:
  Status configure(int width, int height);  // the finest level's size, as the aligners'

 private:
  friend class DirectAligner;
  std::vector<float> planes_;        // per level: current image, scratch, x and y gradients
  std::vector<std::uint8_t> masks_;  // per level: the current image's valid mask
  int width_ = 0, height_ = 0;
};

class DirectAligner {
 public:
  DirectAligner() = default;
  DirectAligner(const DirectAligner&) = delete;  // its levels point into its scratch
  DirectAligner& operator=(const DirectAligner&) = delete;

  static constexpr int kMaxPoints = 4096;
  static constexpr int kLevels = 4;          // at most
  static constexpr int kMinLevelWidth = 32;  // coarser levels while at least this wide
  static constexpr int kMinPoints = 50;      // reference points on the organ needed at each level
  static constexpr int kTargetWidth = 320;   // the finest level's width to aim for (see choose_level)
  // An estimate whose contrast gain left [kMinGain, kMaxGain] is refused.
  // The gain is how much of the reference's texture the current image shows
  // at the estimate: blur lowers it (0.33-0.89 over the simulator's lost
  // frames: smeared liver, photo liver and stomach), a sharp frame after a
  // smeared reference raises it. Near 0 the points sit on tissue that does not match them
  // and the gain "explains" the difference away, with a small residual: a
  // wrong basin (the simulated stomach's fast swing: 0.04, the organ 10-22
  // px off) or a run-away chain (0.04 at 922 mm off).
  static constexpr double kMinGain = 0.2;
  static constexpr double kMaxGain = 5.0;

  // Of an image pyramid whose level k is widths[k] wide, the level to
  // align on: the one closest to kTargetWidth.
  static int choose_level(const int* widths, int levels);

  // width x height: the images handed over (an ImagePyramid level), scale:
  // full-resolution pixels per pixel (x_full = (x + 0.5) scale - 0.5).
  // shared: a scratch configured for width x height that other aligners of
  // this thread use too (it must outlive this one); null: one of its own.
  Status configure(int width, int height, double scale, DirectAlignScratch* shared = nullptr);
  // The reference: the image, the frame's valid mask (any resolution up to
  // the frame's, 0 = unusable: field stop, highlights; may be empty) and
  // the pose of its frame. Copied; the caller's buffers may change
  // afterwards. A reference with no valid pixel fails at align().
  void keep_reference(GrayView image, GrayView valid, const SE3& T_camera_model);
  void forget_reference() { have_reference_ = false; }
  bool has_reference() const { return have_reference_; }
  const SE3& reference_pose() const { return T_reference_; }

  // Aligns the current small image to the reference. raster must hold a
  // render at reference_pose() (its depth gives the reference points);
  // camera is the full-resolution camera (distortion applied when
  // projecting). *T_camera_model: in, the guess; out, the estimate (only
  // when true is returned: enough points stayed in view and converged,
  // and the contrast gain stayed within [kMinGain, kMaxGain]).
  // allow_coarser: if the finest level's estimate fails those checks, the
  // last coarser level's that passed them is returned instead (summary's
  // level says which). Motion blur takes the fine levels' texture first:
  // on a fast swing over photo-textured tissue the most blurred frame's
  // finest-level gain fell to 0.06-0.09 against the previous frame while
  // the next coarser level's stayed in range.
  bool align(GrayView image, GrayView valid, const MeshRasterizer& raster,
             const CameraModel& camera, SE3* T_camera_model, DirectAlignSummary* summary = nullptr,
             bool allow_coarser = false);

 private:
  struct Level {
    int w = 0, h = 0;
    double scale = 0;  // full-resolution pixels per pixel
    std::vector<float> ref;
    std::vector<std::uint8_t> ref_mask;
    // In the scratch (DirectAlignScratch), w x h each.
    float *cur = nullptr, *gx = nullptr, *gy = nullptr, *tmp = nullptr;
    std::uint8_t* cur_mask = nullptr;
  };
  void sample_valid(GrayView valid, std::uint8_t* mask);  // sample_mask(), then erode_mask()
  void sample_mask(GrayView valid, std::uint8_t* mask);
  void erode_mask(std::uint8_t* mask);
  bool build_reference();
  void build_half(Level* half, const Level& full, bool reference);
  void gradients(Level* l);
  void high_pass(Level* l, bool reference);
  static constexpr int kHighPassRadius = 2;
  int select_points(const Level& l, const MeshRasterizer& raster, const CameraModel& camera);
  bool solve_level(const Level& l, int n, const CameraModel& camera, SE3* T, double* a, double* b,
                   DirectAlignSummary* s);

  Level levels_[kLevels];
  DirectAlignScratch own_scratch_;  // when configure() is given none
  int levels_used_ = 1;
  bool configured_ = false, have_reference_ = false, reference_built_ = false;
  SE3 T_reference_;
  float inv_scale_ = 1.f;  // 1 / the reference's mean intensity (both images are scaled by it)
  // The reference as handed over: its image and its valid mask sampled
  // at the finest level (sample_mask()); the levels are built from them
  // when align() needs them.
  std::vector<std::uint8_t> ref_image_, ref_valid_;
  std::vector<std::int32_t> valid_col_;  // sample_mask's column table (finest level's width)
  std::size_t max_valid_pixels_ = 0;     // the largest valid mask accepted (the frame's size)
  // Reference points of the level being solved: model coordinates and intensity.
  std::vector<Vec3> p_model_;
  std::vector<double> intensity_;
  std::vector<double> residuals_;  // scratch for the robust scale
};

}  // namespace st
