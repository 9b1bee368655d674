// morph_square through MorphBuffers: one configure-time scratch serves masks
// of any size within it (the occluder and valid masks pass bands of rows),
// matches OpenCV's erode/dilate, allocates nothing after configure, and a
// scratch too small for the mask leaves the output untouched.
#include <doctest/doctest.h>

#include <cstdint>
#include <opencv2/imgproc.hpp>
#include <random>
#include <utility>

#include "core/image/image.h"
#include "core/image/mask_morphology.h"
#include "support/alloc_guard.h"
#include "support/morph_reference.h"

using namespace st;

namespace {

// Random blobs: discs of random radius, so both thin and wide structures.
Image<std::uint8_t> blobs(int w, int h, unsigned seed) {
  Image<std::uint8_t> m(w, h);
  m.fill(0);
  cv::Mat view(h, w, CV_8U, m.data());
  std::mt19937 rng(seed);
  for (int i = 0; i < 40; ++i) {
    const int x = static_cast<int>(rng() % static_cast<unsigned>(w));
    const int y = static_cast<int>(rng() % static_cast<unsigned>(h));
    cv::circle(view, {x, y}, 2 + static_cast<int>(rng() % 30u), cv::Scalar(255), cv::FILLED);
  }
  return m;
}

}  // namespace

TEST_CASE("mask morphology: one MorphBuffers serves every size within it, as OpenCV, without allocating") {
  MorphBuffers buffers;
  buffers.configure(320, 240);
  // Full size, a band of rows (as the occluder and valid masks pass), and
  // a narrower mask.
  for (const auto& [w, h] : {std::pair{320, 240}, std::pair{320, 37}, std::pair{211, 240}}) {
    const Image<std::uint8_t> in = blobs(w, h, static_cast<unsigned>(w * 1000 + h));
    Image<std::uint8_t> out(w, h);
    const cv::Mat in_mat(h, w, CV_8U, const_cast<std::uint8_t*>(in.data()));
    for (int k : {-20, -3, -1, 0, 2, 17}) {
      const cv::Mat expected = test::opencv_morph_square(in_mat, k);
      {
        test::AllocationCounter guard;
        morph_square(in.view(), k, out.view(), buffers.scratch(w, h));
        CHECK(guard.count() == 0);
      }
      const cv::Mat ours(h, w, CV_8U, out.data());
      CAPTURE(w);
      CAPTURE(h);
      CAPTURE(k);
      CHECK(cv::countNonZero(ours != expected) == 0);
    }
  }
}

TEST_CASE("mask morphology: a scratch smaller than the mask, or mismatched sizes, leave the output untouched") {
  MorphBuffers buffers;
  buffers.configure(64, 48);
  const Image<std::uint8_t> in = blobs(100, 48, 3);
  Image<std::uint8_t> out(100, 48);
  out.fill(7);
  // Wider than configured: scratch() hands out no buffers.
  morph_square(in.view(), 3, out.view(), buffers.scratch(100, 48));
  CHECK(out(0, 0) == 7);
  CHECK(out(99, 47) == 7);
  // A view that fits the buffers but not the mask.
  morph_square(in.view(), -2, out.view(), buffers.scratch(64, 48));
  CHECK(out(50, 20) == 7);
  // In and out of different sizes.
  Image<std::uint8_t> small(64, 48);
  small.fill(9);
  morph_square(in.view().sub(0, 0, 64, 40), 1, small.view(), buffers.scratch(64, 48));
  CHECK(small(10, 10) == 9);
  // Negative sizes and an unconfigured MorphBuffers.
  const MorphScratch none = MorphBuffers().scratch(10, 10);
  CHECK(none.rows.empty());
  CHECK(none.column_counts == nullptr);
  CHECK(buffers.scratch(-1, 5).rows.empty());
}
