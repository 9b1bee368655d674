// AreaScaler: the working resolution's area filter against OpenCV's
// INTER_AREA (exact area weights in float) at the ratios the tower's
// frames need (3:2, 3:1, 2:1, each through its 8-lane path) and at an odd
// one (the table path), a flat plane kept flat, the same size returned
// as it is, bad sizes refused, and no allocation while scaling; the
// 4:2:0 frame scaler's planes.
#include <doctest/doctest.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <opencv2/imgproc.hpp>
#include <random>

#include "core/image/area_scale.h"
#include "core/image/image.h"
#include "support/alloc_guard.h"

using namespace st;

namespace {

// Smooth shading, a few hard edges, noise: what a frame has.
Image<std::uint8_t> scene(int w, int h, unsigned seed) {
  Image<std::uint8_t> img(w, h);
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> noise(-6, 6);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      int v = 40 + (150 * x) / w + (40 * y) / h + noise(rng);
      if ((x / 37 + y / 23) % 5 == 0) v += 50;
      img(x, y) = static_cast<std::uint8_t>(std::clamp(v, 0, 255));
    }
  return img;
}

int max_difference_to_opencv(const Image<std::uint8_t>& in, int out_w, int out_h, Image<std::uint8_t>* out) {
  AreaScaler s;
  REQUIRE(s.configure(in.width(), in.height(), out_w, out_h).ok());
  out->allocate(out_w, out_h);
  REQUIRE(s.scale(in.cview(), out->view()));
  const cv::Mat src(in.height(), in.width(), CV_8U, const_cast<std::uint8_t*>(in.data()));
  cv::Mat ref;
  cv::resize(src, ref, cv::Size(out_w, out_h), 0, 0, cv::INTER_AREA);
  int worst = 0;
  for (int y = 0; y < out_h; ++y)
    for (int x = 0; x < out_w; ++x) worst = std::max(worst, std::abs(int{(*out)(x, y)} - int{ref.at<std::uint8_t>(y, x)}));
  return worst;
}

}  // namespace

TEST_CASE("area scale: the tower's frames to the working size, within a level of OpenCV's area filter") {
  struct Case {
    int in_w, in_h, out_w, out_h;
  };
  for (const Case c : {Case{1920, 1080, 1280, 720}, Case{3840, 2160, 1280, 720}, Case{1920, 1080, 960, 540},
                       Case{960, 540, 640, 360}, Case{1001, 777, 640, 497}, Case{1280, 720, 1280, 720},
                       Case{643, 361, 97, 51}}) {
    CAPTURE(c.in_w);
    CAPTURE(c.out_w);
    const Image<std::uint8_t> in = scene(c.in_w, c.in_h, static_cast<unsigned>(c.in_w + c.out_w));
    Image<std::uint8_t> out;
    CHECK(max_difference_to_opencv(in, c.out_w, c.out_h, &out) <= 1);
  }
}

TEST_CASE("area scale: a flat plane stays flat, the same size is a copy") {
  for (const int v : {0, 1, 127, 254, 255}) {
    Image<std::uint8_t> in(1920, 1080), out(1280, 720);
    in.fill(static_cast<std::uint8_t>(v));
    AreaScaler s;
    REQUIRE(s.configure(1920, 1080, 1280, 720).ok());
    REQUIRE(s.scale(in.cview(), out.view()));
    bool flat = true;
    for (int y = 0; y < 720; ++y)
      for (int x = 0; x < 1280; ++x) flat = flat && out(x, y) == v;
    CHECK(flat);
  }
  const Image<std::uint8_t> in = scene(333, 211, 5);
  Image<std::uint8_t> out(333, 211);
  AreaScaler s;
  REQUIRE(s.configure(333, 211, 333, 211).ok());
  REQUIRE(s.scale(in.cview(), out.view()));
  bool same = true;
  for (int y = 0; y < 211; ++y)
    for (int x = 0; x < 333; ++x) same = same && out(x, y) == in(x, y);
  CHECK(same);
}

TEST_CASE("area scale: sizes it cannot serve are refused, frames of another size left alone") {
  AreaScaler s;
  CHECK_FALSE(s.configure(0, 720, 640, 360).ok());
  CHECK_FALSE(s.configure(1280, 720, 1281, 720).ok());  // no upscaling
  CHECK_FALSE(s.configure(1280, 720, 0, 360).ok());
  CHECK_FALSE(s.configure(5000, 720, 1280, 360).ok());  // beyond the image caps
  CHECK_FALSE(s.configure(1280, 720, 100, 360).ok());   // more than 8x down
  Image<std::uint8_t> unconfigured_out(10, 10);
  CHECK_FALSE(s.scale(Image<std::uint8_t>(20, 20).cview(), unconfigured_out.view()));
  REQUIRE(s.configure(1920, 1080, 1280, 720).ok());
  Image<std::uint8_t> wrong_in(1280, 720), out(1280, 720), wrong_out(1000, 720);
  out.fill(7);
  CHECK_FALSE(s.scale(wrong_in.cview(), out.view()));
  CHECK(out(0, 0) == 7);
  CHECK_FALSE(s.scale(Image<std::uint8_t>(1920, 1080).cview(), wrong_out.view()));
}

TEST_CASE("area scale: band by band, the rows equal the whole frame's, rows outside the band refused") {
  struct Case {
    int in_w, in_h, out_w, out_h;
  };
  std::mt19937 rng(5);
  for (const Case c : {Case{1920, 1080, 1280, 720}, Case{3840, 2160, 1280, 720}, Case{1001, 777, 640, 497},
                       Case{643, 361, 97, 51}}) {
    CAPTURE(c.in_w);
    CAPTURE(c.out_w);
    const Image<std::uint8_t> in = scene(c.in_w, c.in_h, 11);
    AreaScaler s;
    REQUIRE(s.configure(c.in_w, c.in_h, c.out_w, c.out_h).ok());
    Image<std::uint8_t> whole(c.out_w, c.out_h), banded(c.out_w, c.out_h);
    REQUIRE(s.scale(in.cview(), whole.view()));
    banded.fill(0);
    // Bands of random heights: each scales the output rows whose input
    // rows it completes, from the first row the next output row needs.
    int j = 0, next_row = 0;
    while (next_row < c.in_h) {
      const int keep = j < c.out_h ? s.input_row_begin(j) : next_row;
      next_row = std::min(c.in_h, next_row + std::uniform_int_distribution<int>(1, 40)(rng));
      int j_end = j;
      while (j_end < c.out_h && s.input_row_end(j_end) <= next_row) ++j_end;
      CHECK(j_end - j <= next_row - keep);
      REQUIRE(s.scale_rows(in.cview().sub(0, keep, c.in_w, next_row - keep), keep, j, j_end, banded.view()));
      j = j_end;
    }
    CHECK(j == c.out_h);
    CHECK(std::equal(whole.data(), whole.data() + static_cast<std::ptrdiff_t>(c.out_w) * c.out_h, banded.data()));
    for (int k = 1; k < c.out_h; ++k) {
      CHECK(s.input_row_begin(k) >= s.input_row_begin(k - 1));
      CHECK(s.input_row_end(k) >= s.input_row_end(k - 1));
      CHECK(s.input_row_end(k) - s.input_row_begin(k) <= s.max_rows_per_output());
    }
  }
  AreaScaler s;
  REQUIRE(s.configure(1920, 1080, 1280, 720).ok());
  const Image<std::uint8_t> in = scene(1920, 1080, 12);
  Image<std::uint8_t> out(1280, 720);
  out.fill(7);
  // Output row 10 reads input rows 15 and 16: a band from row 16 lacks one,
  // a band of rows 0-15 lacks the other.
  CHECK(s.input_row_begin(10) == 15);
  CHECK(s.input_row_end(10) == 17);
  CHECK_FALSE(s.scale_rows(in.cview().sub(0, 16, 1920, 100), 16, 10, 11, out.view()));
  CHECK_FALSE(s.scale_rows(in.cview().sub(0, 0, 1920, 16), 0, 10, 11, out.view()));
  CHECK_FALSE(s.scale_rows(in.cview(), 0, 10, 721, out.view()));
  CHECK_FALSE(s.scale_rows(in.cview(), 0, 11, 10, out.view()));
  CHECK(out(0, 10) == 7);
  CHECK(s.scale_rows(in.cview().sub(0, 15, 1920, 2), 15, 10, 11, out.view()));
}

TEST_CASE("area scale: scaling allocates nothing") {
  const Image<std::uint8_t> in = scene(1920, 1080, 3);
  Image<std::uint8_t> out(1280, 720), odd_out(700, 400);
  AreaScaler s, odd;
  REQUIRE(s.configure(1920, 1080, 1280, 720).ok());
  REQUIRE(odd.configure(1920, 1080, 700, 400).ok());
  const test::AllocationCounter counter;
  for (int i = 0; i < 3; ++i) {
    CHECK(s.scale(in.cview(), out.view()));
    CHECK(odd.scale(in.cview(), odd_out.view()));
  }
  CHECK(counter.count() == 0);
}

TEST_CASE("area scale: a 4:2:0 frame's three planes, the chroma only when it has the frame's chroma size") {
  const Image<std::uint8_t> y = scene(1920, 1080, 8), u = scene(960, 540, 9), v = scene(960, 540, 10);
  FrameScaler frame;
  REQUIRE(frame.configure(1920, 1080, 1280, 720).ok());
  Image<std::uint8_t> oy(1280, 720), ou(640, 360), ov(640, 360), ref(640, 360);
  bool chroma = false;
  REQUIRE(frame.scale(y.cview(), u.cview(), v.cview(), oy.view(), ou.view(), ov.view(), &chroma));
  CHECK(chroma);
  AreaScaler plane;
  REQUIRE(plane.configure(960, 540, 640, 360).ok());
  REQUIRE(plane.scale(v.cview(), ref.view()));
  bool same = true;
  for (int r = 0; r < 360; ++r)
    for (int c = 0; c < 640; ++c) same = same && ov(c, r) == ref(c, r);
  CHECK(same);
  REQUIRE(frame.scale(y.cview(), GrayView{}, GrayView{}, oy.view(), ou.view(), ov.view(), &chroma));
  CHECK_FALSE(chroma);  // no chroma: the luma alone
  const Image<std::uint8_t> odd = scene(900, 540, 11);
  REQUIRE(frame.scale(y.cview(), odd.cview(), v.cview(), oy.view(), ou.view(), ov.view(), &chroma));
  CHECK_FALSE(chroma);  // a plane of another size
  CHECK_FALSE(frame.scale(u.cview(), u.cview(), v.cview(), oy.view(), ou.view(), ov.view(), &chroma));
}
