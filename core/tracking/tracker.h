// Tracker: for every frame, the scope pose in the organ's (model) frame, or
// an honest `lost`. The paper's system on the rasteriser and the ORB
// frontend: prior-shape initialisation from the mesh depth at frame 0,
// pseudo-segmentation (features only inside the mesh projected at the
// predicted pose), a bounded map with points from the mesh depth at each
// keyframe, robust LM pose, relocalisation by P3P RANSAC when lost.
//
// Lifecycle: configure() (allocates every pool, once) -> start() -> step()
// per frame (allocates nothing, throws nothing, logs nothing) -> stop().
// Thread: the tracking thread. core/ has no clock: the caller injects one
// (TrackerConfig::now_ns) for the per-stage timings.
#pragma once

#include <array>
#include <cstdint>

#include "core/features/orb_extractor.h"
#include "core/features/orb_matcher.h"
#include "core/geometry/camera.h"
#include "core/mapping/ba_options.h"
#include "core/image/image.h"
#include "core/mesh/mesh.h"
#include "core/base/result.h"
#include "core/geometry/se3.h"
#include "core/tracking/modality_agreement.h"

namespace st {

enum class TrackState : std::uint8_t {
  kInitialised,  // frame 0 (or a restart): pose from T_camera_model_init, map built from the mesh
  kTracking,     // pose reported, passed every quality check
  kRelocalised,  // pose recovered by relocalisation this frame (stricter checks passed)
  kLost,         // no pose reported: the tracker is not sure
};
const char* to_string(TrackState s);

// Stage timings of one step, milliseconds (0 where the stage did not run).
enum class Stage : int { kScale, kPyramid, kOccluder, kRaster, kDetect, kDescribe, kMatch, kPose, kMap, kReloc, kContour, kTotal, kCount };
const char* to_string(Stage s);
using StageTimes = std::array<double, static_cast<int>(Stage::kCount)>;

// Every tunable of the tracker, one name per concept: the stages' own
// configs are held here, not copied field by field. The settings file
// (core/tracking/tracker_settings.h) names each key, its range and meaning.
struct TrackerConfig {
  int width = 0, height = 0;       // frame size = calibration size
  // The tracker's own frame width (the working resolution): a wider frame
  // is brought down to it by an area filter (core/image/area_scale.h), the
  // height in proportion, the calibration scaled with it; 0: the frame's
  // own. Every pixel setting below is in working pixels; the poses are the
  // same either way, and TrackResult's pixel figures are the frame's.
  // 1280: the 1280x720 that the tracker's settings were measured at, and
  // the speed the tower's 1080p60 and 4K60 need (docs/results.md,
  // "Working resolution").
  int working_width = 1280;
  // The ORB frontend (core/features/orb_extractor.h). The tracker's defaults
  // differ from the extractor's own in two places:
  // - organ_margin_px -4: the organ mask is eroded a little, since the prior
  //   and the predicted pose are never exact;
  // - organ_patch_inside: a keypoint is kept only if its descriptor patch
  //   (radius 16 px, times 1.2 per octave) lies on the organ. The organ's
  //   outline is an occluding contour: it slides over the surface as the
  //   view changes, and a patch that reaches across it describes the
  //   contour, not the tissue, so its map point pulls the pose towards
  //   where the contour was. On smooth tissue such keypoints are a large
  //   share and the map drifts until tracking is lost
  //   (docs/design-notes.md, "The organ's outline").
  // features.denoise (keypoints from the frame through a 3x3 binomial
  // filter) on forces the filter; off, denoise_noise_ratio decides it.
  OrbConfig features = [] {
    OrbConfig c;
    c.organ_margin_px = -4;
    c.organ_patch_inside = true;
    return c;
  }();
  // The filter follows the frame's noise: at initialisation, where the
  // organ's pixel-level contrast is at least this many times its contrast
  // between 4x4 blocks (FastThresholdScaler::organ_noise_ratio: about 4
  // for white noise, 1 or less for texture), the keypoints of the whole
  // run come from the filtered frame: there sensor noise makes corners of
  // its own that no other frame repeats, and the filter halves the losses
  // of noisy smooth tissue; where texture dominates the pixel level (a
  // photo texture at 640x360) the filter takes the detail the features
  // need (docs/results.md, "Keypoints from the filtered frame where noise
  // dominates", says why 2.5). 0: never.
  double denoise_noise_ratio = 2.5;
  // Pseudo-segmentation.
  bool use_mask = true;            // false: --no-mask ablation (whole valid image)
  int raster_downscale = 2;        // mask/depth raster at 1/2 resolution
  // The per-frame render (mask, depth for new map points, dead reckoning's
  // reference depth) uses the mesh simplified to at most this many
  // triangles (core/mesh/mesh_simplify.h): a segmentation exported as it is can
  // hold hundreds of thousands, and the render's cost grows with them. The
  // shape residual in BA and the texturing keep the mesh as given. 0: never
  // simplify.
  int max_raster_triangles = 40000;
  // Dim video: FAST thresholds are intensity differences, and every
  // difference shrinks with the light (gamma-encoded luma above black scales
  // with it). A frame whose median luma over the organ (the valid image
  // when there is no organ mask) is below this has its FAST thresholds
  // scaled by (median - 16) / (fast_reference_luma - 16), down to
  // OrbExtractor's floors (5 strict, 2 relaxed): the features of a dim
  // frame are those of the same scene lit brighter. At or above it, the
  // configured thresholds (ORB-SLAM's 20 / 7). 0 (or anything up to 16): off.
  double fast_reference_luma = 80.0;
  // A veiled view (surgical smoke, a fogged lens): the frame is bright but
  // its texture is flat, and every intensity difference FAST tests shrinks
  // with the veil. A frame whose organ texture contrast
  // (FastThresholdScaler::organ_contrast: the median difference of
  // neighbouring 4x4 block means, luma units) is below this has its FAST thresholds scaled by contrast /
  // fast_reference_contrast, as a dim frame is (the smaller scale wins).
  // Measured: the real liver frame 6.6 (at 1280x720), the simulator's
  // procedural texture 7-9, its real-photo texture 3.4-4.4 (smoother than the
  // real frame: the photo is magnified onto the organ), under its smoke
  // 1.9-3.4. 0: off.
  double fast_reference_contrast = 5.0;
  // Occluders: when step() is given chroma, near-neutral pixels (surgical
  // instruments: steel, black/grey plastic; core/image/occluder_mask.h) leave the
  // valid mask, with a margin: no keypoint there, hence no map point on an
  // instrument that lies in front of the organ (inside its mask) and moves
  // against it; direct alignment and the image-motion prior skip them too.
  // false: --no-occluder-mask ablation. Without chroma there is no mask.
  bool use_occluder_mask = true;
  // Map points take the descriptor (and angle, octave, distance, viewing
  // direction) of their latest keyframe inlier observation, not only of the
  // keyframe that made them (TrackerImpl::add_keyframe). false: the
  // creating observation's for good (--no-descriptor-refresh ablation).
  bool refresh_descriptors = true;
  // Bounded map.
  int max_keyframes = 48;          // <= kMaxKeyframes
  int max_map_points = 12000;      // <= kMaxMapPoints
  // Honest state: below any of these the frame is lost.
  int min_inliers = 30;
  double min_inlier_ratio = 0.35;  // inliers / matched correspondences
  double max_rms_px = 2.5;         // inlier reprojection RMS, ideal pixels, each residual scaled
                                   // by its octave's sigma (1.2^octave): level-0 pixels
  double min_mask_agreement = 0.9; // share of inliers inside the organ rendered at the final pose
  // Confirmed poses: on smooth, noisy tissue most ORB matches are wrong
  // (simulated invivo with half the organ detail: 30 % of a pose's matches
  // are inliers while its markers are 1 px from the truth), so a right pose
  // fails min_inlier_ratio. A pose that passes every gate but that one,
  // down to confirmed_min_inlier_ratio, is reported if direct alignment of
  // the frame against the last frame that passed the normal gates with an
  // inlier ratio of at least anchor_min_inlier_ratio (the anchor) puts the
  // organ within confirm_agreement_px of it (mean over the organ, level-0
  // px): two independent measurements agree. Such a frame never becomes
  // the anchor, and it adds a keyframe only if at least
  // confirmed_keyframe_min_anchored of its inliers are anchored points
  // (made by keyframes of normal-gate frames): a slow drift cannot extend
  // the map on its own. Needs use_image_motion; confirmed_min_inlier_ratio
  // >= min_inlier_ratio turns it off.
  double confirmed_min_inlier_ratio = 0.2;
  double confirm_agreement_px = 3.0;
  double anchor_min_inlier_ratio = 0.4;
  double confirmed_keyframe_min_anchored = 0.5;
  // Smooth tissue: when the features give no pose, the organ's outline
  // (core/contour/region_modality.h) and its shading (direct alignment
  // against the last reported frame, through the mesh's depth) each
  // measure it. The frame is reported only when the two agree
  // (core/tracking/modality_agreement.h): at least contour_min_lines
  // outline lines measured, the outline alone fixing the organ in view to
  // contour_max_sigma_px (1 sigma, RMS over the organ, level-0 px), the
  // outline's pose alone and the shading's pose alone putting the organ
  // within contour_agreement_px of each other, and the two together fixing
  // it to contour_max_joint_sigma_px. The reported
  // pose then minimises both (the shading's information scaled by
  // photometric_weight: its pixels are not independent). Such a frame
  // adds no keyframe.
  bool use_contour = true;
  int contour_min_lines = 40;
  double contour_max_sigma_px = 3.0;
  // The joint pose's uncertainty (the outline's information plus the
  // shading's, scaled by photometric_weight), 1 sigma as above; 0: not
  // tested (with contour_max_sigma_px 1.5: the gate before the joint test,
  // docs/design-notes.md).
  double contour_max_joint_sigma_px = 1.5;
  double contour_agreement_px = 6.0;
  double photometric_weight = 0.1;
  // The outline also checks weak feature poses: a pose that passed the
  // gates with fewer than contour_check_inliers inliers (a blurred frame,
  // the start of a swing) is lost if the outline, measured from it, puts
  // the organ more than contour_veto_px away, and more than 5 times its own
  // uncertainty (the features matched the wrong tissue).
  // contour_check_inliers 0: never.
  int contour_check_inliers = 90;
  double contour_veto_px = 20.0;
  // While lost, an outline that places the organ on its own (lines and
  // sigma as above) but lies farther than wide_radius_px from the shading's
  // pose (or the shading measured nothing) is a guess of its own: the
  // features are tracked from it (reported only under the stricter gates
  // of relocalisation), and when dead reckoning measured nothing it is the
  // next frame's guess.
  bool outline_guess = true;
  // While lost with no outline near the guess (too few lines, or not fixing
  // the organ to contour_max_sigma_px), the organ's silhouette is searched
  // over every viewing direction (core/contour/outline_search.h) and the
  // best candidates are fitted by the outline's lines; the best fit is a
  // guess of its own as above (the features tracked from it pass only the
  // stricter gates), and the next frame's dead reckoning and keyframe
  // order start from it.
  bool outline_search = true;
  // A candidate's features, tracked from its outline fit, are reported
  // under the stricter gates; or under the normal gates when their pose
  // lies within search_radius_px of the fit; or, within refine_radius_px,
  // with the normal gates' minimum inliers times this factor (2/3: 20 of
  // 30; smooth tissue at half detail gave 24-28 inliers at ratio 0.6,
  // 0.5-1.3 px from a fit 0.04-0.36 deg off).
  double outline_agreement_inlier_factor = 2.0 / 3.0;
  // Descriptor matching (core/features/orb_matcher.h): max_distance (of 256
  // bits), the ratio test, the orientation check.
  MatchConfig matching;
  // Search by projection (full-resolution pixels, scaled by the predicted octave's scale).
  float search_radius_px = 15.f;   // around the constant-velocity prediction
  float wide_radius_px = 45.f;     // second pass when the first gives too few matches
  float refine_radius_px = 5.f;    // local-map search again at the first solved pose
  // Implausible motion: a pose this far from the prediction is lost (generous on purpose).
  double max_jump_deg = 25.0;
  double max_jump_mm = 40.0;       // camera centre displacement
  // Keyframes: inserted when the tracked points fell below this share of the
  // reference keyframe's, or the view turned / travelled beyond these.
  double keyframe_tracked_ratio = 0.7;
  double keyframe_angle_deg = 10.0;
  double keyframe_distance_ratio = 0.1;  // camera travel / median inlier depth
  float keyframe_max_motion_px = 40.f;    // no keyframe from a frame whose view moved more than this
                                          // since the last one (level-0 px at the tracked depth): blurred
  // Relocalisation and the stricter gates after it.
  int reloc_keyframes_per_frame = 2;    // brute-force budget per lost frame
  int reloc_min_matches = 15;           // brute-force matches (and RANSAC inliers) to try a keyframe's pose
  int strict_frames = 5;                // frames after relocalisation under strict gates
  int dead_reckoning_frames = 10;       // lost: predict with the last velocity for this many frames
  double dead_reckoning_decay = 0.7;    // lost: the carried velocity's twist shrinks by this per frame
                                        // (a fast turn that broke tracking ends; 1: constant velocity)
  bool use_image_motion = true;         // rotation prior from the whole-image shift (core/motion/image_motion.h)
  double strict_inlier_factor = 1.5;    // min_inliers multiplier when strict
  int min_spread_cells = 3;             // strict: inliers must occupy this many cells of a 4x4 grid
  // Bundle adjustment (core/mapping/bundle_adjustment.h), run by the mapping side
  // given to Tracker::set_ba_channel(); without one there is no BA.
  bool use_ba = true;                   // false: no BA (ablation: no jobs handed out)
  // The window solver (core/mapping/ba_options.h): ba.w_shape is the shape
  // residual's weight (paper: 100; 0: reprojection only), ba.max_iterations
  // and ba.max_time_s bound a window solve, ba.prior_release_f is the F test
  // that frees frame 0 under the registration prior (below).
  BundleAdjusterOptions ba = [] {
    BundleAdjusterOptions o;
    o.max_time_s = 0.03;
    return o;
  }();
  int ba_window_keyframes = 8;          // newest keyframes optimised by a window BA (<= max_keyframes used)
  bool ba_global_after_reloc = true;    // a global BA over all keyframes after a relocalisation
  // Refining the first frame's registration. T_camera_model_init is a coarse
  // registration (sequence-format.md). While frame 0's keyframe lives, every
  // BA job holding it free puts this prior on it (1 sigma per axis, rotation
  // and translation of the camera frame), and BA tests it: the job is
  // solved with frame 0 held, then with it free under the prior (no
  // keyframe held: the mesh and the prior fix the frame, and the whole
  // map, first pose included, moves to agree with the mesh and the
  // observations); the freed solution is kept only if its cost is lower by
  // F > ba.prior_release_f (BundleAdjusterOptions). A
  // global BA every ba_registration_keyframes keyframes lets the older
  // keyframes follow. Sigmas 0 (the default): the registration is taken as
  // exact. Off by default because the test cannot tell a misplaced prior
  // from a mis-shaped one: on a kidney whose prior is 1 mm off in shape,
  // seen from close up, it moved a right registration by 2 deg / 6 mm and
  // TRE went from 3.1 to 8.1 px (docs/design-notes.md, "Refining a coarse
  // registration").
  double registration_sigma_deg = 0.0;
  double registration_sigma_mm = 0.0;
  int ba_registration_keyframes = 4;  // 0: no periodic global BA
  int ba_global_max_iterations = 15;
  double ba_global_max_time_s = 0.2;
  int ba_max_observations = 40000;      // observations per job (the job buffer's capacity)
  // 0 (live): a solved job is applied at the first frame that finds it
  // solved, so where corrections land depends on the machine's speed. N > 0
  // (deterministic replays and tests): a job is applied exactly N frames
  // after it was handed over (a focal test's: at the next frame), the
  // tracking thread waiting for the solve if it must, and solves stop by
  // iteration count, not time. Read by the
  // mapping side (firmware_app/mapping_worker.h).
  int ba_lag_frames = 0;
  // The calibration's focal length, tested after each of the first window
  // BA jobs by a job of its own (BaKind::kFocalTest, handed out when no
  // correction is pending; needs BA and the shape residual). A scope
  // calibrated at another zoom, or another scope's calibration, moves every
  // pose by degrees and mm while tracking stays self-consistent: on the
  // simulated orbit with fx, fy 15 % too long, 0 % lost and 9 % of the
  // frames more than 50 px off. A tested job whose data fits focal lengths
  // scaled by s with F > calibration_min_f and |s - 1| >
  // calibration_scale_error is a vote; calibration_votes votes in a row (s
  // on the same side of 1) and the calibration is judged suspect
  // (CalibrationCheck; the app warns, summary.json says so). Tracking goes
  // on: the mesh is not the organ, and a prior off in shape pulls s as a
  // focal error does (the simulated kidney seen from close up with a
  // prior 3 mm off in places: s 0.90-0.92 at F up to 210 with the right
  // calibration), so the test cannot tell which of the two is wrong, only
  // that the video and the prior disagree in a way that costs degrees.
  // Both tests must hold: F alone flags small biases, |s - 1| alone the
  // scatter of a weak window (s = 1.13 at F = 8). docs/design-notes.md, "The
  // focal-length test".
  bool check_calibration = true;
  int calibration_test_jobs = 6;  // window jobs followed by a test (the first ones; a test is two solves)
  double calibration_min_f = 100.0;
  double calibration_scale_error = 0.05;
  int calibration_votes = 2;
  // Clock for stage timings (monotonic ns); nullptr: no timings.
  std::int64_t (*now_ns)() = nullptr;
};

// The checks of configure() that concern the settings alone (not the frame
// size, the camera or the mesh), across fields too: what a settings file
// or --set can get wrong. The message names the setting.
Status validate_tracker_settings(const TrackerConfig& config);

// The tracker's working resolution for a frame of width x height
// (TrackerConfig::working_width): the frame's own size, or working_width
// wide with the height in proportion (rounded).
struct WorkingSize {
  int width = 0, height = 0;
};
WorkingSize working_size(int width, int height, int working_width);

struct TrackResult {
  TrackState state = TrackState::kLost;
  bool pose_valid = false;        // true for kInitialised, kTracking, kRelocalised
  SE3 T_camera_model;             // valid only when pose_valid
  int features = 0;               // keypoints extracted this frame
  int matches = 0;                // correspondences given to the pose solver
  int inliers = 0;
  double inlier_ratio = 0;
  double rms_px = 0;              // unweighted inlier RMS, ideal pixels
  double whitened_rms_px = 0;     // octave-normalised inlier RMS (what max_rms_px gates)
  double mask_agreement = 0;
  bool confirmed_by_alignment = false;  // reported under the relaxed ratio, confirmed by direct alignment
  // The outline and the shading measured this frame (no feature pose): lines
  // measured, their RMS at the outline's own pose, and how far apart the
  // outline's and the shading's poses put the organ (level-0 px; -1: not
  // compared). outline_tried: they were measured this frame, agreement
  // says what was found; by_outline: the pose reported is theirs.
  bool outline_tried = false;
  bool by_outline = false;
  // A feature pose that passed the gates, refused because the outline
  // measured from it put the organ elsewhere (contour_veto_px).
  bool outline_vetoed = false;
  // Lost with no outline near the guess: the silhouette was searched from
  // every side (the frame showed one to match), and a candidate's outline
  // fit placed the organ (TrackerConfig::outline_search).
  bool outline_searched = false;
  bool outline_search_found = false;
  SE3 T_search;                   // the search's fit (outline_search_found), else its best candidate
  int contour_lines = 0;
  double contour_rms_px = 0;
  double contour_sigma_px = -1;
  double joint_sigma_px = -1;     // the outline's and the shading's pose together (when both measured)
  SE3 T_outline, T_shading;       // each one's pose alone (outline_tried; T_outline can be a lost frame's guess)
  double modality_agreement_px = -1;
  Agreement agreement = Agreement::kNoOutline;
  bool keyframe = false;          // a keyframe was inserted this frame
  int map_points = 0, keyframes = 0;
  StageTimes times_ms{};
  double pose_jump_deg = 0, pose_jump_mm = 0;  // final pose vs the prediction (tracking)
  int local_map = 0;              // map points projected into the predicted view
  bool ba_applied = false;        // a solved BA job was applied to the map at the start of this frame
  bool ba_submitted = false;      // a BA job was handed to the mapping side this frame
  int occluder_pixels = -1;       // valid-mask pixels (1/2 resolution) removed as occluders; -1: no
                                  // occluder mask this frame (no chroma, or use_occluder_mask off)
  bool occluder_refused = false;  // the mask covered most of the organ (its own colour): not used
  float fast_threshold_scale = 1.f;  // FAST thresholds scaled for a dim or veiled frame (fast_reference_luma,
                                     // fast_reference_contrast)
  bool low_contrast = false;         // the contrast, not the luma, set fast_threshold_scale
  double noise_ratio = -1;           // initialisation only: organ_noise_ratio() of the frame (-1: not measured)
  bool denoise = false;              // initialisation only: the run's keypoints come from the filtered frame
  bool calibration_suspect = false;  // the calibration was judged suspect (at this frame or before)
  float calibration_focal_scale = 1.f;  // ... the focal scale the video fits (CalibrationCheck)
};

// What the focal-length test of the calibration found so far
// (TrackerConfig::check_calibration).
struct CalibrationCheck {
  int tests = 0;           // window jobs whose focal test came back
  int votes = 0;           // consecutive votes against the calibration
  bool suspect = false;    // judged suspect at suspect_frame
  int suspect_frame = -1;
  double focal_scale = 1;  // the best-fitting focal scale of the last test, or of the deciding one
  double focal_f = 0;      // ... and its F statistic
  double max_f = 0;        // the largest F of all tests
  double last_scale = 1;   // the last test's scale (the side of 1 its vote was on)
};

class TrackerImpl;
class BaChannel;

class Tracker {
 public:
  Tracker();
  ~Tracker();
  Tracker(const Tracker&) = delete;
  Tracker& operator=(const Tracker&) = delete;

  // Validates the config against capacity.h and the camera, copies the mesh,
  // sizes every pool and buffer. T_camera_model_init registers the mesh to
  // the first frame given to step().
  Status configure(const TrackerConfig& config, const Mesh& mesh, const CameraModel& camera,
                   const SE3& T_camera_model_init);
  // Optional mapping side for bundle adjustment (core/mapping/ba_channel.h); call
  // after configure(), before start(); nullptr detaches. Not owned.
  void set_ba_channel(BaChannel* channel);
  void start();
  // One frame: luma (Y plane, distorted image as captured, width x height)
  // and, optionally, its 4:2:0 chroma for the occluder mask
  // (TrackerConfig::use_occluder_mask); empty chroma, or planes of another
  // size: no occluder mask. When the tracker works at a smaller size
  // (working_camera()), a frame already brought to that size (by the
  // capture) is taken as it is. Allocates nothing.
  TrackResult step(GrayView luma, int frame_index, ChromaView chroma = {});
  void stop();

  // Diagnostics (tests, overlay; not for the hot path): copies the model
  // points of up to capacity alive map points to p_model; returns how many
  // were written. 0 before configure().
  int map_points(Vec3* p_model, int capacity) const;
  // Triangles of the mesh the tracker renders every frame (the given mesh's
  // count unless it was simplified; TrackerConfig::max_raster_triangles).
  // 0 before configure().
  int raster_triangles() const;
  // The calibration test so far (default values before configure()).
  CalibrationCheck calibration_check() const;
  // The camera at the working resolution (TrackerConfig::working_width):
  // the calibration given to configure(), scaled when the tracker works
  // at a smaller size. The mapping side's bundle adjustment works in these
  // pixels. Default before configure().
  CameraModel working_camera() const;

 private:
  TrackerImpl* impl_ = nullptr;  // allocated in configure()
};

}  // namespace st
