// RegionModality: the organ's outline as a measurement of the camera pose,
// for tissue without corners.
//
// Why: real liver is smooth and glossy; its few corners are noise and
// highlights, so feature tracking is lost on it. Its outline against fat,
// bowel and the abdominal wall is a strong colour edge that the registered
// mesh predicts exactly. Region-based trackers of textureless objects
// (RBOT, SRT3D, ICG/M3T of DLR) track from that edge alone.
//
// Method (a sparse region modality in the manner of SRT3D/ICG):
//  - The mesh is rendered at the current pose (its own rasteriser, about
//    480-640 pixels wide). Its silhouette pixels that lie away from the
//    image border give up to kMaxLines correspondence lines: a centre on
//    the outline (half a raster pixel outwards from the last organ pixel,
//    so the quantised silhouette does not pull the outline inwards), the
//    outward normal (from the mask's local moments) and the model point
//    there (render depth).
//  - Along each line the frame's colour (Y at 8 levels; U and V as ratios
//    to the luma above black, (C - 128) / max(Y - 16, 16), at 16 levels
//    over [-0.75, 0.75]: a surface's chroma falls with its luma, so the
//    organ's rim, darkened where the surface turns away from the light,
//    keeps the organ's hue instead of looking like grey background) is read at
//    2 kHalfLength + 1 steps; the organ's and the background's colour
//    histograms, learnt online along the lines at tracked poses, turn each
//    sample into P(organ). The outline's position
//    on the line then has a discrete posterior (every split of the line
//    into organ inside, background outside); its mean and variance are the
//    line's measurement and its noise.
//  - Samples outside the image or outside the valid mask (the field stop,
//    specular highlights, instruments taken out by the occluder mask) carry
//    no evidence; a line with too few valid samples is dropped. The mask's
//    outline is organ against non-organ only: where the organ occludes
//    itself (a fold) both sides have the organ's colour, and no line is
//    placed there.
//  - The residual of a line is the projected model point's offset along the
//    normal minus the measured position, whitened by the measured variance;
//    linearize() gives its fixed-size 6x6 normal equations at any pose, so
//    that it joins the other modalities in one pose problem. estimate()
//    runs it alone, coarse to fine (line steps 4, 2, 1, 1 x the base step,
//    rendering again before each: the outline slides over the surface as
//    the pose changes, so its model points are taken again).
//
// configure() allocates; everything else allocates nothing. Tracking
// thread.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "core/base/result.h"
#include "core/geometry/camera.h"
#include "core/geometry/se3.h"
#include "core/image/image.h"
#include "core/mesh/mesh.h"
#include "core/raster/rasterizer.h"

namespace st {

// What the last measure() / estimate() saw.
struct ContourFit {
  int lines = 0;            // correspondence lines measured (valid, informative)
  int candidates = 0;       // silhouette lines placed before the validity tests
  double rms_px = 0;        // RMS of the lines' offsets at the pose (level-0 px)
  double chi2_per_line = 0; // mean whitened squared residual at the pose
  // How well the colour models tell the organ from its surroundings on this
  // frame's lines: mean |P(organ) - 1/2| x 2 over the valid samples
  // (0: no distinction, 1: perfect).
  double separation = 0;
};

class RegionModality {
 public:
  static constexpr int kMaxLines = 240;
  static constexpr int kHalfLength = 10;      // samples on each side of the centre
  static constexpr int kSamples = 2 * kHalfLength + 1;
  static constexpr int kBins = 8 * 16 * 16;  // Y at 3 bits, U and V ratios at 4 bits each

  // width x height: the frame. The mesh is copied into the modality's own
  // rasteriser.
  Status configure(const Mesh& mesh, int width, int height);
  // Forgets the colour models (a new run).
  void reset();
  bool has_colour_model() const { return model_ready_; }

  // Renders at T, places the lines and measures the outline along them with
  // steps of step_factor x the base step (frame width / 640 pixels rounded
  // down, at least 1). Needs the colour model. Returns the number of lines measured.
  int measure(GrayView luma, ChromaView chroma, GrayView valid, const CameraModel& camera, const SE3& T,
              int step_factor);
  // Normal equations of the measured lines at pose T (left perturbation
  // [omega; v], as PoseSolver), Huber-weighted; adds into *H, *g and returns
  // the cost 1/2 sum rho. Lines whose point is behind the camera are skipped.
  double linearize(const SE3& T, Mat6* H, Vec6* g) const;
  // Cost only (same terms as linearize).
  double cost(const SE3& T) const;
  // Fills *fit for the measured lines at pose T.
  void evaluate(const SE3& T, ContourFit* fit) const;

  // The pose from the outline alone, from *T (in: the guess; out: the
  // estimate when true). True when every pass measured at least min_lines
  // lines and the solve stayed finite.
  bool estimate(GrayView luma, ChromaView chroma, GrayView valid, const CameraModel& camera, SE3* T,
                ContourFit* fit, int min_lines = 30);

  // Learns the colour models from lines placed at pose T (a pose the
  // tracker reports; one render) at the base step: samples more than 1.5
  // steps inside the outline are the organ's, more than 1.5 steps outside
  // the background's. Blended in with rate `rate` (the first learn sets
  // them).
  void learn(GrayView luma, ChromaView chroma, GrayView valid, const CameraModel& camera, const SE3& T,
             float rate = 0.2f);

  const MeshRasterizer& raster() const { return raster_; }

  // The colour bin (of kBins) of the frame's pixel (x, y): Y at 3 bits, the
  // chroma ratios at 4 bits each.
  static int colour_bin(GrayView luma, ChromaView chroma, int x, int y);
  // P(organ) of a colour with weights f and g in the organ's and the
  // background's histograms, kept within [0.05, 0.95] (one sample of a
  // colour seen only on one side must not decide a line alone).
  static double organ_probability(double f, double g);

 private:
  struct Line {
    Vec3 p_model;    // the model point on the outline at the render
    Vec2 centre;     // ideal pixel of the outline at the render (level 0)
    Vec2 normal;     // unit outward normal, ideal image
    Vec2 centre_d;   // distorted pixel of the centre
    Vec2 dir_d;      // unit direction of the line in the distorted image
    double scale_d;  // distorted px per ideal px along the normal
    double mean = 0, var = 1;  // the outline's measured offset along the normal (ideal px) and its variance
    std::array<std::uint16_t, kSamples> bin{};
    std::uint32_t valid_bits = 0;
  };
  int place_lines(const CameraModel& camera, const SE3& T);
  void sample_lines(GrayView luma, ChromaView chroma, GrayView valid, double step);
  int measure_lines(double step);
  double offset_of(const Line& l, const SE3& T, Eigen::Matrix<double, 1, 6>* J) const;

  MeshRasterizer raster_;
  bool configured_ = false, model_ready_ = false;
  int width_ = 0, height_ = 0;
  double base_step_ = 1;
  double last_step_ = 1;
  Pinhole K_;
  std::vector<Line> lines_;        // kMaxLines placed
  int placed_ = 0;                 // lines placed at the last render
  std::vector<std::uint8_t> used_; // per placed line: measured and informative
  std::vector<std::int32_t> silhouette_;  // scratch: silhouette pixel indices of the raster
  std::vector<float> fg_, bg_;           // colour histograms (sum 1 each)
  std::vector<float> fg_new_, bg_new_;   // scratch for learn()
  double separation_ = 0;
};

}  // namespace st
