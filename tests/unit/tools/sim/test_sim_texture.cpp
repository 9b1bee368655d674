#include <doctest/doctest.h>

#include <cmath>

#include <opencv2/core.hpp>

#include "core/image/image.h"
#include "tools/sim/materials.h"
#include "tools/sim/yuv.h"

using namespace st;
using namespace st::sim;

TEST_CASE("sim: RGB -> C420jpeg full-range BT.601 on known colours") {
  cv::Mat rgb(4, 6, CV_8UC3, cv::Scalar(128, 128, 128));
  rgb(cv::Rect(2, 0, 2, 2)).setTo(cv::Scalar(255, 0, 0));  // pure red block (R first)
  Image<std::uint8_t> y(6, 4), u(3, 2), v(3, 2);
  rgb_to_yuv420_jpeg(rgb, y.view(), u.view(), v.view());
  CHECK(y(0, 0) == 128);
  CHECK(u(0, 0) == 128);
  CHECK(v(0, 0) == 128);
  CHECK(y(2, 0) == 76);   // 0.299 * 255
  CHECK(u(1, 0) == 85);   // 128 - 0.1687 * 255
  CHECK(v(1, 0) == 255);  // 128 + 0.5 * 255, clamped
  CHECK(u(1, 1) == 128);
}

TEST_CASE("sim: odd frame sizes convert without reading outside the image") {
  cv::Mat rgb(3, 5, CV_8UC3, cv::Scalar(10, 200, 30));
  Image<std::uint8_t> y(5, 3), u(3, 2), v(3, 2);
  rgb_to_yuv420_jpeg(rgb, y.view(), u.view(), v.view());
  CHECK(u(2, 1) == u(0, 0));
  CHECK(v(2, 1) == v(0, 0));
}

TEST_CASE("sim: tissue textures vary, stay in range, and liver is red-brown") {
  const Texture tex(3);
  for (int id = 0; id < static_cast<int>(MaterialId::Count); ++id) {
    const Material m = material(static_cast<MaterialId>(id));
    double lo = 1e9, hi = -1e9;
    for (int i = 0; i < 3000; ++i) {
      const Vec3f p(static_cast<float>(i % 50) * 1.7f, static_cast<float>(i / 50) * 1.3f, 0.37f * static_cast<float>(i % 7));
      const Vec3f a = tex.detail_at(m, p, tex.albedo_at_vertex(m, p));
      CHECK(a.minCoeff() >= 0.0f);
      CHECK(a.maxCoeff() <= 1.0f);
      lo = std::min(lo, static_cast<double>(a.x()));
      hi = std::max(hi, static_cast<double>(a.x()));
    }
    CAPTURE(id);
    CHECK(hi > lo * 1.15);  // not flat
  }
  const Material liver = material(MaterialId::Liver);
  const Vec3f a = tex.albedo_at_vertex(liver, Vec3f(1, 2, 3));
  CHECK(a.x() > 3.0f * a.y());
  CHECK(a.x() > 3.0f * a.z());
}
