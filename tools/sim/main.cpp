// scopetrack-sim: writes a synthetic laparoscopic sequence with exact
// ground truth (docs/sequence-format.md).
//   scopetrack-sim --scenario NAME --out DIR [--frames N] [--size WxH]
//                  [--seed S] [--organ liver|kidney|stomach | --mesh FILE] [--prior-subdivide N] [--field-stop on|off] [--organ-detail F]
//                  [--shutter F] [--light F] [--smoke F] [--texture FILE.y4m] [--texture-scale PX_PER_MM]
//                  [--tissue textured|smooth] [--breathing MM]
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <string_view>

#include "core/formats/text_scan.h"
#include "tools/sim/organ_shapes.h"
#include "tools/sim/sim_run.h"

namespace {

// The CT liver of shared/data, where the build's SCOPETRACK_SHARED_DIR put it.
constexpr const char* kCtLiver = SCOPETRACK_SIM_CT_LIVER;

void usage(std::FILE* to) {
  std::fprintf(to,
               "usage: scopetrack-sim --scenario orbit|fast|outofview|manipulation|invivo|newview --out DIR\n"
               "                      [--frames N (300)] [--size WxH (1280x720; invivo 960x540)]\n"
               "                      [--seed S (1)] [--organ liver|kidney|stomach (liver) | --mesh FILE.ply|stl]\n"
               "                      [--field-stop on|off]\n"
               "                      [--prior-subdivide N (0; organ.ply split N times at edge midpoints:\n"
               "                       the same surface, 4^N times the triangles, as a dense CT export)]\n"
               "                      [--organ-detail F (1; lower = smoother tissue)]\n"
               "                      [--shutter F (0.5 of the frame interval; 0 = no motion blur)]\n"
               "                      [--light F (1: the scope light's power; lower = a dimmer, noisier scene)]\n"
               "                      [--smoke F (0: none; surgical smoke episodes, the veil's peak share 0..0.9)]\n"
               "                      [--texture FILE.y4m (organ texture from a photo's first frame)]\n"
               "                      [--texture-scale PX_PER_MM (4: photo pixels per mm of tissue)]\n"
               "                      [--tissue textured|smooth (textured; smooth: glossy, wet, ~1 corner per\n"
               "                       10k organ px, on the CT liver: --mesh defaults to %s)]\n"
               "                      [--breathing MM (0: none; the organ's largest displacement, period 4 s)]\n",
               kCtLiver);
}

// Returns an error message, or empty when all arguments were understood.
std::string parse_args(int argc, char** argv, st::sim::SimOptions* o) {
  bool have_scenario = false, have_organ = false;
  for (int i = 1; i < argc; ++i) {
    const std::string_view a = argv[i];
    if (i + 1 >= argc) return "missing value after " + std::string(a);
    const std::string_view v = argv[++i];
    long long n = 0;
    if (a == "--scenario") {
      auto k = st::sim::parse_scenario(v);
      if (!k) return k.message();
      o->scenario = k.value();
      have_scenario = true;
    } else if (a == "--out") {
      o->out_dir = std::string(v);
    } else if (a == "--frames") {
      if (!st::parse_int64_in(v, 1, 1'000'000, &n)) return "--frames wants an integer in 1..1000000";
      o->frames = static_cast<int>(n);
    } else if (a == "--size") {
      const auto x = v.find('x');
      long long w = 0, h = 0;
      if (x == std::string_view::npos || !st::parse_int64_in(v.substr(0, x), 16, 4096, &w) ||
          !st::parse_int64_in(v.substr(x + 1), 16, 4096, &h))
        return "--size wants WxH, e.g. 1280x720";
      o->width = static_cast<int>(w);
      o->height = static_cast<int>(h);
    } else if (a == "--seed") {
      if (!st::parse_int64_in(v, 0, (1ll << 62), &n)) return "--seed wants a non-negative integer";
      o->seed = static_cast<std::uint64_t>(n);
    } else if (a == "--organ") {
      auto k = st::sim::parse_organ(v);
      if (!k) return k.message();
      o->organ = k.value();
      have_organ = true;
    } else if (a == "--mesh") {
      o->mesh_file = std::string(v);
    } else if (a == "--prior-subdivide") {
      if (!st::parse_int64_in(v, 0, 3, &n)) return "--prior-subdivide wants 0..3 (each level: 4 times the triangles)";
      o->prior_subdivide = static_cast<int>(n);
    } else if (a == "--organ-detail") {
      if (!st::parse_double_in(v, 0.0, st::sim::kMaxOrganDetail, &o->organ_detail))
        return "--organ-detail wants a number in 0..2 (1: the calibrated tissue texture)";
    } else if (a == "--shutter") {
      if (!st::parse_double_in(v, 0.0, 1.0, &o->shutter))
        return "--shutter wants the open fraction of the frame interval, 0..1 (0: no motion blur)";
    } else if (a == "--light") {
      if (!st::parse_double_in(v, 0.05, 4.0, &o->light))
        return "--light wants the scope light's power relative to the default, 0.05..4";
    } else if (a == "--smoke") {
      if (!st::parse_double_in(v, 0.0, st::sim::kMaxSmoke, &o->smoke))
        return "--smoke wants the smoke veil's peak share of the view, 0..0.9 (0: no smoke)";
    } else if (a == "--texture") {
      o->texture_file = std::string(v);
    } else if (a == "--texture-scale") {
      if (!st::parse_double_in(v, 0.1, 1000.0, &o->texture_px_per_mm))
        return "--texture-scale wants photo pixels per mm of tissue, 0.1..1000";
    } else if (a == "--tissue") {
      if (v != "textured" && v != "smooth") return "--tissue wants textured or smooth";
      o->tissue = v == "smooth" ? st::sim::Tissue::Smooth : st::sim::Tissue::Textured;
    } else if (a == "--breathing") {
      if (!st::parse_double_in(v, 0.0, st::sim::kMaxBreathingMm, &o->breathing_mm))
        return "--breathing wants the organ's largest displacement in mm, 0..20 (0: none)";
    } else if (a == "--field-stop") {
      if (v != "on" && v != "off") return "--field-stop wants on or off";
      o->field_stop = v == "on" ? 1 : 0;
    } else {
      return "unknown option " + std::string(a);
    }
  }
  if (!have_scenario) return "--scenario is required";
  if (o->out_dir.empty()) return "--out is required";
  if (have_organ && !o->mesh_file.empty()) return "--organ and --mesh both name the organ: give one";
  if (o->tissue == st::sim::Tissue::Smooth) {
    if (have_organ) return "--tissue smooth is rendered on a mesh file (the CT liver), not on --organ";
    if (!o->texture_file.empty()) return "--tissue smooth and --texture both define the organ's texture: give one";
    if (o->mesh_file.empty()) {
      o->mesh_file = kCtLiver;
      std::error_code ec;
      if (!std::filesystem::is_regular_file(o->mesh_file, ec))
        return std::string("--tissue smooth renders the CT liver, not found at ") + kCtLiver +
               ": give its path with --mesh (shared/data/liver/liver.ply)";
    }
  }
  return {};
}

}  // namespace

int main(int argc, char** argv) {
  st::sim::SimOptions options;
  options.progress = true;
  if (argc == 2 && (std::string_view(argv[1]) == "--help" || std::string_view(argv[1]) == "-h")) {
    usage(stdout);
    return 0;
  }
  if (const std::string err = parse_args(argc, argv, &options); !err.empty()) {
    std::fprintf(stderr, "scopetrack-sim: %s\n", err.c_str());
    usage(stderr);
    return 2;
  }
  const auto report = st::sim::run_simulation(options);
  if (!report) {
    std::fprintf(stderr, "scopetrack-sim: %s\n", report.message().c_str());
    return 1;
  }
  std::printf("%s: %d frames in %.2f s (%.1f frames/s) -> %s\n",
              st::sim::scenario_name(options.scenario), report->frames, report->seconds, report->fps,
              options.out_dir.string().c_str());
  return 0;
}
