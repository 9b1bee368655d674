// Mesh texturing (core/texture/mesh_texture.h, Algorithm 1) on synthetic frames: a
// cube whose faces have known colours is painted through the rasteriser's
// own id buffer, converted to Y'CbCr 4:2:0, and textured back.
#include <doctest/doctest.h>

#include <array>
#include <cmath>

#include "core/texture/mesh_texture.h"
#include "core/raster/rasterizer.h"
#include "support/alloc_guard.h"
#include "support/tiny_sequence.h"

using namespace st;

namespace {

constexpr int kW = 320, kH = 240;
const Pinhole kK{300, 300, 159.5, 119.5, kW, kH};

using Rgb = std::array<int, 3>;
// Face f of centred_cube owns triangles 2f and 2f + 1.
const std::array<Rgb, 6> kFaceRgb = {
    {{200, 40, 30}, {60, 180, 90}, {40, 70, 210}, {220, 200, 60}, {150, 60, 170}, {90, 200, 200}}};

SE3 cube_pose() {
  const Mat3 R = (Eigen::AngleAxisd(0.5, Vec3::UnitX()) * Eigen::AngleAxisd(-0.6, Vec3::UnitY()))
                     .toRotationMatrix();
  return SE3(R, Vec3(0, 0, 160));
}

// RGB -> Y'CbCr, BT.601 (the inverse of what the texturer decodes).
void rgb_to_ycc(const Rgb& c, bool full_range, double ycc[3]) {
  const double r = c[0], g = c[1], b = c[2];
  const double y = 0.299 * r + 0.587 * g + 0.114 * b;
  const double cb = (b - y) / 1.772, cr = (r - y) / 1.402;
  if (full_range) {
    ycc[0] = y;
    ycc[1] = 128 + cb;
    ycc[2] = 128 + cr;
  } else {
    ycc[0] = 16 + y * 219.0 / 255.0;
    ycc[1] = 128 + cb * 224.0 / 255.0;
    ycc[2] = 128 + cr * 224.0 / 255.0;
  }
}

struct Frame {
  Image<std::uint8_t> y{kW, kH}, u{kW / 2, kH / 2}, v{kW / 2, kH / 2};
  YuvFrameView view() const { return {y.cview(), u.cview(), v.cview()}; }
};

// Paints every pixel with the colour of the cube face it sees (black
// elsewhere); chroma is the mean of each 2x2 block.
Frame paint(const Mesh& cube, const SE3& T, const std::array<Rgb, 6>& face_rgb, bool full_range) {
  MeshRasterizer r;
  RasterConfig rc;
  rc.width = kW;
  rc.height = kH;
  REQUIRE(r.configure(cube, rc).ok());
  r.render(T, kK);
  Frame f;
  for (int by = 0; by < kH / 2; ++by)
    for (int bx = 0; bx < kW / 2; ++bx) {
      double cb = 0, cr = 0;
      for (int k = 0; k < 4; ++k) {
        const int x = 2 * bx + (k & 1), y = 2 * by + (k >> 1);
        const std::int32_t t = r.triangle_id()(x, y);
        double ycc[3];
        rgb_to_ycc(t < 0 ? Rgb{0, 0, 0} : face_rgb[static_cast<std::size_t>(t / 2)], full_range,
                   ycc);
        f.y(x, y) = static_cast<std::uint8_t>(std::lround(ycc[0]));
        cb += ycc[1] / 4;
        cr += ycc[2] / 4;
      }
      f.u(bx, by) = static_cast<std::uint8_t>(std::lround(cb));
      f.v(bx, by) = static_cast<std::uint8_t>(std::lround(cr));
    }
  return f;
}

TextureConfig config(bool full_range) {
  TextureConfig c;
  c.width = kW;
  c.height = kH;
  c.full_range = full_range;
  return c;
}

// Facing the camera: the normal points against the ray to the centroid.
bool facing(const Mesh& m, int t, const SE3& T) {
  const Vec3 a = T * m.vertex(m.tri[3 * t]), b = T * m.vertex(m.tri[3 * t + 1]),
             c = T * m.vertex(m.tri[3 * t + 2]);
  return (b - a).cross(c - a).dot((a + b + c) / 3) < 0;
}

}  // namespace

TEST_CASE("texture: BT.601 Y'CbCr -> RGB, full and studio range, known colours") {
  std::uint8_t rgb[3];
  yuv_to_rgb(76, 85, 255, true,
             rgb);  // full-range red (the simulator's RGB -> C420jpeg of 255,0,0)
  CHECK(rgb[0] >= 253);
  CHECK(rgb[1] <= 2);
  CHECK(rgb[2] <= 2);
  yuv_to_rgb(81, 90, 240, false, rgb);  // studio-range red
  CHECK(rgb[0] >= 253);
  CHECK(rgb[1] <= 2);
  CHECK(rgb[2] <= 2);
  yuv_to_rgb(16, 128, 128, false, rgb);  // studio black and white clamp
  CHECK(rgb[0] == 0);
  yuv_to_rgb(235, 128, 128, false, rgb);
  CHECK(rgb[1] == 255);
  yuv_to_rgb(128, 128, 128, true, rgb);
  CHECK((rgb[0] == 128 && rgb[1] == 128 && rgb[2] == 128));
}

TEST_CASE("texture: visible front faces get their colour, back faces none, in both YUV ranges") {
  const Mesh cube = test::centred_cube(40);
  const SE3 T = cube_pose();
  for (const bool full_range : {true, false}) {
    CAPTURE(full_range);
    MeshTexture tex;
    REQUIRE(tex.configure(cube, CameraModel(kK, Distortion{}), config(full_range)).ok());
    const Frame f = paint(cube, T, kFaceRgb, full_range);
    const int changed = tex.add_frame(f.view(), T);
    int coloured = 0;
    for (int t = 0; t < cube.triangle_count(); ++t) {
      CAPTURE(t);
      if (!facing(cube, t, T)) {
        CHECK(tex.weight(t) == 0);
        continue;
      }
      REQUIRE(tex.weight(t) == 1);
      ++coloured;
      const TriangleRgb c = tex.colour(t);
      const Rgb& want = kFaceRgb[static_cast<std::size_t>(t / 2)];
      // Chroma of 2x2 blocks on face edges mixes neighbours: a few levels.
      CHECK(std::abs(c.r - want[0]) <= 4);
      CHECK(std::abs(c.g - want[1]) <= 4);
      CHECK(std::abs(c.b - want[2]) <= 4);
    }
    CHECK(coloured == 6);  // three faces of a cube seen from a corner
    CHECK(changed == coloured);
    CHECK(tex.changed().size() == static_cast<std::size_t>(changed));
  }
}

TEST_CASE(
    "texture: running weighted mean with the weight capped at 10 keeps adapting, no allocation per "
    "frame") {
  const Mesh cube = test::centred_cube(40);
  const SE3 T = cube_pose();
  MeshTexture tex;
  REQUIRE(tex.configure(cube, CameraModel(kK, Distortion{}), config(true)).ok());
  std::array<Rgb, 6> grey{}, white{};
  grey.fill({100, 100, 100});
  white.fill({210, 210, 210});
  const Frame a = paint(cube, T, grey, true), b = paint(cube, T, white, true);
  const int t = 0;  // face z = -h: seen from this pose
  REQUIRE(facing(cube, t, T));
  {
    test::AllocationCounter allocs;
    for (int i = 0; i < 12; ++i) tex.add_frame(a.view(), T);
    CHECK(allocs.count() == 0);
  }
  CHECK(tex.weight(t) == 10);
  CHECK(tex.frames_seen(t) == 12);
  CHECK(tex.colour(t).r == 100);
  tex.add_frame(b.view(), T);  // (10 * 100 + 210) / 11 = 110
  CHECK(tex.colour(t).r == 110);
  CHECK(tex.changed().size() == 6);
  tex.add_frame(b.view(), T);  // (10 * 110 + 210) / 11 = 119.09
  CHECK(tex.colour(t).r == 119);
  for (int i = 0; i < 60; ++i) tex.add_frame(b.view(), T);
  CHECK(tex.colour(t).r >= 209);  // with a frozen weight it would stay near 100
  tex.add_frame(b.view(), T);
  CHECK(tex.changed().empty());  // nothing changed at 8 bits: no delta
}

TEST_CASE("texture: wrong frame size, mono frames and a bad config are handled") {
  const Mesh cube = test::centred_cube(40);
  MeshTexture tex;
  TextureConfig bad = config(true);
  bad.max_weight = 0;
  CHECK_FALSE(tex.configure(cube, CameraModel(kK, Distortion{}), bad).ok());
  REQUIRE(tex.configure(cube, CameraModel(kK, Distortion{}), config(true)).ok());
  Image<std::uint8_t> small(100, 80);
  CHECK(tex.add_frame({small.cview(), {}, {}}, cube_pose()) == 0);
  const Frame f = paint(cube, cube_pose(), kFaceRgb, true);
  CHECK(tex.add_frame({f.y.cview(), {}, {}}, cube_pose()) == 6);  // mono: grey from luma
  const TriangleRgb c = tex.colour(0);
  CHECK((c.r == c.g && c.g == c.b));
  SE3 behind(Mat3::Identity(), Vec3(0, 0, -500));  // the cube behind the camera: nothing visible
  CHECK(tex.add_frame(f.view(), behind) == 0);
}
