// ORB descriptor matching: Hamming distance, search by projection through a
// FeatureGrid (tracking), brute force (relocalisation). Both apply the
// best / second-best ratio test, keep at most one match per frame keypoint
// (the closer claim wins), and can apply ORB-SLAM's orientation consistency
// check: a histogram of (frame angle - reference angle) in rotation_bins
// bins keeps only matches in the three fullest bins (a bin must hold at
// least 10% of the fullest to count).
//
// configure() allocates the scratch (kMaxMapPoints / kMaxKeypoints);
// matching allocates nothing. Tracking thread (one instance per thread).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "core/base/cpu_features.h"
#include "core/features/feature_grid.h"
#include "core/features/feature_set.h"
#include "core/base/result.h"

namespace st {

// Hamming distance of two 32-byte descriptors: SIMD where the build has it,
// else hamming256_portable (word popcounts), which tests compare against.
int hamming256(const std::uint8_t* a, const std::uint8_t* b);
int hamming256_portable(const std::uint8_t* a, const std::uint8_t* b);
// On an x86-64 CPU with the POPCNT instruction (cpu_has_popcnt(), detected
// at run time: the generic board's baseline ISA lacks it, nearly every CPU
// has it) matching counts bits with it: the same distances, about 2x faster
// than the SSE2 count (brute force).
// hamming256 by four POPCNTs. Call only where cpu_has_popcnt().
int hamming256_popcnt(const std::uint8_t* a, const std::uint8_t* b);

struct MatchConfig {
  int max_distance = 100;       // reject matches with a larger Hamming distance (of 256 bits)
  float ratio = 0.8f;           // best < ratio * second best (1 disables)
  bool check_orientation = true;
  int rotation_bins = 30;       // 12 degrees per bin
  int octave_window = 1;        // search by projection: predicted octave +- this
  bool use_popcnt = true;       // count bits with the POPCNT instruction where the CPU has it
                                // (false: hamming256 as built, for tests and comparisons)
};

// A map point projected into the current frame (level-0 pixels).
struct ProjectedPoint {
  float x = 0.f, y = 0.f;
  float radius_px = 0.f;       // search radius, level-0 pixels (scale it by the predicted octave's scale)
  int predicted_octave = -1;   // -1: any octave
  float ref_angle_deg = -1.f;  // angle of the observation the descriptor came from; < 0: skip the orientation check
  Descriptor descriptor{};
};

struct MatchStats {
  int candidates = 0;          // descriptor comparisons
  int ratio_rejected = 0;
  int orientation_rejected = 0;
  int matched = 0;
};

class OrbMatcher {
 public:
  Status configure(const MatchConfig& config);

  // For each of n points (n <= kMaxMapPoints), the index of its matching
  // keypoint in frame, or -1, into match_of_point[n] (distances into
  // distance_of_point[n] if not null). grid must be built on frame. Points
  // with active[i] == 0 (when active is not null) are not searched: no
  // match. Returns the number of matches.
  int search_by_projection(const ProjectedPoint* points, int n, const FeatureSet& frame,
                           const FeatureGrid& grid, int* match_of_point, int* distance_of_point,
                           const std::uint8_t* active = nullptr);
  // Per point of the last search_by_projection: the smallest Hamming
  // distance among its candidates (kNoCandidate if it had none or was not
  // searched), whether or not it matched. A point whose best exceeds
  // config().max_distance cannot match any subset of those candidates.
  static constexpr std::uint16_t kNoCandidate = 257;
  std::span<const std::uint16_t> best_distances() const { return best_dist_; }

  // For each keypoint of query, the index of its match in train or -1, into
  // match_of_query[query.count]. Orientation check uses both sets' angles.
  int match_brute_force(const FeatureSet& query, const FeatureSet& train, int* match_of_query,
                        int* distance_of_query);

  const MatchConfig& config() const { return config_; }
  const MatchStats& stats() const { return stats_; }

 private:
  // Best and second-best Hamming distance over one point's candidates.
  struct BestTwo {
    int best = kNoCandidate, second = kNoCandidate, best_k = -1;
    void add(int d, int k) {
      if (d < best) { second = best; best = d; best_k = k; }
      else if (d < second) { second = d; }
    }
  };
  // Adds train's descriptors idx[0..n) (0..n when idx is null) to b for one
  // query descriptor, counting bits with POPCNT if popcnt.
  static void scan(const std::uint8_t* q, const FeatureSet& train, const std::int32_t* idx, int n, bool popcnt,
                   BestTwo* b);
  // Max-distance and ratio tests (counts ratio rejections).
  bool accept(const BestTwo& b);
  // Orientation filter, then the match count (into stats_).
  int finish(const FeatureSet& frame, int n, int* match_of_point);
  bool claim(int point, int keypoint, int distance, int* match_of_point, int* distance_of_point);
  void orientation_filter(const float* ref_angle, const FeatureSet& frame, int n,
                          int* match_of_point);
  MatchConfig config_;
  MatchStats stats_;
  std::vector<std::int32_t> claimed_by_;     // per frame keypoint: point index or -1
  std::vector<std::int32_t> claim_dist_;
  std::vector<std::int32_t> candidates_;     // grid query scratch
  std::vector<std::int32_t> dist_scratch_;   // distances when the caller passes none
  std::vector<std::uint16_t> best_dist_;     // per point of the last search: best candidate distance
  std::vector<float> ref_angles_;            // per point / query keypoint
  std::vector<std::int32_t> rot_bin_count_;
};

}  // namespace st
