// The real laparoscopic frame of shared/data (real/laparoscopy_liver_1080p.y4m,
// 1920x1080, video range) as the tests that compare the simulator with it
// read it.
#pragma once

#include <doctest/doctest.h>

#include <cstdint>

#include <opencv2/core.hpp>

#include "hal/capture/y4m_reader.h"
#include "tests/support/support.h"

namespace st::test {

// Its luma plane, a copy that owns its pixels.
inline cv::Mat real_frame_luma() {
  Y4mReader reader;
  REQUIRE(reader.open(shared_data("real/laparoscopy_liver_1080p.y4m")));
  FrameRef f;
  REQUIRE(reader.read_frame(&f) == ReadResult::kFrame);
  return cv::Mat(f.y.height, f.y.width, CV_8U, const_cast<std::uint8_t*>(f.y.data),
                 static_cast<std::size_t>(f.y.stride))
      .clone();
}

}  // namespace st::test
