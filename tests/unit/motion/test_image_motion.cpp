// ImageMotion on the real laparoscopic frame: two 1280x720 windows of the
// 1080p frame offset by a known amount must give that shift (sign and size),
// also with one of them blurred along the motion (a fast turn); a window
// turned about a point off its centre must give that roll and the shift of
// the centre; a featureless frame must give no estimate rather than a
// made-up one.
#include <doctest/doctest.h>

#include <opencv2/imgproc.hpp>

#include "core/motion/image_motion.h"
#include "hal/capture/y4m_reader.h"
#include "platform/alloc_counter.h"
#include "tests/support/alloc_guard.h"
#include "tests/support/support.h"

using namespace st;

namespace {

cv::Mat real_luma() {
  Y4mReader reader;
  REQUIRE(reader.open(test::shared_data("real/laparoscopy_liver_1080p.y4m")));
  FrameRef f;
  REQUIRE(reader.read_frame(&f) == ReadResult::kFrame);
  return cv::Mat(f.y.height, f.y.width, CV_8U, const_cast<std::uint8_t*>(f.y.data), static_cast<std::size_t>(f.y.stride)).clone();
}

GrayView view_of(const cv::Mat& m) { return GrayView(m.data, m.cols, m.rows, static_cast<std::ptrdiff_t>(m.step)); }

const Vec2 kCentre(639.5, 359.5);

ViewMotion shift_of(double x, double y) {
  ViewMotion m;
  m.shift_px = Vec2(x, y);
  return m;
}

// update() with a pure-shift guess; the estimate's shift (roll in *roll).
bool update(ImageMotion& m, const cv::Mat& frame, GrayView valid, const Vec2& guess, Vec2* shift,
            double* roll = nullptr) {
  ViewMotion out;
  const bool ok = m.update(view_of(frame), valid, kCentre, shift_of(guess.x(), guess.y()), &out);
  *shift = out.shift_px;
  if (roll) *roll = out.roll_rad;
  return ok;
}

// The window whose content sits (sx, sy) pixels further right/down than
// the window at (x0, y0).
cv::Mat window(const cv::Mat& full, int x0, int y0, int sx, int sy) {
  return full(cv::Rect(x0 - sx, y0 - sy, 1280, 720)).clone();
}

// The current window: the full frame turned by roll about the point pivot
// of the previous window (its pixels), then shifted by (sx, sy); the
// previous window sits at (x0, y0) of the full frame.
cv::Mat rolled_window(const cv::Mat& full, int x0, int y0, double roll_deg, const Vec2& pivot, double sx, double sy) {
  const double r = roll_deg * M_PI / 180.0, c = std::cos(r), s = std::sin(r);
  // current(q) = full(A^-1 (q - b)) with q = pivot + R (x - pivot) + (sx, sy), x = window pixel.
  const cv::Point2d p(pivot.x() + x0, pivot.y() + y0);  // pivot in the full frame
  cv::Mat M = (cv::Mat_<double>(2, 3) << c, -s, pivot.x() + sx - (c * p.x - s * p.y),  //
               s, c, pivot.y() + sy - (s * p.x + c * p.y));
  cv::Mat out;
  cv::warpAffine(full, out, M, cv::Size(1280, 720), cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  return out;
}

}  // namespace

TEST_CASE("image_motion: known shift of the real frame, sharp and motion-blurred") {
  const cv::Mat full = real_luma();
  REQUIRE(full.cols >= 1900);
  ImageMotion m;
  REQUIRE(m.configure(1280, 720).ok());
  const cv::Mat prev = window(full, 300, 180, 0, 0);
  const cv::Mat cur = window(full, 300, 180, 37, -21);
  Vec2 shift(0, 0);
  CHECK_FALSE(update(m, prev, GrayView{}, Vec2(0, 0), &shift));  // no previous frame yet
  {
    test::AllocationCounter guard;
    double roll = 1.0;
    REQUIRE(update(m, cur, GrayView{}, Vec2(20, -10), &shift, &roll));
    CHECK(std::abs(roll) < 0.2 * M_PI / 180.0);
    CHECK(guard.count() == 0);
  }
  CHECK(std::abs(shift.x() - 37) < 2.0);
  CHECK(std::abs(shift.y() + 21) < 2.0);
  // A 40 px horizontal smear on the next frame (shifted by a further 50 px).
  cv::Mat blurred;
  cv::blur(window(full, 300, 180, 87, -21), blurred, cv::Size(41, 1));
  const bool blurred_ok = update(m, blurred, GrayView{}, Vec2(37, 0), &shift);
  MESSAGE("blurred shift " << shift.x() << " " << shift.y());
  REQUIRE(blurred_ok);
  CHECK(std::abs(shift.x() - 50) < 3.0);
  CHECK(std::abs(shift.y()) < 3.0);
  // A sudden turn the guess knows nothing about: 80 px back and 30 down.
  REQUIRE(update(m, window(full, 300, 180, 7, 9), GrayView{}, Vec2(0, 0), &shift));
  CHECK(std::abs(shift.x() + 80) < 2.0);
  CHECK(std::abs(shift.y() - 30) < 2.0);
}

TEST_CASE("image_motion: a featureless frame gives no estimate") {
  ImageMotion m;
  REQUIRE(m.configure(640, 480).ok());
  const cv::Mat flat(480, 640, CV_8U, cv::Scalar(90));
  Vec2 shift(0, 0);
  update(m, flat, GrayView{}, Vec2(0, 0), &shift);
  CHECK_FALSE(update(m, flat, GrayView{}, Vec2(0, 0), &shift));
  CHECK_FALSE(m.configure(100, 100).ok());
}

TEST_CASE("image_motion: a valid mask at half resolution (the tracker's) is sampled in its own pixels") {
  const cv::Mat full = real_luma();
  ImageMotion m;
  REQUIRE(m.configure(1280, 720).ok());
  // Half-resolution valid mask with the left quarter invalid: it must be
  // read inside its own 640x360 buffer (ASan catches a full-resolution
  // read) and still give the shift from the valid part.
  cv::Mat valid(360, 640, CV_8U, cv::Scalar(255));
  valid(cv::Rect(0, 0, 160, 360)).setTo(0);
  Vec2 shift(0, 0);
  CHECK_FALSE(update(m, window(full, 300, 180, 0, 0), view_of(valid), Vec2(0, 0), &shift));
  REQUIRE(update(m, window(full, 300, 180, -25, 14), view_of(valid), Vec2(0, 0), &shift));
  CHECK(std::abs(shift.x() + 25) < 2.0);
  CHECK(std::abs(shift.y() - 14) < 2.0);
}

TEST_CASE("image_motion: a roll about the optical axis, sharp and motion-blurred") {
  const cv::Mat full = real_luma();
  ImageMotion m;
  REQUIRE(m.configure(1280, 720).ok());
  // The scope's field stop: only a disc of the view is valid (the tracker's
  // half-resolution mask), so the corners cannot carry the roll.
  cv::Mat valid(360, 640, CV_8U, cv::Scalar(0));
  cv::circle(valid, cv::Point(320, 180), 175, cv::Scalar(255), -1);
  const cv::Mat prev = full(cv::Rect(300, 180, 1280, 720)).clone();
  Vec2 shift;
  double roll = 0;
  CHECK_FALSE(update(m, prev, view_of(valid), Vec2(0, 0), &shift, &roll));
  // 4 degrees about a point off the centre, plus a shift: the centre moves
  // by pivot + R (centre - pivot) + shift - centre.
  const Vec2 pivot(500, 300), sh(-12, 7);
  const double r = 4.0 * M_PI / 180.0;
  const Eigen::Rotation2Dd R(r);
  const Vec2 centre_moves = pivot + R * (kCentre - pivot) + sh - kCentre;
  REQUIRE(update(m, rolled_window(full, 300, 180, 4.0, pivot, sh.x(), sh.y()), view_of(valid), Vec2(0, 0), &shift, &roll));
  MESSAGE("roll " << roll * 180.0 / M_PI << " deg, centre shift " << shift.x() << " " << shift.y() << " (true "
                  << centre_moves.x() << " " << centre_moves.y() << ")");
  CHECK(std::abs(roll - r) < 0.15 * M_PI / 180.0);
  CHECK((shift - centre_moves).norm() < 2.0);
  // Then -3 degrees about the centre, smeared 25 px along x: a roll of -7
  // degrees from the last frame, past the coarse search's +-6 around a
  // zero guess (Gauss-Newton takes the rest).
  const cv::Mat next = rolled_window(full, 300, 180, -3.0, kCentre, 0, 0);
  cv::Mat blurred;
  cv::blur(next, blurred, cv::Size(25, 1));
  REQUIRE(update(m, blurred, view_of(valid), Vec2(0, 0), &shift, &roll));
  MESSAGE("blurred roll " << roll * 180.0 / M_PI << " deg (true -7)");
  CHECK(std::abs(roll + 7.0 * M_PI / 180.0) < 0.3 * M_PI / 180.0);
}
