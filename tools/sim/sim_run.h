// One simulated sequence, end to end: scene + prior + trajectory + renderer,
// written in the format of docs/sequence-format.md (video.y4m C420jpeg,
// organ.ply, sequence.yaml, groundtruth.txt, markers.txt). Used by the
// scopetrack-sim executable, the tests and the evaluator's tests.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <vector>

#include <opencv2/core.hpp>

#include "core/mesh/mesh.h"
#include "core/base/result.h"
#include "core/formats/trajectory.h"
#include "tools/sim/organ_shapes.h"
#include "tools/sim/renderer.h"
#include "tools/sim/scenario.h"
#include "tools/sim/scene.h"

namespace st::sim {

struct SimOptions {
  ScenarioKind scenario = ScenarioKind::Orbit;
  std::filesystem::path out_dir;
  int frames = 300;
  int width = 0, height = 0;  // 0: the scenario's default (1280x720; invivo 960x540)
  std::uint64_t seed = 1;
  OrganKind organ = OrganKind::Liver;  // the procedural organ when mesh_file is empty
  std::filesystem::path mesh_file;  // empty: the procedural organ
  int prior_subdivide = 0;          // organ.ply subdivided this many times (same surface, 4^N triangles)
  int field_stop = -1;              // -1: scenario default (invivo only), 0 off, 1 on
  double organ_detail = 1.0;        // RenderSettings::organ_detail (1: calibrated on the real liver)
  double shutter = kDefaultShutter; // RenderSettings::shutter (0: no motion blur)
  // The scope light's power relative to the default (RenderSettings::exposure
  // times this): below 1 a dimmer scene, whose sensor noise stays that of the
  // sensor, so the signal-to-noise ratio falls as on a real camera.
  double light = 1.0;
  double smoke = 0.0;               // RenderSettings::smoke (0: no surgical smoke)
  std::filesystem::path texture_file;  // a Y4M photo for the organ's texture; empty: procedural
  double texture_px_per_mm = PhotoTexture::kDefaultPxPerMm;
  // RenderSettings::tissue. Smooth is rendered on a mesh file (the CT
  // liver, shared/data/liver/liver.ply): make_setup refuses it without one.
  Tissue tissue = Tissue::Textured;
  double breathing_mm = 0.0;        // RenderSettings::breathing_mm (0: a rigid organ)
  bool progress = false;            // progress bar on stderr
};

// Everything a run needs, built once (allocates). The renderer keeps a
// pointer to `scene`: keep the SimSetup where it is while rendering.
struct SimSetup {
  Scene scene;
  Mesh prior;  // what organ.ply holds: the rendered mesh, or for invivo a decimated, perturbed copy
  RenderSettings render;
  double fps = 30.0;
  int frames = 0;
};
Result<SimSetup> make_setup(const SimOptions& options);

struct SimReport {
  int frames = 0;
  double seconds = 0;  // wall time of the frame loop (render + convert + write)
  double fps = 0;
  std::vector<Marker> markers;
  std::vector<TimedPose> groundtruth;
};

// Called after every frame with its 8-bit RGB image and labels (renderer.h).
using FrameSink = std::function<void(int frame, const cv::Mat& rgb, const cv::Mat& labels)>;
Result<SimReport> run_simulation(const SimOptions& options, const FrameSink& sink = {});

// Three markers well spread (farthest-point in the image) over the organ
// pixels of frame 0 that lie at least margin_px inside the organ's region.
std::vector<Marker> pick_markers(const std::vector<std::pair<Vec2, Vec3>>& candidates);

}  // namespace st::sim
