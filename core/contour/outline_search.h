// OutlineSearch: where the organ is when nothing local can say so: its
// silhouette seen from every side, matched against the frame's organ
// colours.
//
// Why: after the organ left the view, or after a swing onto tissue no
// keyframe has seen, the tracker's guess (dead reckoning) can be tens of
// degrees and millimetres off, out of reach of every local search (features
// by projection, the outline's lines, the shading). The organ's silhouette
// is its own global evidence: the mesh says what it looks like from every
// side, the colour models learnt along the outline say which pixels of the
// frame are the organ.
//
// Method:
//  - configure() renders the mesh's silhouette from kDirections viewing
//    directions spread evenly over the sphere (a Fibonacci lattice, about
//    13 deg apart), the organ centred and whole in view, on a small grid of
//    kGridWidth pixels across; each is kept as a bitmap with its area,
//    centroid and second moments.
//  - learn() keeps colour histograms of the whole organ and of everything
//    else in view (RegionModality's bins), from a reported frame and the
//    mesh rendered at its pose; cells the outline crosses are left out. The
//    outline's own models are learnt along its lines only, where the organ
//    is darker than its middle: under them most of the organ's face reads
//    as unknown.
//  - search() turns the frame into P(organ) on the same grid (averaged
//    over 2x2 samples a cell; cells outside the valid mask carry no
//    evidence) and takes the organ's area, centroid and principal axis. Each template is brought onto it by the
//    2D similarity that matches area and centroid, at the rotations that
//    align the principal axes (two, or eight where either shape is nearly
//    round), and scored by the log-likelihood of the frame's P(organ)
//    under that silhouette, per valid cell.
//  - The best candidates of directions at least kSeparationDeg apart
//    become camera poses: the
//    template's camera turned about its axis by the rotation, moved along
//    it by the scale, and turned so that the organ's centre lies on the ray
//    of its matched position. They are guesses for the outline's local fit
//    (RegionModality::estimate), never reported as they are.
// The search needs most of the organ in view: a frame the organ fills
// (over kMaxAreaFraction of the valid cells) or hardly touches (under
// kMinAreaFraction) is not searched.
//
// configure() allocates; search() allocates nothing. Tracking thread.
#pragma once

#include <cstdint>
#include <vector>

#include "core/base/result.h"
#include "core/contour/region_modality.h"
#include "core/geometry/camera.h"
#include "core/geometry/se3.h"
#include "core/image/image.h"
#include "core/mesh/mesh.h"
#include "core/raster/rasterizer.h"

namespace st {

struct OutlineCandidate {
  SE3 T_camera_model;
  double score = 0;     // mean log-likelihood per scored valid cell (higher is better; 0 at best)
};

struct OutlineSearchStats {
  int valid_cells = 0;
  double organ_fraction = 0;  // cells with P(organ) > 1/2, of the valid ones
  int candidates_scored = 0;
  bool searched = false;      // the frame had a silhouette to match
};

class OutlineSearch {
 public:
  static constexpr int kDirections = 256;
  static constexpr int kGridWidth = 96;
  static constexpr int kScoreStride = 2;  // candidates are scored on every second cell across and down
  static constexpr int kMaxCandidates = 4;
  static constexpr double kMinAreaFraction = 0.03;
  static constexpr double kMaxAreaFraction = 0.85;
  static constexpr double kSeparationDeg = 30.0;  // between the viewing directions of two candidates

  // K: the frame's ideal pinhole (its size is the frame's).
  Status configure(const Mesh& mesh, const Pinhole& K);
  bool configured() const { return configured_; }

  // Learns the colour models from a frame and the mesh rendered at its
  // pose (raster: any render at the frame's pose, of any downscale),
  // blended in with `rate` (the first learn sets them). Frames with too
  // few cells of either side are skipped.
  void learn(GrayView luma, ChromaView chroma, GrayView valid, const MeshRasterizer& raster, float rate);
  void reset();  // forgets the colour models (a new run)
  bool has_colour_model() const { return model_ready_; }

  // Up to `capacity` (at most kMaxCandidates) candidates, best first, of
  // different viewing directions. 0 when the colour model is not ready or
  // the frame shows no silhouette to match.
  int search(GrayView luma, ChromaView chroma, GrayView valid, OutlineCandidate* out, int capacity);
  const OutlineSearchStats& stats() const { return stats_; }

  const Vec3& centre() const { return centre_; }  // of the mesh's bounding box

 private:
  struct Shape {
    double area = 0, cx = 0, cy = 0, mu20 = 0, mu11 = 0, mu02 = 0;
    double angle() const;
    double elongation() const;  // ratio of the principal second moments (>= 1)
  };
  // Area, centroid and second moments of a set of grid cells.
  struct Moments {
    double m00 = 0, m10 = 0, m01 = 0, m20 = 0, m11 = 0, m02 = 0;
    void add(int x, int y);
    Shape shape() const;  // needs m00 > 0
  };
  // The template camera of a direction: the organ's centre on the optical
  // axis at the reference distance.
  SE3 template_pose(int direction) const;
  struct Kept {
    double score = -1e300;
    int direction = -1;
    double rotation = 0, scale = 0;
  };
  double score(int direction, double rotation, double scale) const;
  SE3 pose_of(const Kept& k) const;

  // f(x, y) for each of a grid cell's 2x2 sample pixels in the valid mask.
  template <class F>
  void for_cell_samples(int x, int y, GrayView valid, F&& f) const;

  bool configured_ = false, model_ready_ = false;
  int w_ = 0, h_ = 0, words_ = 0;
  std::vector<float> fg_, bg_, fg_new_, bg_new_;  // colour histograms (RegionModality::kBins, sum 1 each)
  Pinhole K_, K_grid_;
  Vec3 centre_ = Vec3::Zero();
  double d_ref_ = 0;
  const Vec3& direction(int d) const { return dirs_[static_cast<std::size_t>(d)]; }

  std::vector<Mat3> R_dir_;           // model -> template camera rotation per direction
  std::vector<Vec3> dirs_;            // unit, organ centre -> template camera
  std::vector<Kept> kept_;            // search(): each direction's best rotation
  std::vector<Shape> shapes_;         // per direction
  std::vector<std::uint64_t> bits_;   // kDirections x words_: template silhouettes
  std::vector<float> l_in_, l_out_;   // per cell: log P(organ), log (1 - P(organ)); 0, 0 where not valid
  std::vector<std::int32_t> cells_;   // valid cell indices of this frame
  int scored_cells_ = 0;  // valid cells of this frame that candidates are scored on
  Shape frame_;
  OutlineSearchStats stats_;
};

}  // namespace st
