// Stage "features": our ORB frontend (valid mask + extract, 1500 keypoints,
// 8 levels x 1.2) against cv::ORB (1500 features, 8 levels, 1.2, one
// thread) on the same 1280x720 frames made from the real frame (resized,
// rotated, scaled, perspective-warped), in the same run.
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "bench.h"
#include "core/formats/text_scan.h"
#include "core/image/image_pyramid.h"
#include "core/features/orb_extractor.h"
#include "core/features/orb_matcher.h"
#include "core/image/valid_mask.h"
#include "core/formats/y4m.h"

namespace {

// Luma of the one-frame Y4M, through the project's parser (core/formats/y4m.h).
cv::Mat read_luma(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  const std::string_view all(bytes);
  const st::Result<st::Y4mHeader> header = st::parse_y4m_header(all);
  if (!header) return {};
  const st::Result<std::size_t> frame_line = st::parse_y4m_frame_line(all.substr(header->header_bytes));
  if (!frame_line) return {};
  const std::size_t y0 = header->header_bytes + frame_line.value();
  if (bytes.size() < y0 + header->frame_bytes()) return {};
  cv::Mat y(header->height, header->width, CV_8UC1);
  std::memcpy(y.data, bytes.data() + y0, header->luma_bytes());
  return y;
}

std::vector<cv::Mat> make_frames(const cv::Mat& full, int n) {
  cv::Mat base;
  cv::resize(full, base, cv::Size(1280, 720), 0, 0, cv::INTER_AREA);
  std::vector<cv::Mat> frames;
  for (int i = 0; i < n; ++i) {
    const double a = (i % 7 - 3) * 4.0 * CV_PI / 180.0, s = 1.0 + 0.04 * (i % 5 - 2);
    const double px = 1e-4 * (i % 3 - 1);
    const cv::Matx33d T1(1, 0, -640, 0, 1, -360, 0, 0, 1), T2(1, 0, 640, 0, 1, 360, 0, 0, 1);
    const cv::Matx33d RS(s * std::cos(a), -s * std::sin(a), 0, s * std::sin(a), s * std::cos(a), 0, px, 0, 1);
    cv::Mat out;
    cv::warpPerspective(base, out, T2 * RS * T1, base.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT, 0);
    frames.push_back(out);
  }
  return frames;
}

// Relocalisation's brute-force matching (every keypoint of one frame
// against every keypoint of another: two warped real frames), with the
// POPCNT count where the CPU has it, against the same matcher counting
// with SSE2 (the generic board's baseline ISA), in the same run.
bool bench_brute_force(const st::bench::Options& opt, const std::vector<cv::Mat>& frames, st::OrbExtractor& orb,
                       st::ValidMaskBuilder& valid) {
  auto a = std::make_unique<st::FeatureSet>(), b = std::make_unique<st::FeatureSet>();
  for (int k = 0; k < 2; ++k) {
    const cv::Mat& f = frames[static_cast<std::size_t>(k)];
    const st::GrayView view(f.ptr<std::uint8_t>(0), f.cols, f.rows, static_cast<std::ptrdiff_t>(f.step[0]));
    orb.extract(view, st::GrayView(), valid.build(view), k == 0 ? *a : *b);
  }
  const int iterations = opt.iterations > 0 ? opt.iterations : 30;
  std::vector<int> match(static_cast<std::size_t>(a->count) + 1);
  std::vector<double> ms[2];
  int matched[2] = {0, 0};
  for (int use_popcnt = 0; use_popcnt < 2; ++use_popcnt) {
    st::OrbMatcher matcher;
    st::MatchConfig mc;
    mc.use_popcnt = use_popcnt == 1;
    if (!matcher.configure(mc)) return false;
    for (int i = -2; i < iterations; ++i) {
      const double t0 = st::bench::now_ms();
      matched[use_popcnt] = matcher.match_brute_force(*a, *b, match.data(), nullptr);
      if (i >= 0) ms[use_popcnt].push_back(st::bench::now_ms() - t0);
    }
  }
  char note[200];
  std::snprintf(note, sizeof note, "%d x %d keypoints, %d / %d matches; POPCNT %s on this CPU", a->count, b->count,
                matched[1], matched[0], st::cpu_has_popcnt() ? "used" : "absent (both rows the same count)");
  st::bench::report(opt, {"features.match_brute_force", ms[1], "same matcher, SSE2 bit count", ms[0], note});
  return true;
}

int bench_features(const st::bench::Options& opt) {
  const cv::Mat full = read_luma(opt.shared_dir + "/data/real/laparoscopy_liver_1080p.y4m");
  if (full.empty()) {
    std::fprintf(stderr, "features: cannot read the real frame under %s\n", opt.shared_dir.c_str());
    return 1;
  }
  cv::setNumThreads(1);
  const int iterations = opt.iterations > 0 ? opt.iterations : 60;
  const std::vector<cv::Mat> frames = make_frames(full, 12);
  st::OrbExtractor orb;
  st::ValidMaskBuilder valid;
  st::OrbConfig config;  // args: [relaxed_threshold [strict_threshold]] to explore
  for (std::size_t k = 0; k < opt.args.size() && k < 2; ++k) {
    long long t = 0;
    if (!st::parse_int64_in(opt.args[k], 1, 254, &t)) {
      std::fprintf(stderr, "bench features: FAST thresholds are whole numbers in 1..254\n");
      return 2;
    }
    (k == 0 ? config.fast_threshold_relaxed : config.fast_threshold_strict) = static_cast<int>(t);
  }
  if (!orb.configure(config, 1280, 720) || !valid.configure(st::ValidMaskConfig{}, 1280, 720)) return 1;
  auto features = std::make_unique<st::FeatureSet>();
  st::ImagePyramid pyramid;  // the same pyramid alone, to split the time
  if (!pyramid.configure(1280, 720, config.levels, config.scale_factor)) return 1;
  cv::Ptr<cv::ORB> cv_orb = cv::ORB::create(1500, 1.2f, 8);
  std::vector<cv::KeyPoint> kps;
  cv::Mat desc;
  std::vector<double> ours_ms, ours_extract_ms, mask_ms, cv_ms, pyramid_ms;
  double n_ours = 0, n_cv = 0;
  for (int i = -3; i < iterations; ++i) {  // 3 warm-up rounds
    const cv::Mat& f = frames[static_cast<std::size_t>((i + 3) % static_cast<int>(frames.size()))];
    const st::GrayView view(f.ptr<std::uint8_t>(0), f.cols, f.rows, static_cast<std::ptrdiff_t>(f.step[0]));
    const double t0 = st::bench::now_ms();
    const st::GrayView vm = valid.build(view);
    const double t1 = st::bench::now_ms();
    orb.extract(view, st::GrayView(), vm, *features);
    const double t2 = st::bench::now_ms();
    cv_orb->detectAndCompute(f, cv::noArray(), kps, desc);
    const double t3 = st::bench::now_ms();
    pyramid.build_levels(view);  // extract smooths only the tiles of kept patches, later
    const double t4 = st::bench::now_ms();
    if (i < 0) continue;
    pyramid_ms.push_back(t4 - t3);
    mask_ms.push_back(t1 - t0);
    ours_extract_ms.push_back(t2 - t1);
    ours_ms.push_back(t2 - t0);
    cv_ms.push_back(t3 - t2);
    n_ours += features->count;
    n_cv += static_cast<double>(kps.size());
  }
  char note[160];
  std::snprintf(note, sizeof note, "1280x720, mean keypoints: ours %.0f, cv::ORB %.0f", n_ours / iterations,
                n_cv / iterations);
  st::bench::report(opt, {"features.orb_frontend (mask+extract)", ours_ms, "cv::ORB detectAndCompute", cv_ms, note});
  st::bench::report(opt, {"features.orb_extract", ours_extract_ms, "", {}, ""});
  st::bench::report(opt, {"features.valid_mask", mask_ms, "", {}, ""});
  st::bench::report(opt, {"features.pyramid levels, no smoothing (part of extract)", pyramid_ms, "", {}, ""});
  return bench_brute_force(opt, frames, orb, valid) ? 0 : 1;
}

}  // namespace

SCOPETRACK_BENCH_STAGE("features", "ORB frontend vs cv::ORB at 1280x720, 1500 keypoints", bench_features);
