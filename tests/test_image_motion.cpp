// ImageMotion on the real laparoscopic frame: two 1280x720 windows of the
// 1080p frame offset by a known amount must give that shift (sign and size),
// also with one of them blurred along the motion (a fast turn), and a
// featureless frame must give no estimate rather than a made-up one.
#include <doctest/doctest.h>

#include <opencv2/imgproc.hpp>

#include "core/image_motion.h"
#include "hal/y4m_reader.h"
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

// The window whose content sits (sx, sy) pixels further right/down than
// the window at (x0, y0).
cv::Mat window(const cv::Mat& full, int x0, int y0, int sx, int sy) {
  return full(cv::Rect(x0 - sx, y0 - sy, 1280, 720)).clone();
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
  CHECK_FALSE(m.update(view_of(prev), GrayView{}, Vec2(0, 0), &shift));  // no previous frame yet
  {
    test::AllocationCounter guard;
    REQUIRE(m.update(view_of(cur), GrayView{}, Vec2(20, -10), &shift));
    CHECK(guard.count() == 0);
  }
  CHECK(std::abs(shift.x() - 37) < 2.0);
  CHECK(std::abs(shift.y() + 21) < 2.0);
  // A 40 px horizontal smear on the next frame (shifted by a further 50 px).
  cv::Mat blurred;
  cv::blur(window(full, 300, 180, 87, -21), blurred, cv::Size(41, 1));
  const bool blurred_ok = m.update(view_of(blurred), GrayView{}, Vec2(37, 0), &shift);
  MESSAGE("blurred shift " << shift.x() << " " << shift.y());
  REQUIRE(blurred_ok);
  CHECK(std::abs(shift.x() - 50) < 3.0);
  CHECK(std::abs(shift.y()) < 3.0);
  // A sudden turn the guess knows nothing about: 80 px back and 30 down.
  REQUIRE(m.update(view_of(window(full, 300, 180, 7, 9)), GrayView{}, Vec2(0, 0), &shift));
  CHECK(std::abs(shift.x() + 80) < 2.0);
  CHECK(std::abs(shift.y() - 30) < 2.0);
}

TEST_CASE("image_motion: a featureless frame gives no estimate") {
  ImageMotion m;
  REQUIRE(m.configure(640, 480).ok());
  const cv::Mat flat(480, 640, CV_8U, cv::Scalar(90));
  Vec2 shift(0, 0);
  m.update(view_of(flat), GrayView{}, Vec2(0, 0), &shift);
  CHECK_FALSE(m.update(view_of(flat), GrayView{}, Vec2(0, 0), &shift));
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
  CHECK_FALSE(m.update(view_of(window(full, 300, 180, 0, 0)), view_of(valid), Vec2(0, 0), &shift));
  REQUIRE(m.update(view_of(window(full, 300, 180, -25, 14)), view_of(valid), Vec2(0, 0), &shift));
  CHECK(std::abs(shift.x() + 25) < 2.0);
  CHECK(std::abs(shift.y() - 14) < 2.0);
}
