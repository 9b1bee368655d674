#include "tools/sim/corner_density.h"

#include <algorithm>

#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

namespace st::sim {

cv::Mat exclude_highlights(const cv::Mat& gray, const cv::Mat& mask, int highlight_level, int margin_px) {
  cv::Mat bright = gray >= highlight_level;
  const cv::Mat kernel = cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * margin_px + 1, 2 * margin_px + 1));
  cv::dilate(bright, bright, kernel);
  cv::Mat out = mask.clone();
  out.setTo(0, bright);
  return out;
}

std::vector<cv::Point> fast_corners(const cv::Mat& gray, const cv::Mat& mask, int threshold) {
  std::vector<cv::KeyPoint> kps;
  cv::FAST(gray, kps, threshold, true);
  std::vector<cv::Point> out;
  for (const cv::KeyPoint& k : kps) {
    const cv::Point p(cvRound(k.pt.x), cvRound(k.pt.y));
    if (mask.at<std::uint8_t>(p) != 0) out.push_back(p);
  }
  return out;
}

CornerDensity corner_density(const cv::Mat& gray, const cv::Mat& mask, int threshold) {
  CornerDensity d;
  d.corners = static_cast<int>(fast_corners(gray, mask, threshold).size());
  d.pixels = cv::countNonZero(mask);
  d.per_10k = d.pixels > 0 ? 1e4 * d.corners / d.pixels : 0.0;
  return d;
}

double repeated_share(const cv::Mat& gray_a, const cv::Mat& gray_b, const cv::Mat& mask, int threshold,
                      double radius_px, cv::Point shift_px) {
  const std::vector<cv::Point> a = fast_corners(gray_a, mask, threshold);
  if (a.empty()) return 0.0;
  // Corners of b anywhere (not only in mask): a corner at the mask's edge
  // may be found one pixel outside it in b.
  const cv::Mat all(gray_b.size(), CV_8U, cv::Scalar(255));
  const std::vector<cv::Point> b = fast_corners(gray_b, all, threshold);
  cv::Mat hit(gray_b.size(), CV_8U, cv::Scalar(0));
  for (const cv::Point& p : b) hit.at<std::uint8_t>(p) = 255;
  const int r = static_cast<int>(radius_px);
  int found = 0;
  for (const cv::Point& pa : a) {
    const cv::Point p = pa + shift_px;
    const cv::Rect win = cv::Rect(p.x - r, p.y - r, 2 * r + 1, 2 * r + 1) & cv::Rect(0, 0, hit.cols, hit.rows);
    if (cv::countNonZero(hit(win)) > 0) ++found;
  }
  return static_cast<double>(found) / static_cast<double>(a.size());
}

double surface_fixed_share(const cv::Mat& gray_a, const cv::Mat& gray_b, const cv::Mat& mask, int threshold,
                           double radius_px) {
  const double seen = repeated_share(gray_a, gray_b, mask, threshold, radius_px);
  const double chance = repeated_share(gray_a, gray_b, mask, threshold, radius_px, {9, 5});
  return chance < 1.0 ? std::max(0.0, (seen - chance) / (1.0 - chance)) : 0.0;
}

}  // namespace st::sim
