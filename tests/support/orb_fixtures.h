// Fixtures for the ORB frontend tests: the real frame's luma, a synthetic
// textured image, homography warps, and conversions to/from cv::Mat.
// The real frame is read through the project's Y4M parser (core/formats/y4m.h).
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "core/features/feature_set.h"
#include "core/image/image.h"

namespace st::test {

// Luma plane of ../shared/data/real/laparoscopy_liver_1080p.y4m (1920x1080,
// CV_8UC1); empty Mat if the file is missing or malformed.
cv::Mat real_frame_luma();
// The real frame resized (area) to width x height.
cv::Mat real_frame_luma(int width, int height);
// Deterministic texture: random discs/rectangles of luma 60..200, lightly
// blurred (never black, never saturated).
cv::Mat synthetic_texture(int width, int height, unsigned seed);

// A homography about the image centre: rotation (deg), isotropic scale and a
// perspective term (1/px along x and y).
cv::Matx33d centred_homography(int width, int height, double rot_deg, double scale,
                               double persp_x, double persp_y);
// src warped by H (bilinear, black outside).
cv::Mat warp(const cv::Mat& src, const cv::Matx33d& H);

inline GrayView view_of(const cv::Mat& m) {
  return GrayView(m.ptr<std::uint8_t>(0), m.cols, m.rows, static_cast<std::ptrdiff_t>(m.step[0]));
}
inline cv::Mat mat_of(GrayView v) {
  return cv::Mat(v.height, v.width, CV_8UC1, const_cast<std::uint8_t*>(v.data),
                 static_cast<std::size_t>(v.stride));
}

// cv::ORB output as a FeatureSet (same matcher and metrics for both).
void to_feature_set(const std::vector<cv::KeyPoint>& kps, const cv::Mat& desc, int width,
                    int height, FeatureSet& out);

}  // namespace st::test
