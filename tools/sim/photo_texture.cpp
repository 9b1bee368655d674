#include "tools/sim/photo_texture.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <opencv2/imgproc.hpp>

#include "hal/capture/y4m_reader.h"
#include "tools/sim/corner_density.h"

namespace st::sim {
namespace {

constexpr int kMinCropPx = 64;
// A field stop's black is the level at the image's corners; lit is above
// it by this much (after a blur that evens out the sensor noise). Corners
// brighter than kMaxBlackLevel mean there is no field stop.
constexpr int kLitMargin = 10, kMaxBlackLevel = 40, kCornerPx = 32;
// Share of the image lit above which there is no field stop to avoid.
constexpr double kNoFieldStopShare = 0.97;

// The largest axis-aligned square inside the lit region (a scope's disc):
// the inscribed circle from the distance transform, then its square.
cv::Rect lit_square(const cv::Mat& luma) {
  const int k = std::min({kCornerPx, luma.cols / 4, luma.rows / 4});
  double black = 255;
  for (const cv::Point corner : {cv::Point(0, 0), cv::Point(luma.cols - k, 0), cv::Point(0, luma.rows - k),
                                 cv::Point(luma.cols - k, luma.rows - k)})
    black = std::min(black, cv::mean(luma(cv::Rect(corner, cv::Size(k, k))))[0]);
  if (black > kMaxBlackLevel) return {0, 0, luma.cols, luma.rows};
  cv::Mat smooth, lit;
  cv::GaussianBlur(luma, smooth, cv::Size(), 4.0);
  cv::threshold(smooth, lit, black + kLitMargin, 255, cv::THRESH_BINARY);
  if (cv::countNonZero(lit) >= kNoFieldStopShare * static_cast<double>(luma.total()))
    return {0, 0, luma.cols, luma.rows};
  // The image's edge bounds the square too: an unlit frame around it.
  cv::Mat framed, dist;
  cv::copyMakeBorder(lit, framed, 1, 1, 1, 1, cv::BORDER_CONSTANT, cv::Scalar(0));
  cv::distanceTransform(framed, dist, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  double r = 0;
  cv::Point c;
  cv::minMaxLoc(dist, nullptr, &r, nullptr, &c);
  c -= cv::Point(1, 1);
  const int half = static_cast<int>(std::floor(r / std::sqrt(2.0))) - 4;  // 4 px inside the rim
  if (half <= 0) return {};
  return cv::Rect(c.x - half, c.y - half, 2 * half, 2 * half) & cv::Rect(0, 0, luma.cols, luma.rows);
}

// Mirror-repeat of a coordinate into [0, n - 1].
inline float mirror(float u, int n) {
  const float period = 2.0f * static_cast<float>(n - 1);
  float m = std::fmod(u, period);
  if (m < 0) m += period;
  return m > static_cast<float>(n - 1) ? period - m : m;
}

}  // namespace

Result<std::shared_ptr<const PhotoTexture>> PhotoTexture::load(const std::filesystem::path& y4m, double px_per_mm) {
  Y4mReader reader;
  if (Status s = reader.open(y4m, 1); !s) return make_error("texture " + y4m.string() + ": " + s.message());
  FrameRef frame;
  if (reader.read_frame(&frame) != ReadResult::kFrame)
    return make_error("texture " + y4m.string() + ": no frame" +
                      (reader.error().empty() ? std::string() : " (" + reader.error() + ")"));
  const cv::Mat view(frame.y.height, frame.y.width, CV_8U, const_cast<std::uint8_t*>(frame.y.data),
                     static_cast<std::size_t>(frame.y.stride));
  auto out = from_luma(view.clone(), px_per_mm);
  if (!out) return make_error("texture " + y4m.string() + ": " + out.message());
  return out;
}

Result<std::shared_ptr<const PhotoTexture>> PhotoTexture::from_luma(const cv::Mat& luma, double px_per_mm) {
  if (luma.empty() || luma.type() != CV_8U) return make_error("texture: not an 8-bit luma image");
  if (!(px_per_mm > 0.0) || !std::isfinite(px_per_mm) || px_per_mm > 1000.0)
    return make_error("texture scale must be in (0, 1000] photo pixels per mm");
  const cv::Rect crop = lit_square(luma);
  if (crop.width < kMinCropPx || crop.height < kMinCropPx)
    return make_error("texture: the lit part of the photo is smaller than " + std::to_string(kMinCropPx) + " x " +
                      std::to_string(kMinCropPx) + " pixels");
  cv::Mat linear;
  luma(crop).convertTo(linear, CV_32F, 1.0 / 255.0);
  cv::pow(linear, 2.2, linear);  // the photo's display gamma undone: albedo is linear
  // The camera's noise and the JPEG's blocks are no tissue; undone, they
  // would be the strongest "texture" of a dark, smooth liver.
  cv::GaussianBlur(linear, linear, cv::Size(), kDenoiseSigmaPx);
  // Highlights move with the light, not the tissue: fill them (and their
  // rims) from the surrounding tissue by normalised convolution.
  const cv::Mat keep = exclude_highlights(luma(crop), cv::Mat(crop.size(), CV_8U, cv::Scalar(255)), kHighlightLevel,
                                          kHighlightMarginPx);
  // Coarser and coarser until the middle of a large highlight is reached.
  cv::Mat weight, num, den;
  keep.convertTo(weight, CV_32F, 1.0 / 255.0);
  const cv::Mat kept = linear.mul(weight);
  cv::Mat clean = linear.clone(), filled = keep.clone();
  for (double sigma = kFillSigmaPx; sigma <= 8 * kFillSigmaPx; sigma *= 2) {
    cv::GaussianBlur(kept, num, cv::Size(), sigma, 0.0, cv::BORDER_REFLECT);
    cv::GaussianBlur(weight, den, cv::Size(), sigma, 0.0, cv::BORDER_REFLECT);
    for (int y = 0; y < clean.rows; ++y)
      for (int x = 0; x < clean.cols; ++x)
        if (!filled.at<std::uint8_t>(y, x) && den.at<float>(y, x) > 0.05f) {
          clean.at<float>(y, x) = num.at<float>(y, x) / den.at<float>(y, x);
          filled.at<std::uint8_t>(y, x) = 255;
        }
  }
  const float mean = static_cast<float>(cv::mean(linear, keep)[0]);
  clean.setTo(mean, filled == 0);
  // The photo's illumination (light falloff, shading of the organ's shape)
  // is what a wide mean keeps; the ratio to it is the tissue.
  cv::Mat illumination;
  cv::GaussianBlur(clean, illumination, cv::Size(), kIlluminationSigmaPx, 0.0, cv::BORDER_REFLECT);
  auto t = std::make_shared<PhotoTexture>();
  t->crop_ = crop;
  t->px_per_mm_ = px_per_mm;
  t->ratio_.create(clean.size(), CV_32F);
  for (int y = 0; y < clean.rows; ++y)
    for (int x = 0; x < clean.cols; ++x) {
      const float ill = std::max(illumination.at<float>(y, x), 1e-4f);
      t->ratio_.at<float>(y, x) = std::clamp(clean.at<float>(y, x) / ill, kMinRatio, kMaxRatio);
    }
  return std::shared_ptr<const PhotoTexture>(std::move(t));
}

float PhotoTexture::sample(float u, float v) const {
  const float x = mirror(u, ratio_.cols), y = mirror(v, ratio_.rows);
  const int x0 = std::min(static_cast<int>(x), ratio_.cols - 2), y0 = std::min(static_cast<int>(y), ratio_.rows - 2);
  const float fx = x - static_cast<float>(x0), fy = y - static_cast<float>(y0);
  const float* r0 = ratio_.ptr<float>(y0);
  const float* r1 = ratio_.ptr<float>(y0 + 1);
  return (1 - fy) * ((1 - fx) * r0[x0] + fx * r0[x0 + 1]) + fy * ((1 - fx) * r1[x0] + fx * r1[x0 + 1]);
}

float PhotoTexture::ratio_at(const Vec3f& p, const Vec3f& normal) const {
  const float s = static_cast<float>(px_per_mm_);
  float w[3];
  float sum = 0;
  for (int a = 0; a < 3; ++a) {
    const float n2 = normal[a] * normal[a];
    w[a] = n2 * n2;
    sum += w[a];
  }
  if (!(sum > 0.0f)) return 1.0f;
  // Each plane's map starts elsewhere in the photo, so the three do not
  // show the same patch where they blend.
  const float r = w[0] * sample(s * p.y() + 0.0f, s * p.z() + 0.0f) +
                  w[1] * sample(s * p.x() + 311.0f, s * p.z() + 157.0f) +
                  w[2] * sample(s * p.x() + 97.0f, s * p.y() + 433.0f);
  return r / sum;
}

}  // namespace st::sim
