#include "core/features/orb_matcher.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>

#include <opencv2/core/hal/intrin.hpp>

#include "core/base/capacity.h"

namespace st {

// 256-bit Hamming distance. The portable build targets baseline x86-64,
// where std::popcount is a libgcc call per word; the universal-intrinsics
// path counts bits per byte in two 16-byte registers and sums them with
// one horizontal add (psadbw on SSE2, cnt + addv on NEON).
int hamming256(const std::uint8_t* a, const std::uint8_t* b) {
#if CV_SIMD128
  const cv::v_uint8x16 x0 = cv::v_load(a) ^ cv::v_load(b);
  const cv::v_uint8x16 x1 = cv::v_load(a + 16) ^ cv::v_load(b + 16);
  return static_cast<int>(cv::v_reduce_sum(cv::v_popcount(x0) + cv::v_popcount(x1)));
#else
  return hamming256_portable(a, b);
#endif
}

int hamming256_portable(const std::uint8_t* a, const std::uint8_t* b) {
  int d = 0;
  for (int i = 0; i < 4; ++i) {
    std::uint64_t x, y;
    std::memcpy(&x, a + 8 * i, 8);
    std::memcpy(&y, b + 8 * i, 8);
    d += std::popcount(x ^ y);
  }
  return d;
}

#if ST_HAVE_POPCNT
namespace {
inline std::uint64_t word(const std::uint8_t* p, int i) {
  std::uint64_t w;
  std::memcpy(&w, p + 8 * i, sizeof w);
  return w;
}

// Bits differing between the words q0..q3 and descriptor t: one POPCNT a
// word (compiled for POPCNT whatever the board's flags; only reached where
// the CPU has it).
ST_POPCNT inline int popcnt256(std::uint64_t q0, std::uint64_t q1, std::uint64_t q2,
                                                       std::uint64_t q3, const std::uint8_t* t) {
  return __builtin_popcountll(q0 ^ word(t, 0)) + __builtin_popcountll(q1 ^ word(t, 1)) +
         __builtin_popcountll(q2 ^ word(t, 2)) + __builtin_popcountll(q3 ^ word(t, 3));
}

// The query's words and the best two stay in registers over the scan of
// train's descriptors idx[0..n) (0..n when idx is null).
template <typename BestTwo>
ST_POPCNT void scan_popcnt(const std::uint8_t* q, const FeatureSet& train,
                                                    const std::int32_t* idx, int n, BestTwo* out) {
  const std::uint64_t q0 = word(q, 0), q1 = word(q, 1), q2 = word(q, 2), q3 = word(q, 3);
  BestTwo b = *out;
  // No lambda here: it would not carry the target attribute, and POPCNT
  // code does not inline into it.
  for (int j = 0; j < n; ++j) {
    const int k = idx ? idx[j] : j;
    b.add(popcnt256(q0, q1, q2, q3, train.descriptors[static_cast<std::size_t>(k)].data()), k);
  }
  *out = b;
}
}  // namespace

int hamming256_popcnt(const std::uint8_t* a, const std::uint8_t* b) {
  return popcnt256(word(a, 0), word(a, 1), word(a, 2), word(a, 3), b);
}
#else
int hamming256_popcnt(const std::uint8_t* a, const std::uint8_t* b) { return hamming256(a, b); }
#endif

void OrbMatcher::scan(const std::uint8_t* q, const FeatureSet& train, const std::int32_t* idx, int n, bool popcnt,
                      BestTwo* b) {
#if ST_HAVE_POPCNT
  if (popcnt) {
    scan_popcnt(q, train, idx, n, b);
    return;
  }
#else
  (void)popcnt;
#endif
  for (int j = 0; j < n; ++j) {
    const int k = idx ? idx[j] : j;
    b->add(hamming256(q, train.descriptors[static_cast<std::size_t>(k)].data()), k);
  }
}

bool OrbMatcher::accept(const BestTwo& b) {
  if (b.best_k < 0 || b.best > config_.max_distance) return false;
  if (b.second < kNoCandidate && static_cast<float>(b.best) >= config_.ratio * static_cast<float>(b.second)) {
    ++stats_.ratio_rejected;
    return false;
  }
  return true;
}

int OrbMatcher::finish(const FeatureSet& frame, int n, int* match) {
  orientation_filter(ref_angles_.data(), frame, n, match);
  int count = 0;
  for (int i = 0; i < n; ++i) count += match[i] >= 0 ? 1 : 0;
  stats_.matched = count;
  return count;
}

Status OrbMatcher::configure(const MatchConfig& c) {
  if (c.max_distance < 0 || c.max_distance > 256) return make_error("MatchConfig.max_distance must be in [0, 256]");
  if (!(c.ratio > 0.f && c.ratio <= 1.f)) return make_error("MatchConfig.ratio must be in (0, 1]");
  if (c.rotation_bins < 3 || c.rotation_bins > 360) return make_error("MatchConfig.rotation_bins must be in [3, 360]");
  if (c.octave_window < 0 || c.octave_window > kMaxPyramidLevels) return make_error("MatchConfig.octave_window must be in [0, kMaxPyramidLevels]");
  config_ = c;
  const std::size_t n = std::max<std::size_t>(kMaxMapPoints, kMaxKeypoints);
  claimed_by_.assign(kMaxKeypoints, -1);
  claim_dist_.assign(kMaxKeypoints, 0);
  candidates_.assign(kMaxKeypoints, 0);
  dist_scratch_.assign(n, 0);
  best_dist_.assign(n, kNoCandidate);
  ref_angles_.assign(n, -1.f);
  rot_bin_count_.assign(static_cast<std::size_t>(c.rotation_bins), 0);
  return Status::Ok();
}

// The closer claim on a keypoint wins; the loser's match is cleared.
bool OrbMatcher::claim(int point, int keypoint, int distance, int* match_of_point, int* distance_of_point) {
  const std::size_t k = static_cast<std::size_t>(keypoint);
  const int holder = claimed_by_[k];
  if (holder >= 0) {
    if (claim_dist_[k] <= distance) return false;
    match_of_point[holder] = -1;
  }
  claimed_by_[k] = point;
  claim_dist_[k] = distance;
  match_of_point[point] = keypoint;
  distance_of_point[point] = distance;
  return true;
}

void OrbMatcher::orientation_filter(const float* ref_angle, const FeatureSet& frame, int n, int* match) {
  if (!config_.check_orientation) return;
  const int bins = config_.rotation_bins;
  std::fill(rot_bin_count_.begin(), rot_bin_count_.end(), 0);
  auto bin_of = [&](int i) {
    float rot = frame.keypoints[static_cast<std::size_t>(match[i])].angle_deg - ref_angle[i];
    rot = std::fmod(rot + 720.f, 360.f);
    return std::min(static_cast<int>(rot * static_cast<float>(bins) / 360.f), bins - 1);
  };
  for (int i = 0; i < n; ++i)
    if (match[i] >= 0 && ref_angle[i] >= 0.f) ++rot_bin_count_[static_cast<std::size_t>(bin_of(i))];
  int top[3] = {-1, -1, -1};
  for (int b = 0; b < bins; ++b) {
    const int c = rot_bin_count_[static_cast<std::size_t>(b)];
    if (c == 0) continue;
    if (top[0] < 0 || c > rot_bin_count_[static_cast<std::size_t>(top[0])]) { top[2] = top[1]; top[1] = top[0]; top[0] = b; }
    else if (top[1] < 0 || c > rot_bin_count_[static_cast<std::size_t>(top[1])]) { top[2] = top[1]; top[1] = b; }
    else if (top[2] < 0 || c > rot_bin_count_[static_cast<std::size_t>(top[2])]) { top[2] = b; }
  }
  if (top[0] < 0) return;
  const int best = rot_bin_count_[static_cast<std::size_t>(top[0])];
  for (int j = 1; j < 3; ++j)
    if (top[j] >= 0 && rot_bin_count_[static_cast<std::size_t>(top[j])] * 10 < best) top[j] = -1;
  for (int i = 0; i < n; ++i) {
    if (match[i] < 0 || ref_angle[i] < 0.f) continue;
    const int b = bin_of(i);
    if (b != top[0] && b != top[1] && b != top[2]) {
      if (match[i] >= 0) claimed_by_[static_cast<std::size_t>(match[i])] = -1;
      match[i] = -1;
      ++stats_.orientation_rejected;
    }
  }
}

int OrbMatcher::search_by_projection(const ProjectedPoint* points, int n, const FeatureSet& frame,
                                     const FeatureGrid& grid, int* match, int* distance,
                                     const std::uint8_t* active) {
  stats_ = MatchStats{};
  n = std::clamp(n, 0, kMaxMapPoints);
  if (!distance) distance = dist_scratch_.data();
  std::fill(claimed_by_.begin(), claimed_by_.begin() + std::clamp(frame.count, 0, kMaxKeypoints), -1);
  const bool popcnt = config_.use_popcnt && cpu_has_popcnt();
  for (int i = 0; i < n; ++i) {
    const ProjectedPoint& p = points[i];
    match[i] = -1;
    distance[i] = 256;
    ref_angles_[static_cast<std::size_t>(i)] = p.ref_angle_deg;
    best_dist_[static_cast<std::size_t>(i)] = kNoCandidate;
    if (active && !active[i]) continue;
    const int lo = p.predicted_octave < 0 ? -1 : std::max(0, p.predicted_octave - config_.octave_window);
    const int hi = p.predicted_octave < 0 ? -1 : p.predicted_octave + config_.octave_window;
    const int nc = grid.query(p.x, p.y, p.radius_px, lo, hi, candidates_.data(), kMaxKeypoints);
    BestTwo b;
    scan(p.descriptor.data(), frame, candidates_.data(), nc, popcnt, &b);
    stats_.candidates += nc;
    best_dist_[static_cast<std::size_t>(i)] = static_cast<std::uint16_t>(b.best);  // kNoCandidate if none
    if (accept(b)) claim(i, b.best_k, b.best, match, distance);
  }
  return finish(frame, n, match);
}

int OrbMatcher::match_brute_force(const FeatureSet& query, const FeatureSet& train, int* match, int* distance) {
  stats_ = MatchStats{};
  const int nq = std::clamp(query.count, 0, kMaxKeypoints), nt = std::clamp(train.count, 0, kMaxKeypoints);
  if (!distance) distance = dist_scratch_.data();
  std::fill(claimed_by_.begin(), claimed_by_.begin() + nt, -1);
  const bool popcnt = config_.use_popcnt && cpu_has_popcnt();
  for (int i = 0; i < nq; ++i) {
    match[i] = -1;
    distance[i] = 256;
    ref_angles_[static_cast<std::size_t>(i)] = query.keypoints[static_cast<std::size_t>(i)].angle_deg;
    const std::uint8_t* q = query.descriptors[static_cast<std::size_t>(i)].data();
    BestTwo b;
    scan(q, train, nullptr, nt, popcnt, &b);
    stats_.candidates += nt;
    if (accept(b)) claim(i, b.best_k, b.best, match, distance);
  }
  return finish(train, nq, match);
}

}  // namespace st
