// End to end through the executables: scopetrack-sim makes a sequence,
// scopetrack replays it, the evaluator library scores the output. Also the
// application's behaviour on broken input (a video cut mid-frame, a
// sequence --check refuses, a bad command line).
#include <doctest/doctest.h>

#include <cstdlib>
#include <fstream>
#include <string>

#include "core/formats/sequence.h"
#include "core/tracking/tracker.h"
#include "hal/storage/file_io.h"
#include "hal/storage/mesh_file.h"
#include "hal/storage/sequence_loader.h"
#include "platform/realtime.h"
#include "support/shell.h"
#include "support/support.h"
#include "tools/eval/eval_report.h"
#include "tools/sim/liver_mesh.h"

using namespace st;
using st::test::summary_number;

namespace {

void simulate(const std::filesystem::path& dir, int frames, const std::string& size, int seed,
              const std::string& scenario = "orbit", const std::string& sim_extra = "") {
  const std::string cmd = test::bin_command("scopetrack-sim") + " --scenario " + scenario + " --frames " +
                          std::to_string(frames) + " --size " + size + " --seed " +
                          std::to_string(seed) + sim_extra + " --out " + test::shell_quoted(dir) +
                          " > /dev/null";
  REQUIRE_MESSAGE(test::run_shell(cmd) == 0, cmd);
}

// scopetrack --sequence SEQ --out OUT [extra]; stderr goes to OUT/../NAME.stderr.
int track(const std::filesystem::path& seq, const std::filesystem::path& out,
          std::string* stderr_text, const std::string& extra = "") {
  const auto err = out.parent_path() / (out.filename().string() + ".stderr");
  const int code = test::run_shell(test::bin_command("scopetrack") + " --sequence " +
                                   test::shell_quoted(seq) + " --out " + test::shell_quoted(out) + extra +
                                   " > /dev/null 2> " + test::shell_quoted(err));
  *stderr_text = test::read_file_bytes(err);
  return code;
}

// Replays dir/seq into dir/out and scores it. extra: replay options
// (kDeterministic for runs whose outcome must not depend on the machine's
// speed).
EvalReport track_evaluate(const std::filesystem::path& dir, const std::string& extra = "") {
  std::string err;
  REQUIRE_MESSAGE(track(dir / "seq", dir / "out", &err, extra) == 0, err);
  auto report = evaluate_run(dir / "seq", dir / "out");
  REQUIRE_MESSAGE(report.ok(), (report.ok() ? std::string() : report.message()));
  MESSAGE(format_eval_table(report.value()));
  return report.value();
}

// Simulates a sequence into dir/seq, then track_evaluate().
EvalReport simulate_track_evaluate(const std::filesystem::path& dir, int frames, const std::string& size, int seed,
                                   const std::string& scenario, const std::string& extra = "") {
  simulate(dir / "seq", frames, size, seed, scenario);
  return track_evaluate(dir, extra);
}

// Where the mapping thread's corrections land decided whether fast seed 2
// at 960x540 recovered: live, the same binary lost 2.0-4.3 % on a quiet or
// loaded machine (TRE p95 3.5 px, or 8 px in 5 of 12 loaded runs, after a
// relocalisation that seeded a keyframe 8 px off), and 69 % in one of four
// ASan runs, as with use_ba=0. With the corrections landing 3 frames after
// their job, runs are byte-identical whatever the load.
const std::string kDeterministic = " --ba-lag 3";

// Refining the registration (off by default; see TrackerConfig::registration_sigma_deg).
const std::string kRefineRegistration = " --set registration_sigma_deg=1 --set registration_sigma_mm=2";

int data_lines(const std::filesystem::path& p) {
  std::ifstream f(p);
  int n = 0;
  for (std::string line; std::getline(f, line);) n += !line.empty() && line[0] != '#';
  return n;
}

// scopetrack-sim's option for the organ texture from the real liver photo.
std::string photo_texture() {
  return " --texture " + test::shell_quoted(test::shared_data("real/laparoscopy_liver_1080p.y4m"));
}

// The ablation run of a test: dir/seq replayed into dir/control with
// kDeterministic + extra, scored and printed under label.
EvalResult track_control(const std::filesystem::path& dir, const std::string& extra, const std::string& label) {
  std::string err;
  REQUIRE_MESSAGE(track(dir / "seq", dir / "control", &err, kDeterministic + extra) == 0, err);
  auto control = evaluate_run(dir / "seq", dir / "control");
  REQUIRE(control.ok());
  MESSAGE(label << ": " << format_eval_table(control.value()));
  return control->result;
}

// Photo-textured scenario (sim_extra: more scopetrack-sim options), frames
// of size and seed, simulated into dir/seq and replayed deterministically
// into dir/out.
EvalReport photo_run(const std::filesystem::path& dir, int frames, const std::string& size, int seed,
                     const std::string& scenario, const std::string& sim_extra = "") {
  simulate(dir / "seq", frames, size, seed, scenario, sim_extra + photo_texture());
  return track_evaluate(dir, kDeterministic);
}

// Photo-textured manipulation, 300 frames of size and seed.
EvalReport photo_manipulation_run(const std::filesystem::path& dir, const std::string& size, int seed) {
  return photo_run(dir, 300, size, seed, "manipulation");
}

// Initialised, no wrong pose, and lost / TRE median / TRE p95 within bounds.
void check_run(const EvalResult& e, double max_lost_pct, double max_tre_median_px, double max_tre_p95_px) {
  CHECK(e.init_ok);
  CHECK(e.wrong_pct == 0.0);
  CHECK(e.lost_pct <= max_lost_pct);
  CHECK(e.tre_median_px < max_tre_median_px);
  CHECK(e.tre_p95_px < max_tre_p95_px);
}

}  // namespace

// The end-to-end gate: init ok, lost 0, median TRE < 2 px, no wrong pose.
TEST_CASE(
    "app_e2e: simulate 150 frames, track, evaluate: init ok, no frame lost, median TRE < 2 px" *
    doctest::timeout(test::budget_s(300))) {
  const auto dir = test::scratch_dir("app_e2e_orbit");
  const EvalReport report = simulate_track_evaluate(dir, 150, "480x270", 2, "orbit");
  const EvalResult& e = report.result;
  CHECK(report.frames_in_csv == 150);
  CHECK(e.frames == 150);
  CHECK(e.init_ok);
  CHECK(e.wrong_pct == 0.0);
  CHECK(e.reported_frames == 150);
  CHECK(e.tre_median_px < 2.0);
  CHECK(summary_number(dir / "out", "tracking_thread_allocations") == 0);
  // The mapping thread yields to the tracking thread on a shared core.
  CHECK(summary_number(dir / "out", "ba_thread_nice") >= platform::kBackgroundWorkerNice);
}

// A prior exported at full density: the CT liver of shared/data split
// twice at its edge midpoints (scopetrack-sim --prior-subdivide 2: the
// same surface, 320k triangles). The tracker renders a simplified copy of
// at most TrackerConfig::max_raster_triangles every frame
// (core/mesh/mesh_simplify.h); the shape residual keeps the full mesh. Tracking
// stays as accurate as on the 20k-triangle original (docs/design-notes.md,
// "A dense prior").
TEST_CASE("app_e2e: a dense prior (the CT liver at 320k triangles) is simplified for the per-frame render" *
          doctest::timeout(test::budget_s(300)) * doctest::test_suite(test::kLongSuite)) {
  const auto dir = test::scratch_dir("app_e2e_dense_prior");
  simulate(dir / "seq", 120, "480x270", 2, "orbit",
           " --prior-subdivide 2 --mesh " + test::shell_quoted(test::shared_data("liver/liver.ply")));
  const EvalReport report = track_evaluate(dir, kDeterministic);
  check_run(report.result, 0.0, 1.0, 2.0);
  CHECK(summary_number(dir / "out", "mesh_triangles") == 320000);
  const double rendered = summary_number(dir / "out", "raster_triangles");
  CHECK(rendered <= TrackerConfig{}.max_raster_triangles);
  CHECK(rendered >= 20000);
  CHECK(summary_number(dir / "out", "tracking_thread_allocations") == 0);
  // The control renders all 320k triangles: the same poses within noise.
  const EvalResult control = track_control(dir, " --set max_raster_triangles=0", "every triangle rendered");
  CHECK(summary_number(dir / "control", "raster_triangles") == 320000);
  CHECK(control.lost_pct == 0.0);
  CHECK(report.result.tre_median_px < control.tre_median_px + 0.5);
}

// Organs other than the liver (scopetrack-sim --organ, tools/sim/
// organ_shapes.h): a kidney, about 110 x 60 x 50 mm and seen from closer,
// and a stomach, a long bent sack. Nothing in the tracker knows the organ;
// these guard against thresholds that only suit the liver. Measured when
// the test was written: kidney orbit 0 % lost, TRE 0.27 / 0.86 px; stomach
// manipulation 0 %, 0.30 / 0.81 px.
TEST_CASE("app_e2e: other organs (a kidney's orbit, a stomach's manipulation, 640x360) are tracked" *
          doctest::timeout(test::budget_s(300)) * doctest::test_suite(test::kLongSuite)) {
  struct Case {
    const char* organ;
    const char* scenario;
    int seed;
  };
  for (const Case& c : {Case{"kidney", "orbit", 1}, Case{"stomach", "manipulation", 2}}) {
    CAPTURE(c.organ);
    const auto dir = test::scratch_dir(std::string("app_e2e_organ_") + c.organ);
    simulate(dir / "seq", 150, "640x360", c.seed, c.scenario, std::string(" --organ ") + c.organ);
    check_run(track_evaluate(dir, kDeterministic).result, 0.0, 1.0, 2.5);
  }
}

// Tissue from a real photo (scopetrack-sim --texture: the real liver
// frame's structure, its noise smoothed away): a smooth, dark liver with a
// few vessels and fat. Before keypoints had to keep their descriptor patch
// on the organ (OrbConfig::organ_patch_inside; the mask was dilated by
// 12 px) the map drifted on it: 0 % lost but TRE 3.02 / 13.68 px on this
// sequence; then 0.80 / 1.86 px (--ba-lag 3, so every run is the same).
// Smooth tissue is a knife edge: any change to the keypoints moves the
// figures. With the FAST thresholds
// scaled to the organ's luma (~70 here, TrackerConfig::fast_reference_luma
// 80): 1.14 / 4.04 px; at a reference of 72 0.59 / 1.71, at 96 0.75 / 1.86.
// In every one a slow drift of 2-4 px over frames 150-250, which returns
// to within 1-2 px at the end; the bound is for the drift of before.
TEST_CASE("app_e2e: tissue from the real liver photo (orbit, 640x360) is tracked without drift" *
          doctest::timeout(test::budget_s(300)) * doctest::test_suite(test::kLongSuite)) {
  const auto dir = test::scratch_dir("app_e2e_photo");
  check_run(photo_run(dir, 300, "640x360", 1, "orbit").result, 3.0, 1.5, 5.0);
}

// A dim scene: the same photo tissue with the scope light at 0.3
// (scopetrack-sim --light: the sensor's noise stays, so the image is darker
// and noisier; organ luma median ~55 instead of ~80). FAST thresholds are
// intensity differences, which shrink with the light: at ORB-SLAM's 20 / 7
// the frame keeps few corners and tracking is lost on and off (control:
// 14.7 % lost, TRE 2.00 / 7.84 px). Scaled with the organ's luma
// (TrackerConfig::fast_reference_luma): 0 % lost, 1.58 / 3.91 px.
TEST_CASE("app_e2e: a dim scene (photo tissue, light 0.3, 640x360): FAST thresholds follow the light" *
          doctest::timeout(test::budget_s(300)) * doctest::test_suite(test::kLongSuite)) {
  const auto dir = test::scratch_dir("app_e2e_dim");
  check_run(photo_run(dir, 150, "640x360", 1, "orbit", " --light 0.3").result, 3.0, 2.5, 6.0);
  CHECK(summary_number(dir / "out", "dim_frames") >= 140);
  CHECK(summary_number(dir / "out", "min_fast_threshold_scale") < 0.7);
  const EvalResult control =
      track_control(dir, " --set fast_reference_luma=0 --set fast_reference_contrast=0", "FAST thresholds not scaled");
  CHECK(summary_number(dir / "control", "dim_frames") == 0);
  // The control shows the test needs the scaling.
  CHECK((control.lost_pct > 5.0 || control.tre_p95_px > 6.0));
}

// Surgical smoke (scopetrack-sim --smoke 0.8; tools/sim/smoke.h): the
// instrument's plume lays a bright veil over the photo tissue for ~3.7 s
// at a time, and FAST at its usual thresholds finds too few corners in
// the flattened texture. Without the contrast rule (the control) tracking
// is lost at the first episode and, the organ having been turned ~25 deg
// meanwhile, never found again: 63.0 % lost. With the FAST thresholds
// following the organ's texture contrast (TrackerConfig::
// fast_reference_contrast): 0 % lost, TRE 2.50 / 5.03 px, 0 wrong.
TEST_CASE("app_e2e: surgical smoke over photo tissue (manipulation seed 2, 640x360): FAST follows the contrast" *
          doctest::timeout(test::budget_s(300)) * doctest::test_suite(test::kLongSuite)) {
  const auto dir = test::scratch_dir("app_e2e_smoke");
  check_run(photo_run(dir, 300, "640x360", 2, "manipulation", " --smoke 0.8").result, 3.0, 4.0, 10.0);
  CHECK(summary_number(dir / "out", "low_contrast_frames") >= 50);
  const EvalResult control = track_control(dir, " --set fast_reference_contrast=0", "FAST thresholds not scaled by contrast");
  CHECK(summary_number(dir / "control", "low_contrast_frames") == 0);
  CHECK(control.wrong_pct == 0.0);
  CHECK(control.lost_pct > 30.0);
}

// A grasping instrument over smooth tissue (photo texture, manipulation
// seed 1, 640x360, deterministic): the instrument lies inside the organ's
// mask, its outline gives keypoints, keyframes make them map points with
// the mesh's depth behind them, and the pose follows the instrument
// (docs/design-notes.md, "The occluder mask"). The occluder mask
// from chroma (core/image/occluder_mask.h) keeps them out: 0 lost, TRE 0.73 /
// 2.69 px; without it (the control) 23.7 % lost, 0.79 / 15.6 px.
TEST_CASE("app_e2e: an instrument over smooth tissue is masked by its colour (photo manipulation, 640x360)" *
          doctest::timeout(test::budget_s(300)) * doctest::test_suite(test::kLongSuite)) {
  const auto dir = test::scratch_dir("app_e2e_instrument");
  const EvalReport with_mask = photo_manipulation_run(dir, "640x360", 1);
  CHECK(summary_number(dir / "out", "occluder_mask_frames") == 300);
  CHECK(summary_number(dir / "out", "occluder_removed_px_mean") > 1000);
  check_run(with_mask.result, 3.0, 1.5, 6.0);
  const EvalResult control = track_control(dir, " --set use_occluder_mask=0", "without the occluder mask");
  // The control shows the test needs the mask: the pose follows the instrument.
  CHECK((control.lost_pct > 10.0 || control.tre_p95_px > 10.0));
}

// Map points take the descriptor of their latest keyframe observation
// (TrackerConfig::refresh_descriptors). On this sequence the instrument
// turns the smooth photo tissue under the scope's light for 150 frames;
// with the descriptors the points were made with, ever more of each
// frame's matches are look-alike corners near the right one (inlier ratio
// 0.83 at frame 1, 0.27 at frame 158, while the pose is still 2 px from
// the truth), until the ratio gate calls the frame lost and relocalisation
// cannot match either: 31.7 % lost (frames 159-255, 0 wrong). With them
// refreshed: 1.0 % lost, TRE 1.00 / 4.36 px (deterministic runs). Since the
// FAST thresholds also follow the texture's contrast
// (TrackerConfig::fast_reference_contrast), the flat tissue gives more
// corners and this sequence no longer needs the refresh (0 % lost either
// way; TRE 1.18 / 3.33 px with it, 0.88 / 3.14 px without), and the
// organ's outline carries the frames the ratio gate refuses until the
// features match again (both off, outline on: 0 % lost, 38 frames by the
// outline, TRE 1.00 / 3.37 px): the control turns all three off, to keep
// showing what the refresh does on its own (29.3 % lost).
TEST_CASE("app_e2e: map points follow the tissue's appearance (photo manipulation seed 4, 1280x720)" *
          doctest::timeout(test::budget_s(600)) * doctest::test_suite(test::kLongSuite)) {
  const auto dir = test::scratch_dir("app_e2e_refresh");
  const EvalReport refreshed = photo_manipulation_run(dir, "1280x720", 4);
  CHECK(summary_number(dir / "out", "refresh_descriptors") == 1);
  check_run(refreshed.result, 3.0, 1.5, 6.0);
  const EvalResult control = track_control(dir, " --set refresh_descriptors=0 --set fast_reference_contrast=0 --set use_contour=0",
                                           "descriptors never refreshed, FAST not scaled by contrast, no outline");
  CHECK(control.wrong_pct == 0.0);
  CHECK(control.lost_pct > 20.0);
}

// Fast motion: the scope jumps ahead in two blurred bursts (5-6 deg per
// frame at their peaks). Keyframes taken from blurred burst frames used to
// leave their pose error in the map for the rest of the run (this sequence
// with window BA: TRE median 2.0, p95 8.7 px, 0 % lost); with keyframes only
// from frames that moved <= keyframe_max_motion_px: 0.48 / 1.83 px, and the
// second burst's peak is honestly lost (frames 210-245: 12 %; the issue's
// 3 % is not met here). The outcome depended on which frame the mapping
// thread's corrections landed on: the same binary on the same sequence gave
// 12 % lost in 20 of 22 runs and 22.3 % (TRE 0.66 / 1.62 px) in the other
// two, one of them under ASan (with the simulator's old blur, 5 ghost
// copies). Now the run is deterministic (kDeterministic): 1.3 % lost, TRE
// 0.71 / 1.63 px (live: 1.3 %, 0.70 / 1.64 px). The lost bound only catches
// a tracker that never recovers (fast seed 2: ~70 %); the accuracy bounds
// are the test.
TEST_CASE("app_e2e: fast bursts (seed 4, 640x360): no biased map after a burst, no wrong pose" *
          doctest::timeout(test::budget_s(300)) * doctest::test_suite(test::kLongSuite)) {
  const auto dir = test::scratch_dir("app_e2e_fast");
  const EvalReport report = simulate_track_evaluate(dir, 300, "640x360", 4, "fast", kDeterministic);
  CHECK(summary_number(dir / "out", "ba_lag_frames") == 3);
  check_run(report.result, 30.0, 1.2, 4.0);
}

// Smooth tissue (the CT liver at half detail, breathing 3 mm), fast seed 3,
// 150 frames: at the start of the first swing a blurred frame's features
// pass every gate with 52 inliers, 10.5 deg and 20 mm from the truth (its
// markers' median TRE is 50 px: the one wrong frame of the 36 smooth
// sequences in docs/results.md when the truth was the rest shape's frame).
// The outline measured from that pose puts the organ 29.8 px away, 8.7
// times its own sigma, and the frame is lost instead
// (TrackerConfig::contour_check_inliers). Keypoints from the raw frame, as
// measured: this tissue's noise ratio (2.5) now has them come from the
// filtered frame (TrackerConfig::denoise_noise_ratio), whose features give
// no wrong pose here with or without the check.
TEST_CASE("app_e2e: the outline refuses a blurred frame's wrong feature pose (smooth fast seed 3, breathing)" *
          doctest::timeout(test::budget_s(600)) * doctest::test_suite(test::kLongSuite)) {
  const auto dir = test::scratch_dir("app_e2e_outline_veto");
  simulate(dir / "seq", 150, "1280x720", 3, "fast", " --tissue smooth --organ-detail 0.5 --breathing 3");
  const std::string raw_frame = " --set denoise_noise_ratio=0";
  const EvalReport report = track_evaluate(dir, kDeterministic + raw_frame);
  CHECK(report.result.init_ok);
  CHECK(report.result.wrong_pct == 0.0);
  CHECK(summary_number(dir / "out", "outline_vetoes") >= 1);
  CHECK(summary_number(dir / "out", "tracking_thread_allocations") == 0);  // the check allocates nothing
  const double checked_deg = report.result.rot_err_max_deg;
  const EvalResult control =
      track_control(dir, raw_frame + " --set contour_check_inliers=0", "weak feature poses not checked by the outline");
  const double unchecked_deg = control.rot_err_max_deg;
  MESSAGE("largest rotation error of a reported pose: " << checked_deg << " deg checked, " << unchecked_deg
                                                         << " deg unchecked");
  CHECK(checked_deg < 5.0);
  CHECK(unchecked_deg > 8.0);
  CHECK(control.init_ok);
  const EvalResult filtered = track_control(dir, "", "keypoints from the filtered frame (the default here)");
  CHECK(summary_number(dir / "control", "features_denoise") == 1);
  CHECK(filtered.wrong_pct == 0.0);
  CHECK(filtered.rot_err_max_deg < 5.0);
}

// Smooth tissue (the CT liver, 3 mm breathing), fast seed 1 at 960x540,
// 150 frames: after the swing at frame 103 the view settles near one
// keyframe's, but brute force finds only 30-36 matches a keyframe on that
// tissue (its few corners describe weakly), and with 30 required the run
// was lost for 30.7 % of the frames (frames with 31-32 matches either
// failed RANSAC or fell below it). The matches it finds are right (31 of
// 32 RANSAC inliers, 149 after tracking from that pose), so from 15 the
// pose is tried; the stricter gates after relocalisation judge it.
TEST_CASE("app_e2e: relocalisation tries a keyframe's pose from 15 matches (smooth fast seed 1, breathing)" *
          doctest::timeout(test::budget_s(600)) * doctest::test_suite(test::kLongSuite)) {
  const auto dir = test::scratch_dir("app_e2e_reloc_matches");
  simulate(dir / "seq", 150, "960x540", 1, "fast", " --tissue smooth --breathing 3");
  // The outline as a guess of its own (outline_guess) recovers this swing
  // too: off here, so that the matches alone are measured.
  const EvalReport report = track_evaluate(dir, kDeterministic + " --set outline_guess=0");
  check_run(report.result, 5.0, 1.5, 4.0);
  const EvalResult control =
      track_control(dir, " --set outline_guess=0 --set reloc_min_matches=30", "30 matches needed");
  CHECK(control.wrong_pct == 0.0);
  CHECK(control.lost_pct > 20.0);
}

// Smooth tissue at half detail, fast seed 3, 1280x720, 150 frames: the
// swing at frame 44 leaves dead reckoning with no measurement (the blurred
// frames do not align with the last tracked one), and brute force against
// the keyframes finds too few matches on this tissue: the run was lost
// from frame 44 to the end (70.7 %). The outline, measured in each lost
// frame alone, places the organ to 1.5-2.5 px once the blur eases (frame
// 47: 2.4 px, the shading unmeasured); as a guess of its own
// (TrackerConfig::outline_guess) it carries dead reckoning through the
// swing and brings the features within reach, and what is reported passed
// the stricter gates of relocalisation.
TEST_CASE("app_e2e: a lost frame's outline is a guess of its own (smooth half detail, fast seed 3)" *
          doctest::timeout(test::budget_s(600)) * doctest::test_suite(test::kLongSuite)) {
  const auto dir = test::scratch_dir("app_e2e_outline_guess");
  simulate(dir / "seq", 150, "1280x720", 3, "fast", " --tissue smooth --organ-detail 0.5");
  const EvalReport report = track_evaluate(dir, kDeterministic);
  check_run(report.result, 10.0, 1.5, 4.0);
  CHECK(report.result.rot_err_max_deg < 5.0);
  CHECK(summary_number(dir / "out", "tracking_thread_allocations") == 0);
  const EvalResult control = track_control(dir, " --set outline_guess=0", "the outline not a guess of its own");
  CHECK(control.wrong_pct == 0.0);
  CHECK(control.lost_pct > 50.0);
}

// A near-symmetric organ: an ellipsoid of 120 x 80 x 56 mm, 4 % fuller
// at one end of its long axis. Its silhouette is nearly the same from a
// direction and from the mirrored one, so the outline search's fits land
// on mirror poses as readily as on the right one: on smooth tissue, fast
// seed 2 at 640x360 (the swing into tissue no keyframe has seen), the
// search ran on 84 lost frames and its outline fit placed the organ on 72
// of them; the 49 fits of the bench's replay of the same sequence
// (`scopetrack-bench track --log`) lay 43-172 deg from the truth. None may
// be reported: a fit is only a guess, and what reports a pose from it is
// the features tracked from it passing the stricter gates (or the normal
// ones near the fit), which tissue seen from the mirrored side does not
// give (0 inliers there, even at outline_agreement_inlier_factor 0.2).
TEST_CASE("app_e2e: a near-symmetric organ's mirrored outline fits are never reported (smooth ellipsoid, fast seed 2)" *
          doctest::timeout(test::budget_s(600)) * doctest::test_suite(test::kLongSuite)) {
  const auto dir = test::scratch_dir("app_e2e_symmetric_organ");
  const Mesh ellipsoid = sim::map_icosphere(4, [](const Vec3& d) {
    return Vec3(60.0 * d.x() * (1.0 + 0.04 * d.x()), 40.0 * d.y(), 28.0 * d.z());
  });
  REQUIRE(save_mesh_ply(dir / "ellipsoid.ply", ellipsoid).ok());
  simulate(dir / "seq", 150, "640x360", 2, "fast",
           " --tissue smooth --mesh " + test::shell_quoted(dir / "ellipsoid.ply"));
  const EvalReport report = track_evaluate(dir, kDeterministic);
  const double searches = summary_number(dir / "out", "outline_searches");
  const double fits = summary_number(dir / "out", "outline_search_fits");
  MESSAGE("outline searches " << searches << ", fits " << fits);
  CHECK(report.result.init_ok);
  CHECK(fits >= 20);  // the ambiguity was met: the search placed the organ again and again
  CHECK(report.result.wrong_pct == 0.0);
  CHECK(report.result.rot_err_max_deg < 5.0);
  CHECK(summary_number(dir / "out", "tracking_thread_allocations") == 0);
}

// Fast seed 2: the first burst swings the scope ~16 deg and ~40 mm into
// tissue no keyframe has seen, through smeared frames. Before dead
// reckoning by direct alignment (core/motion/direct_alignment.h), with its
// confirmed relocalisation and keyframe there, this never recovered: 69 %
// lost at 960x540 (and at 640x360 and 1280x720). Then (960x540,
// deterministic, see kDeterministic): 4.3 % lost, TRE 1.29 / 3.5 px; now
// 0.3 % lost, TRE 1.08 / 5.8 px, the organ's outline carrying two frames
// of the swing (features only, --set use_contour=0: 1.0 %, 0.36 / 2.6 px;
// docs/design-notes.md). At 640x360 it is still lost: even from the true
// pose the map yields 20-35 matches there.
TEST_CASE("app_e2e: a fast swing into unmapped tissue is recovered (fast seed 2, 960x540), no wrong pose" *
          doctest::timeout(test::budget_s(600)) * doctest::test_suite(test::kLongSuite)) {
  const EvalReport report =
      simulate_track_evaluate(test::scratch_dir("app_e2e_fast_swing"), 300, "960x540", 2, "fast", kDeterministic);
  check_run(report.result, 10.0, 2.0, 6.0);
}

// Recorded surgical video usually reaches us through a lossy codec, and
// sequence-format.md converts any video with ffmpeg. H.264 at CRF 28 (about
// 300 kbit/s here) smooths the fine texture and lets some of it lag the
// surface (skipped blocks); the same sequence uncompressed: TRE 0.52 / 1.02
// px, at CRF 28 (one encoder thread, so the bits repeat): 0.88 / 1.82 px,
// 0 lost. (At 640x360 and CRF 33 the texture no longer moves with the
// organ and the poses lag the truth, TRE 16 / 39 px with 0.7 % lost and
// hundreds of inliers a frame: a limit docs/design-notes.md notes.)
TEST_CASE("app_e2e: an H.264-compressed sequence (CRF 28, through ffmpeg) still tracks accurately" *
          doctest::timeout(test::budget_s(300)) * doctest::test_suite(test::kLongSuite)) {
  if (std::string(SCOPETRACK_FFMPEG).empty()) return;  // ffmpeg is optional (Dependencies.cmake)
  const auto dir = test::scratch_dir("app_e2e_h264");
  simulate(dir / "raw", 150, "640x360", 5);
  std::filesystem::create_directories(dir / "seq");
  for (const char* f : {"sequence.yaml", "organ.ply", "groundtruth.txt", "markers.txt"})
    std::filesystem::copy_file(dir / "raw" / f, dir / "seq" / f);
  const std::string ffmpeg = test::shell_quoted(SCOPETRACK_FFMPEG) + " -loglevel error -y -i ";
  const std::string encode = ffmpeg + test::shell_quoted(dir / "raw" / "video.y4m") +
                             " -c:v libx264 -preset veryfast -crf 28 -threads 1 -pix_fmt yuv420p " +
                             test::shell_quoted(dir / "video.mp4");
  REQUIRE_MESSAGE(test::run_shell(encode) == 0, encode);
  const std::string decode = ffmpeg + test::shell_quoted(dir / "video.mp4") + " -pix_fmt yuv420p -f yuv4mpegpipe " +
                             test::shell_quoted(dir / "seq" / "video.y4m");
  REQUIRE_MESSAGE(test::run_shell(decode) == 0, decode);
  // The codec really removed most of the bits.
  CHECK(std::filesystem::file_size(dir / "video.mp4") * 20 < std::filesystem::file_size(dir / "raw" / "video.y4m"));
  check_run(track_evaluate(dir, kDeterministic).result, 1.0, 1.5, 3.0);
}

// A coarse registration (sequence-format.md: T_camera_model_init is "the
// coarse registration"): the simulator writes the true pose, here turned by
// 2 deg and shifted by 4 mm. Taken as exact, the whole run carries the error
// (TRE 17.6 / 43.4 px). With the registration prior (registration_sigma_deg 1,
// registration_sigma_mm 2; off by default), BA frees frame 0's pose once the
// data shows the map sits off the organ and the overlay comes back (4.5 /
// 18.3 px; the first frames, before any parallax, keep the error: no image
// tells). One frame is lost where a correction moved the map under it.
TEST_CASE(
    "app_e2e: a coarse registration (2 deg, 4 mm) is refined as the scope moves (orbit, 640x360)" *
    doctest::timeout(test::budget_s(300)) * doctest::test_suite(test::kLongSuite)) {
  const auto dir = test::scratch_dir("app_e2e_registration");
  simulate(dir / "seq", 150, "640x360", 1, "orbit");
  auto text = read_file(dir / "seq" / "sequence.yaml", 1 << 20);
  REQUIRE(text.ok());
  auto config = parse_sequence_yaml(text.value());
  REQUIRE(config.ok());
  SequenceConfig off = config.value();
  off.T_camera_model_init = SE3(so3_exp(2.0 * M_PI / 180.0 * Vec3(1, 1, 1).normalized()),
                                4.0 * Vec3(1, 1, 1).normalized()) *
                            config->T_camera_model_init;
  REQUIRE(write_sequence_files(dir / "seq", off).ok());
  const EvalResult refined = track_evaluate(dir, kDeterministic + kRefineRegistration).result;
  const EvalResult kept = track_control(dir, "", "registration taken as exact (the default)");
  CHECK(refined.init_ok);
  CHECK(refined.wrong_pct == 0.0);
  CHECK(refined.lost_pct <= 1.0);
  CHECK(summary_number(dir / "out", "ba_registration_releases") >= 1);
  CHECK(summary_number(dir / "control", "ba_registration_tests") == 0);
  CHECK(refined.tre_median_px < 0.5 * kept.tre_median_px);
}

TEST_CASE("app_e2e: 1080p input is tracked at the 1280x720 working size, poses as accurate in the input's pixels" *
          doctest::timeout(test::budget_s(300)) * doctest::test_suite(test::kLongSuite)) {
  const auto dir = test::scratch_dir("app_e2e_working_size");
  simulate(dir / "seq", 60, "1920x1080", 3);
  const EvalReport working = track_evaluate(dir, kDeterministic);
  CHECK(summary_number(dir / "out", "width") == 1920);
  CHECK(summary_number(dir / "out", "working_width") == 1280);
  CHECK(summary_number(dir / "out", "working_height") == 720);
  CHECK(summary_number(dir / "out", "tracking_thread_allocations") == 0);
  CHECK(summary_number(dir / "out", "occluder_mask_frames") == 60);  // the chroma is scaled too
  const EvalResult native = track_control(dir, " --set working_width=0", "at the frames' own 1920x1080");
  CHECK(summary_number(dir / "control", "working_width") == 1920);
  CHECK(summary_number(dir / "control", "tracking_thread_allocations") == 0);
  // The evaluation projects the markers with the sequence's own (1080p)
  // calibration: a working camera scaled wrong would show here.
  CHECK(working.result.init_ok);
  CHECK(working.result.lost_pct == 0.0);
  CHECK(working.result.wrong_pct == 0.0);
  CHECK(working.result.tre_median_px < 1.5);
  CHECK(working.result.tre_mean_px < 1.25 * native.tre_mean_px + 0.1);
}

TEST_CASE("app_e2e: 200 simulated frames replay with zero heap allocations on the tracking thread" *
          doctest::timeout(test::budget_s(300)) * doctest::test_suite(test::kLongSuite)) {
  const auto dir = test::scratch_dir("app_e2e_alloc");
  simulate(dir / "seq", 200, "320x180", 5);
  std::string err;
  REQUIRE_MESSAGE(track(dir / "seq", dir / "out", &err) == 0, err);
  CHECK(summary_number(dir / "out", "frames") == 200);
  CHECK(summary_number(dir / "out", "tracking_thread_allocations") == 0);
  CHECK(summary_number(dir / "out", "occluder_mask_frames") == 200);  // the replay hands chroma over
  CHECK(summary_number(dir / "out", "fps") > 0);
  CHECK(summary_number(dir / "out", "p99_latency_ms") > 0);
  CHECK(data_lines(dir / "out" / "frames.csv") == 201);
  // Deterministic replays: the BA corrections land 2 frames after their
  // job, so two runs write the same trajectory to the byte, and the
  // tracking thread's wait for a solve allocates nothing either.
  for (const char* run : {"lag_a", "lag_b"}) {
    REQUIRE_MESSAGE(track(dir / "seq", dir / run, &err, " --ba-lag 2") == 0, err);
    CHECK(summary_number(dir / run, "tracking_thread_allocations") == 0);
    CHECK(summary_number(dir / run, "ba_lag_frames") == 2);
    CHECK(summary_number(dir / run, "ba_jobs_applied") >= 2);
  }
  const std::string a = test::read_file_bytes(dir / "lag_a" / "trajectory.txt");
  CHECK(data_lines(dir / "lag_a" / "trajectory.txt") > 150);
  CHECK(a == test::read_file_bytes(dir / "lag_b" / "trajectory.txt"));
}

TEST_CASE(
    "app_e2e: a video cut mid-frame ends with exit 1, a message naming the frame, output intact" *
    doctest::timeout(test::budget_s(120))) {
  const auto dir = test::scratch_dir("app_e2e_cut");
  simulate(dir / "seq", 40, "320x180", 7);
  const auto seq = load_sequence(dir / "seq");
  REQUIRE(seq.ok());
  const std::size_t record = seq->video_header.frame_bytes() + 6;
  std::filesystem::resize_file(dir / "seq" / "video.y4m",
                               seq->video_header.header_bytes + 30 * record + record / 2);
  std::string err;
  CHECK(track(dir / "seq", dir / "out", &err) == 1);
  CHECK(err.find("frame 30 is truncated") != std::string::npos);
  MESSAGE(err);
  CHECK(data_lines(dir / "out" / "frames.csv") == 31);  // header + frames 0..29
  CHECK(summary_number(dir / "out", "frames") == 30);
  CHECK(test::read_file_bytes(dir / "out" / "summary.json").find("\"error\": \"") !=
        std::string::npos);
  auto report = evaluate_run(dir / "seq", dir / "out");  // what was written is usable
  REQUIRE_MESSAGE(report.ok(), (report.ok() ? std::string() : report.message()));
  CHECK(report->frames_in_csv == 30);
}

// A calibration whose focal lengths are 15 % too long (another scope's, or
// another zoom's): tracking stays self-consistent, so every frame is
// reported while the poses are off by degrees. The focal test of the first
// window BA jobs (TrackerConfig::check_calibration) judges it suspect: a
// warning naming the focal scale the video fits, the summary's flag; the
// right calibration gets neither.
TEST_CASE("app_e2e: focal lengths 15 % off are judged suspect: a warning, the summary's flag, tracking goes on" *
          doctest::timeout(test::budget_s(300)) * doctest::test_suite(test::kLongSuite)) {
  const auto dir = test::scratch_dir("app_e2e_calibration");
  simulate(dir / "seq", 150, "480x270", 2);
  std::string err;
  REQUIRE_MESSAGE(track(dir / "seq", dir / "right", &err, kDeterministic) == 0, err);
  CHECK(summary_number(dir / "right", "calibration_suspect") == 0);
  CHECK(summary_number(dir / "right", "calibration_tests") >= 2);
  CHECK(err.find("calibration suspect") == std::string::npos);
  MESSAGE("right calibration: largest F " << summary_number(dir / "right", "calibration_max_f"));
  std::filesystem::copy(dir / "seq", dir / "bad", std::filesystem::copy_options::recursive);
  auto config = parse_sequence_yaml(test::read_file_bytes(dir / "seq" / "sequence.yaml"));
  REQUIRE(config.ok());
  config->K.fx *= 1.15;
  config->K.fy *= 1.15;
  {
    std::ofstream yaml(dir / "bad" / "sequence.yaml", std::ios::trunc);
    yaml << format_sequence_yaml(config.value());
  }
  CHECK(track(dir / "bad", dir / "out", &err, kDeterministic) == 0);
  MESSAGE(err);
  CHECK(err.find("calibration suspect from frame") != std::string::npos);
  CHECK(err.find("camera_matrix") != std::string::npos);
  CHECK(summary_number(dir / "out", "calibration_suspect") == 1);
  const double scale = summary_number(dir / "out", "calibration_focal_scale");
  CHECK(scale > 0.80);
  CHECK(scale < 0.92);  // 1 / 1.15 = 0.87
  const double verdict = summary_number(dir / "out", "calibration_suspect_frame");
  CHECK(verdict > 0);
  CHECK(verdict < 100);
  auto bad = evaluate_run(dir / "bad", dir / "out");
  auto right = evaluate_run(dir / "seq", dir / "right");
  REQUIRE(bad.ok());
  REQUIRE(right.ok());
  MESSAGE("focal lengths 15 % long: " << format_eval_table(bad.value()));
  MESSAGE("right calibration: " << format_eval_table(right.value()));
  CHECK(bad->result.lost_pct == 0.0);  // tracking went on, and was off:
  CHECK(bad->result.tre_median_px > 3.0 * right->result.tre_median_px);
}

TEST_CASE("app_e2e: sequences --check refuses are refused before tracking with a clear error") {
  const auto dir = test::scratch_dir("app_e2e_refuse");
  simulate(dir / "seq", 3, "160x90", 1);
  auto text = read_file(dir / "seq" / "sequence.yaml", 1 << 20);
  REQUIRE(text.ok());
  auto config = parse_sequence_yaml(text.value());
  REQUIRE(config.ok());
  SUBCASE("mesh behind the camera at T_init") {
    SequenceConfig c = config.value();
    c.T_camera_model_init = SE3(Mat3::Identity(), Vec3(0, 0, -2000));
    REQUIRE(write_sequence_files(dir / "seq", c).ok());
    CHECK(test::run_shell(test::bin_command("scopetrack") + " --check " +
                          test::shell_quoted(dir / "seq") + " > /dev/null") == 1);
    std::string err;
    CHECK(track(dir / "seq", dir / "out", &err) == 1);
    CHECK(err.find("not usable") != std::string::npos);
    CHECK(err.find("behind the camera") != std::string::npos);
    CHECK_FALSE(std::filesystem::exists(dir / "out" / "summary.json"));
  }
  SUBCASE("missing mesh file") {
    std::filesystem::remove(dir / "seq" / config->mesh);
    std::string err;
    CHECK(track(dir / "seq", dir / "out", &err) == 1);
    CHECK(err.find("does not exist") != std::string::npos);
  }
  SUBCASE("bad command line") {
    CHECK(test::run_shell(test::bin_command("scopetrack") + " --sequence " +
                          test::shell_quoted(dir / "seq") + " 2> /dev/null") == 2);  // no --out
    CHECK(test::run_shell(test::bin_command("scopetrack") + " --sequence " +
                          test::shell_quoted(dir / "seq") + " --out x --fast 2> /dev/null") == 2);
    // Each bad value: exit 2, the message, no output written.
    const auto refused = [&](const std::string& option, std::initializer_list<const char*> values,
                             const std::string& message) {
      for (const char* v : values) {
        CAPTURE(option);
        CAPTURE(v);
        std::string err;
        CHECK(track(dir / "seq", dir / "out_bad", &err, " " + option + v) == 2);
        CHECK(err.find(message) != std::string::npos);
        CHECK_FALSE(std::filesystem::exists(dir / "out_bad" / "summary.json"));
      }
    };
    refused("--ba-lag ", {"0", "-1", "1001", "3x", "''", "1e2"}, "--ba-lag takes a whole number of frames in 1..1000");
    refused("--ring ", {"1", "65", "x", "''"}, "--ring takes a slot count in 2..64");
    refused("--stream-wait ", {"-1", "65", "2.5"}, "--stream-wait takes a console count in 0..64");
    refused("--set ba.w_shape=", {"-1", "1e7", "nan", "inf", "3x", "''"}, "ba.w_shape: ");
    refused("--set max_raster_triangles=", {"-1", "4000001", "3x", "''", "1e4"},
            "max_raster_triangles: ");
    refused("--set fast_reference_contrast=", {"-1", "256", "nan", "inf", "3x", "1e"},
            "fast_reference_contrast: ");
    refused("--set registration_sigma_deg=", {"-1", "91", "nan", "3x"}, "registration_sigma_deg: ");
    refused("--set ", {"no_such_key=1", "=1", "use_mask"}, "--set ");
    refused("--set use_mask=", {"2", "yes"}, "use_mask: ");
    // Checks across keys (the tracker's): refused before the replay too.
    refused("--set max_raster_triangles=", {"999"}, "max_raster_triangles 999 outside [1000");
    refused("--set registration_sigma_mm=", {"1"}, "registration prior");
  }
}

// The settings file: the printed defaults, read back, track exactly as no
// file does; a misspelt key or a value out of range is refused (exit 2)
// with the key named, before anything is written.
TEST_CASE("app_e2e: --print-config, read back by --config, tracks as the defaults do, bad files exit 2" *
          doctest::timeout(test::budget_s(300))) {
  const auto dir = test::scratch_dir("app_e2e_settings");
  simulate(dir / "seq", 60, "480x270", 1);
  const std::string app = test::bin_command("scopetrack");
  const auto settings = dir / "settings.yaml";
  REQUIRE(test::run_shell(app + " --print-config > " + test::shell_quoted(settings)) == 0);
  std::string err;
  REQUIRE_MESSAGE(track(dir / "seq", dir / "plain", &err, kDeterministic) == 0, err);
  REQUIRE_MESSAGE(track(dir / "seq", dir / "filed", &err, kDeterministic + " --config " + test::shell_quoted(settings)) == 0,
                  err);
  const std::string plain = test::read_file_bytes(dir / "plain" / "trajectory.txt");
  CHECK(data_lines(dir / "plain" / "trajectory.txt") > 30);
  CHECK(plain == test::read_file_bytes(dir / "filed" / "trajectory.txt"));

  // One line changed: the key and what was wrong with it.
  const std::string text = test::read_file_bytes(settings);
  const auto with_line = [&](const std::string& from, const std::string& to) {
    const std::size_t at = text.find(from);
    REQUIRE(at != std::string::npos);
    std::string t = text;
    t.replace(at, from.size(), to);
    REQUIRE(write_file(dir / "bad.yaml", t).ok());
  };
  const auto refused = [&](const std::string& message) {
    std::filesystem::remove_all(dir / "out_bad");
    CHECK(track(dir / "seq", dir / "out_bad", &err, " --config " + test::shell_quoted(dir / "bad.yaml")) == 2);
    CHECK_MESSAGE(err.find(message) != std::string::npos, err);
    CHECK_FALSE(std::filesystem::exists(dir / "out_bad" / "summary.json"));
  };
  with_line("min_inlier_ratio: 0.35", "min_inlier_ration: 0.35");
  refused("unknown setting 'min_inlier_ration'");
  with_line("features.n_features: 1500", "features.n_features: 40");
  refused("features.n_features: '40' is not a whole number in 50..4096");
  with_line("ba.w_shape: 100", "ba.w_shape: -3");
  refused("ba.w_shape: '-3' is not a number in 0..1e+06");
  with_line("use_mask: 1", "use_mask: 1\nuse_mask: 0");
  refused("use_mask is given twice");
  CHECK(track(dir / "seq", dir / "out_bad", &err, " --config " + test::shell_quoted(dir / "missing.yaml")) == 2);
  CHECK(err.find("--config") != std::string::npos);
}

