// hal/capture/pixel_format: YUV420 and NV12 capture buffers with padding and odd
// sizes become the tracker's Y, U, V planes exactly; bad layouts are refused
// with a clear message (configure) or a status (per frame), never read out
// of bounds; the per-frame conversion allocates nothing.
#include <doctest/doctest.h>

#include <cstdint>
#include <vector>

#include "hal/capture/pixel_format.h"
#include "support/alloc_guard.h"

using namespace st;

namespace {

constexpr std::uint8_t kPad = 0xEE;  // padding bytes: must never reach the output

std::uint8_t luma_at(int x, int y) { return static_cast<std::uint8_t>((x * 7 + y * 13) & 0x7f); }
std::uint8_t u_at(int x, int y) { return static_cast<std::uint8_t>(0x80 | ((x * 3 + y * 5) & 0x3f)); }
std::uint8_t v_at(int x, int y) { return static_cast<std::uint8_t>(0x40 | ((x * 11 + y) & 0x1f)); }

// A synthetic capture buffer: planes filled with the pattern, padding with kPad.
struct Synthetic {
  std::vector<std::vector<std::uint8_t>> bytes;
  RawFrame raw;
};
Synthetic make_frame(CapturePixelFormat f, int w, int h, std::size_t luma_stride, std::size_t extra_tail = 0) {
  Synthetic s;
  s.raw.format = f;
  s.raw.width = w;
  s.raw.height = h;
  const int cw = (w + 1) / 2;
  for (int p = 0; p < plane_count(f); ++p) {
    const std::size_t stride = p == 0 ? luma_stride : chroma_stride(f, luma_stride);
    const int rows = plane_rows(p, h);
    std::vector<std::uint8_t> b(stride * static_cast<std::size_t>(rows) + extra_tail, kPad);
    for (int y = 0; y < rows; ++y)
      for (int x = 0; x < (p == 0 ? w : cw); ++x) {
        std::uint8_t* row = b.data() + static_cast<std::size_t>(y) * stride;
        if (p == 0) row[x] = luma_at(x, y);
        else if (f == CapturePixelFormat::kNv12) row[2 * x] = u_at(x, y), row[2 * x + 1] = v_at(x, y);
        else row[x] = p == 1 ? u_at(x, y) : v_at(x, y);
      }
    s.bytes.push_back(std::move(b));
  }
  for (int p = 0; p < plane_count(f); ++p)
    s.raw.planes[static_cast<std::size_t>(p)] = {s.bytes[static_cast<std::size_t>(p)].data(),
                                                 s.bytes[static_cast<std::size_t>(p)].size(),
                                                 p == 0 ? luma_stride : chroma_stride(f, luma_stride)};
  return s;
}

struct Planes {
  Image<std::uint8_t> y, u, v;
  Planes(int w, int h) : y(w, h), u((w + 1) / 2, (h + 1) / 2), v((w + 1) / 2, (h + 1) / 2) {}
  PlanarFrame view() { return {y.view(), u.view(), v.view()}; }
};

void check_planes(const Planes& out, int w, int h) {
  int bad = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) bad += out.y(x, y) != luma_at(x, y);
  for (int y = 0; y < (h + 1) / 2; ++y)
    for (int x = 0; x < (w + 1) / 2; ++x) bad += (out.u(x, y) != u_at(x, y)) + (out.v(x, y) != v_at(x, y));
  CHECK(bad == 0);
}

}  // namespace

TEST_CASE("pixel_format: YUV420 and NV12 with padded, odd strides convert exactly") {
  for (const CapturePixelFormat f : {CapturePixelFormat::kYuv420, CapturePixelFormat::kNv12}) {
    // Odd width and height (chroma rounds up), odd luma stride with padding,
    // and a tightly packed layout.
    struct Case {
      int w, h;
      std::size_t stride;
    };
    for (const auto& [w, h, stride] : {Case{7, 5, 13}, Case{64, 36, 64}, Case{33, 17, 41}}) {
      CAPTURE(to_string(f));
      CAPTURE(w);
      CAPTURE(stride);
      Synthetic s = make_frame(f, w, h, stride);
      Planes out(w, h);
      out.y.fill(0);
      REQUIRE(check_raw_frame(s.raw, out.view()).ok());
      REQUIRE(convert_to_planar(s.raw, out.view()) == PixelStatus::kOk);
      check_planes(out, w, h);
    }
  }
}

TEST_CASE("pixel_format: plane sizes without padding after the last row are enough") {
  // Drivers often end a plane right after the last row's pixels.
  Synthetic s = make_frame(CapturePixelFormat::kNv12, 10, 6, 16);
  s.raw.planes[0].size = min_plane_size(10, 6, 16);
  s.raw.planes[1].size = min_plane_size(10, 3, 16);
  Planes out(10, 6);
  CHECK(convert_to_planar(s.raw, out.view()) == PixelStatus::kOk);
  check_planes(out, 10, 6);
  s.raw.planes[1].size -= 1;
  CHECK(convert_to_planar(s.raw, out.view()) == PixelStatus::kPlaneTooSmall);
}

TEST_CASE("pixel_format: bad layouts are refused with a message that names the plane and the numbers") {
  Planes out(8, 4);
  SUBCASE("a plane too small") {
    Synthetic s = make_frame(CapturePixelFormat::kYuv420, 8, 4, 10);
    s.raw.planes[2].size = 5;
    const Status st = check_raw_frame(s.raw, out.view());
    REQUIRE(!st.ok());
    CHECK(st.message().find("plane 2 (V)") != std::string::npos);
    CHECK(st.message().find("5 bytes") != std::string::npos);
    CHECK(st.message().find("2 rows at stride 5 need 9") != std::string::npos);  // 5 + 4 bytes
    CHECK(convert_to_planar(s.raw, out.view()) == PixelStatus::kPlaneTooSmall);
  }
  SUBCASE("stride below the row") {
    Synthetic s = make_frame(CapturePixelFormat::kNv12, 8, 4, 8);
    s.raw.planes[1].stride = 6;
    const Status st = check_raw_frame(s.raw, out.view());
    REQUIRE(!st.ok());
    CHECK(st.message().find("plane 1 (UV): stride 6 bytes is below its row of 8 bytes") != std::string::npos);
    CHECK(convert_to_planar(s.raw, out.view()) == PixelStatus::kStrideTooSmall);
  }
  SUBCASE("a missing plane") {
    Synthetic s = make_frame(CapturePixelFormat::kYuv420, 8, 4, 8);
    s.raw.planes[1].data = nullptr;
    CHECK(check_raw_frame(s.raw, out.view()).message().find("plane 1 (U) has no data") != std::string::npos);
    CHECK(convert_to_planar(s.raw, out.view()) == PixelStatus::kMissingPlane);
  }
  SUBCASE("output planes of another size") {
    Synthetic s = make_frame(CapturePixelFormat::kYuv420, 8, 6, 8);
    const Status st = check_raw_frame(s.raw, out.view());
    REQUIRE(!st.ok());
    CHECK(st.message().find("must be 8x6 (Y) and 4x3 (U, V), got 8x4") != std::string::npos);
    CHECK(convert_to_planar(s.raw, out.view()) == PixelStatus::kOutputMismatch);
  }
  SUBCASE("zero or huge frame sizes") {
    Synthetic s = make_frame(CapturePixelFormat::kYuv420, 8, 4, 8);
    s.raw.width = 0;
    CHECK(!check_raw_frame(s.raw, out.view()).ok());
    CHECK(convert_to_planar(s.raw, out.view()) == PixelStatus::kBadSize);
    s.raw.width = 1 << 20;
    CHECK(check_raw_frame(s.raw, out.view()).message().find("frame size outside") != std::string::npos);
  }
}

TEST_CASE("pixel_format: a refused frame leaves the output untouched and nothing allocates per frame") {
  Synthetic good = make_frame(CapturePixelFormat::kNv12, 64, 48, 80);
  Synthetic bad = make_frame(CapturePixelFormat::kNv12, 64, 48, 80);
  bad.raw.planes[0].size = 100;
  Planes out(64, 48);
  out.y.fill(1);
  test::AllocationCounter allocations;
  CHECK(convert_to_planar(bad.raw, out.view()) == PixelStatus::kPlaneTooSmall);
  CHECK(out.y(63, 47) == 1);
  for (int i = 0; i < 10; ++i) CHECK(convert_to_planar(good.raw, out.view()) == PixelStatus::kOk);
  CHECK(describe(PixelStatus::kPlaneTooSmall)[0] != '\0');
  CHECK(allocations.count() == 0);
  check_planes(out, 64, 48);
}
