// How much trackable texture an image region has: FAST-9 corners per
// 10,000 region pixels (cv::FAST, non-max suppression on), highlights
// excluded, and the share of corners that are surface-fixed (found again
// within radius_px in a second image of the same surface, e.g. the same
// frame rendered with another sensor-noise seed). Used by the texture
// calibration test (tests/test_sim_corners.cpp) to compare the simulated
// organ against the real liver frame. Tool code: allocates freely.
#pragma once

#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

namespace st::sim {

// The liver region of the real frame (shared/data/real/laparoscopy_liver_1080p),
// in its 1920x1080 pixels: a rectangle inside the left liver lobe, below the
// small highlight at (600, 390) and above the gallbladder/specular edge.
inline const cv::Rect kRealLiverRect1080p{400, 420, 620, 160};

struct CornerDensity {
  int corners = 0;
  int pixels = 0;
  double per_10k = 0;  // corners per 10,000 region pixels
};

// Region mask without highlights: mask && no pixel >= highlight_level within
// margin_px (a highlight's rim is full of corners that move with the light).
cv::Mat exclude_highlights(const cv::Mat& gray, const cv::Mat& mask, int highlight_level = 215,
                           int margin_px = 4);
// FAST corners (threshold on 8-bit gray) whose pixel lies in mask (CV_8U, != 0).
std::vector<cv::Point> fast_corners(const cv::Mat& gray, const cv::Mat& mask, int threshold);
CornerDensity corner_density(const cv::Mat& gray, const cv::Mat& mask, int threshold);
// Share of corners of a (in mask) that have a corner of b within radius_px
// of the same pixel + shift_px; 0 when a has none. With a shift of several
// pixels it measures the chance of a hit (dense corners always find a
// neighbour): surface_fixed_share() corrects for it.
double repeated_share(const cv::Mat& gray_a, const cv::Mat& gray_b, const cv::Mat& mask, int threshold,
                      double radius_px = 2.0, cv::Point shift_px = {0, 0});
// (repeated - chance) / (1 - chance), chance = repeated_share at a shift of
// (9, 5) px: the share of a's corners that are in b because of the surface.
double surface_fixed_share(const cv::Mat& gray_a, const cv::Mat& gray_b, const cv::Mat& mask, int threshold,
                           double radius_px = 2.0);

}  // namespace st::sim
