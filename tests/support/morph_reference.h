// The reference for morph_square in tests: OpenCV's erode (k < 0) or dilate
// (k > 0) with a (2|k| + 1)-square kernel and its default border; k == 0
// copies.
#pragma once

#include <cstdlib>
#include <opencv2/imgproc.hpp>

namespace st::test {

inline cv::Mat opencv_morph_square(const cv::Mat& in, int k) {
  const int size = 2 * std::abs(k) + 1;
  const cv::Mat kernel = cv::getStructuringElement(cv::MORPH_RECT, cv::Size(size, size));
  cv::Mat out;
  if (k < 0)
    cv::erode(in, out, kernel);
  else
    cv::dilate(in, out, kernel);
  return out;
}

}  // namespace st::test
