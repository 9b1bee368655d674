#include "support/orb_fixtures.h"

#include <cstring>
#include <random>
#include <string_view>

#include <opencv2/imgproc.hpp>

#include "core/formats/y4m.h"
#include "support/support.h"

namespace st::test {

cv::Mat real_frame_luma() {
  const std::string bytes = read_file_bytes(shared_data("real/laparoscopy_liver_1080p.y4m"));
  const std::string_view all(bytes);
  const Result<Y4mHeader> header = parse_y4m_header(all);
  if (!header) return {};
  const Result<std::size_t> frame_line = parse_y4m_frame_line(all.substr(header->header_bytes));
  if (!frame_line) return {};
  const std::size_t y_start = header->header_bytes + frame_line.value();
  if (bytes.size() < y_start + header->frame_bytes()) return {};
  cv::Mat y(header->height, header->width, CV_8UC1);
  std::memcpy(y.data, bytes.data() + y_start, header->luma_bytes());
  return y;
}

cv::Mat real_frame_luma(int width, int height) {
  const cv::Mat full = real_frame_luma();
  if (full.empty()) return {};
  cv::Mat out;
  cv::resize(full, out, cv::Size(width, height), 0, 0, cv::INTER_AREA);
  return out;
}

cv::Mat synthetic_texture(int width, int height, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> ux(0, width - 1), uy(0, height - 1), ur(3, 40), ul(60, 200);
  cv::Mat img(height, width, CV_8UC1, cv::Scalar(130));
  // One draw per statement: the order in which a call's arguments are
  // evaluated is unspecified (GCC takes these right to left on x86-64, left
  // to right on aarch64), and draws inside one call made another image on
  // another platform. The order below is the one x86-64 builds always took,
  // so the image there is the same as before.
  for (int i = 0; i < width * height / 400; ++i) {
    const int y = uy(rng);
    const int x = ux(rng);
    const int r = ur(rng);
    const int level = ul(rng);
    if (i % 2) {
      cv::circle(img, cv::Point(x, y), r, cv::Scalar(level), cv::FILLED, cv::LINE_AA);
    } else {
      const int h = ur(rng);
      cv::rectangle(img, cv::Rect(x, y, r, h), cv::Scalar(level), cv::FILLED);
    }
  }
  cv::GaussianBlur(img, img, cv::Size(3, 3), 0.8);
  return img;
}

cv::Matx33d centred_homography(int width, int height, double rot_deg, double scale,
                               double persp_x, double persp_y) {
  const double cx = width / 2.0, cy = height / 2.0;
  const double a = rot_deg * CV_PI / 180.0;
  const cv::Matx33d T1(1, 0, -cx, 0, 1, -cy, 0, 0, 1);
  const cv::Matx33d RS(scale * std::cos(a), -scale * std::sin(a), 0, scale * std::sin(a),
                       scale * std::cos(a), 0, 0, 0, 1);
  const cv::Matx33d P(1, 0, 0, 0, 1, 0, persp_x, persp_y, 1);
  const cv::Matx33d T2(1, 0, cx, 0, 1, cy, 0, 0, 1);
  return T2 * P * RS * T1;
}

cv::Mat warp(const cv::Mat& src, const cv::Matx33d& H) {
  cv::Mat out;
  cv::warpPerspective(src, out, H, src.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
  return out;
}

void to_feature_set(const std::vector<cv::KeyPoint>& kps, const cv::Mat& desc, int width,
                    int height, FeatureSet& out) {
  out.clear();
  out.width = width;
  out.height = height;
  for (std::size_t i = 0; i < kps.size() && out.count < kMaxKeypoints; ++i) {
    Keypoint& k = out.keypoints[static_cast<std::size_t>(out.count)];
    k.x = kps[i].pt.x;
    k.y = kps[i].pt.y;
    k.angle_deg = kps[i].angle;
    k.response = kps[i].response;
    k.octave = kps[i].octave;
    std::memcpy(out.descriptors[static_cast<std::size_t>(out.count)].data(), desc.ptr(static_cast<int>(i)), 32);
    ++out.count;
  }
}

}  // namespace st::test
