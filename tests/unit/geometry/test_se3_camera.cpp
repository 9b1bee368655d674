#include <doctest/doctest.h>

#include <cmath>
#include <random>

#include "core/geometry/camera.h"
#include "core/geometry/se3.h"
#include "support/alloc_guard.h"
#include "support/support.h"

#ifdef SCOPETRACK_HAVE_CALIB3D
#include <opencv2/calib3d.hpp>
#endif

using namespace st;

TEST_CASE("SE3 exp/log round trip and composition") {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int i = 0; i < 200; ++i) {
    Vec6 xi;
    for (int k = 0; k < 3; ++k) xi[k] = u(rng) * 3.0;   // up to ~pi rad
    for (int k = 3; k < 6; ++k) xi[k] = u(rng) * 200.0;  // mm
    if (xi.head<3>().norm() > 3.1) continue;
    const SE3 T = SE3::exp(xi);
    CHECK((T.rotation().transpose() * T.rotation() - Mat3::Identity()).norm() < 1e-12);
    CHECK((T.log() - xi).norm() < 1e-9);
    const SE3 I = T * T.inverse();
    CHECK(pose_delta(I, SE3()).angle_deg < 1e-9);
    CHECK(I.translation().norm() < 1e-9);
  }
  CHECK((SE3::exp(Vec6::Zero()).matrix() - Mat4::Identity()).norm() < 1e-15);
}

TEST_CASE("orthonormalize removes small errors and keeps det +1") {
  const Mat3 R = so3_exp(Vec3(0.3, -0.2, 0.9));
  Mat3 noisy = R;
  noisy(0, 1) += 1e-4;
  const Mat3 Q = orthonormalize(noisy);
  CHECK(std::abs(Q.determinant() - 1.0) < 1e-12);
  CHECK(rotation_angle_deg(Q, R) < 0.01);
}

static CameraModel barrel_camera(double k1) {
  Pinhole K{900, 905, 639.5, 359.5, 1280, 720};
  Distortion d;
  d.count = 5;
  d.k = {k1, 0.08, 0.001, -0.0005, -0.01, 0, 0, 0};
  return CameraModel(K, d);
}

TEST_CASE("undistort/distort round trip below 1e-6 px over the whole image") {
  for (double k1 : {-0.3, -0.1, 0.0, 0.15}) {
    const CameraModel cam = barrel_camera(k1);
    double worst = 0;
    int failures = 0;
    for (int y = 0; y < 720; y += 8) {
      for (int x = 0; x < 1280; x += 8) {
        Vec2 ideal;
        if (!cam.undistort_pixel(Vec2(x, y), &ideal)) {
          ++failures;
          continue;
        }
        worst = std::max(worst, (cam.distort_pixel(ideal) - Vec2(x, y)).norm());
      }
    }
    INFO("k1 = " << k1);
    CHECK(failures == 0);
    CHECK(worst < 1e-6);
  }
}

TEST_CASE("rational 8-coefficient model round trip") {
  Pinhole K{700, 700, 480, 270, 960, 540};
  Distortion d;
  d.count = 8;
  d.k = {-0.25, 0.05, 0.0008, 0.0003, 0.001, 0.02, 0.001, 0.0005};
  const CameraModel cam(K, d);
  double worst = 0;
  for (int y = 0; y < 540; y += 10)
    for (int x = 0; x < 960; x += 10) {
      Vec2 ideal;
      REQUIRE(cam.undistort_pixel(Vec2(x, y), &ideal));
      worst = std::max(worst, (cam.distort_pixel(ideal) - Vec2(x, y)).norm());
    }
  CHECK(worst < 1e-6);
}

TEST_CASE("distortion Jacobian matches finite differences") {
  Distortion d;
  d.count = 8;
  d.k = {-0.3, 0.1, 0.002, -0.001, 0.01, 0.05, 0.002, 0.001};
  for (const Vec2& x : {Vec2(0.1, -0.2), Vec2(-0.5, 0.3), Vec2(0.7, 0.4)}) {
    Eigen::Matrix2d J;
    d.distort(x, &J);
    const double h = 1e-7;
    for (int c = 0; c < 2; ++c) {
      Vec2 dx = Vec2::Zero();
      dx[c] = h;
      const Vec2 num = (d.distort(x + dx) - d.distort(x - dx)) / (2 * h);
      CHECK((num - J.col(c)).norm() < 1e-6);
    }
  }
}

TEST_CASE("undistortion reports non-convergence instead of guessing") {
  const CameraModel cam = barrel_camera(-0.3);
  Vec2 ideal;
  // Far outside the image, strong barrel distortion folds over: must say so.
  CHECK_FALSE(cam.undistort_pixel(Vec2(-20000, -20000), &ideal));
}

TEST_CASE("camera validation rejects bad calibrations") {
  Distortion none;
  CHECK(CameraModel::validate(Pinhole{900, 900, 640, 360, 1280, 720}, none).ok());
  CHECK_FALSE(CameraModel::validate(Pinhole{-900, 900, 640, 360, 1280, 720}, none).ok());
  CHECK_FALSE(CameraModel::validate(Pinhole{900, 900, 1400, 360, 1280, 720}, none).ok());
  CHECK_FALSE(CameraModel::validate(Pinhole{NAN, 900, 640, 360, 1280, 720}, none).ok());
  CHECK_FALSE(CameraModel::validate(Pinhole{900, 900, 640, 360, 0, 720}, none).ok());
  CHECK_FALSE(CameraModel::validate(Pinhole{900, 900, 640, 360, 100000, 720}, none).ok());
  Distortion three;
  three.count = 3;
  CHECK_FALSE(CameraModel::validate(Pinhole{900, 900, 640, 360, 1280, 720}, three).ok());
  // A field of view under 0.6 deg, or pixels 4x taller than wide: refused;
  // just inside both bounds: accepted.
  CHECK_FALSE(CameraModel::validate(Pinhole{900, 128001, 640, 360, 1280, 720}, none).ok());
  CHECK_FALSE(CameraModel::validate(Pinhole{900, 3601, 640, 360, 1280, 720}, none).ok());
  CHECK_FALSE(CameraModel::validate(Pinhole{3601, 900, 640, 360, 1280, 720}, none).ok());
  CHECK(CameraModel::validate(Pinhole{900, 3600, 640, 360, 1280, 720}, none).ok());
  CHECK(CameraModel::validate(Pinhole{128000, 128000, 640, 360, 1280, 720}, none).ok());
}

TEST_CASE("camera validation of the lens returns promptly, whatever the numbers" *
          doctest::timeout(test::budget_s(5))) {
  // fuzz_sequence_yaml's input: fy = 6e13 px made the fold check step 1/fy
  // along every ray, ~1e14 steps along the x axis. Now refused by the focal
  // bounds; within them each ray steps about a pixel, at most 20000 times.
  Distortion odd;
  odd.count = 5;
  odd.k = {5, 0, 0, 5, 0, 0, 0, 0};
  CHECK_FALSE(CameraModel::validate(Pinhole{24, 6e13, 31.5, 23.5, 64, 48}, odd).ok());
  for (const Pinhole& K : {Pinhole{900, 3600, 640, 360, 1280, 720}, Pinhole{3600, 900, 640, 360, 1280, 720},
                           Pinhole{409600, 409600, 2047.5, 2047.5, 4096, 4096}}) {
    CAPTURE(K.fx);
    CAPTURE(K.fy);
    (void)CameraModel::validate(K, odd);  // either verdict, but promptly
  }
  Distortion folds;
  folds.count = 4;
  folds.k = {-1.5, 0, 0, 0, 0, 0, 0, 0};
  CHECK_FALSE(CameraModel::validate(Pinhole{3000, 3000, 2047.5, 2047.5, 4096, 4096}, folds).ok());
}

TEST_CASE("camera validation refuses a distortion that folds the image, accepts real lenses") {
  const Pinhole K{900, 905, 639.5, 359.5, 1280, 720};
  // Barrel distortion this strong turns back at 0.47 normalised radius
  // (420 px), before the image's corners: two image points per ideal ray.
  Distortion folds;
  folds.count = 4;
  folds.k = {-1.5, 0, 0, 0, 0, 0, 0, 0};
  const Status s = CameraModel::validate(K, folds);
  REQUIRE_FALSE(s.ok());
  CHECK(s.message().find("fold") != std::string::npos);
  // A rational model that turns back at 0.35 normalised radius, inside.
  Distortion rational;
  rational.count = 8;
  rational.k = {0, 0, 0, 0, 0, 2.0, 0, 0};
  CHECK_FALSE(CameraModel::validate(K, rational).ok());
  // Real lenses pass: the simulator's invivo lens and the round-trip tests'
  // ones; so do strong but monotonic coefficients, wrong as they may be for
  // a given video (that mismatch no static check can see).
  Distortion invivo;
  invivo.count = 5;
  invivo.k = {-0.28, 0.10, 0.0005, -0.0004, -0.015, 0, 0, 0};
  CHECK(CameraModel::validate(Pinhole{700, 700, 479.5, 269.5, 960, 540}, invivo).ok());
  for (double k1 : {-0.3, -0.1, 0.0, 0.15}) {
    CAPTURE(k1);
    const CameraModel cam = barrel_camera(k1);
    CHECK(CameraModel::validate(cam.pinhole(), cam.distortion()).ok());
  }
  Distortion strong;
  strong.count = 5;
  strong.k = {10, -50, 0, 0, 100, 0, 0, 0};
  CHECK(CameraModel::validate(Pinhole{230.4, 230.4, 162.75, 87, 320, 180}, strong).ok());
}

#ifdef SCOPETRACK_HAVE_CALIB3D
TEST_CASE("projection agrees with OpenCV's projectPoints") {
  const CameraModel cam = barrel_camera(-0.3);
  const auto& K = cam.pinhole();
  cv::Mat Kcv = (cv::Mat_<double>(3, 3) << K.fx, 0, K.cx, 0, K.fy, K.cy, 0, 0, 1);
  cv::Mat dcv(1, 5, CV_64F);
  for (int i = 0; i < 5; ++i) dcv.at<double>(i) = cam.distortion().k[i];
  std::vector<cv::Point3d> pts;
  for (double x = -40; x <= 40; x += 10)
    for (double y = -25; y <= 25; y += 10) pts.emplace_back(x, y, 80.0);
  std::vector<cv::Point2d> cv_px;
  cv::projectPoints(pts, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), Kcv, dcv, cv_px);
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const Vec2 ours = cam.project(Vec3(pts[i].x, pts[i].y, pts[i].z));
    CHECK((ours - Vec2(cv_px[i].x, cv_px[i].y)).norm() < 1e-9);
  }
}
#endif

TEST_CASE("camera model allocates nothing") {
  const CameraModel cam = barrel_camera(-0.3);
  test::AllocationCounter count;
  Vec2 acc = Vec2::Zero();
  for (int i = 0; i < 1000; ++i) {
    Vec2 ideal;
    (void)cam.undistort_pixel(Vec2(i % 1280, i % 720), &ideal);
    acc += cam.project(Vec3(i * 0.01, 1.0, 50.0)) + ideal;
  }
  CHECK(acc.allFinite());
  CHECK(count.count() == 0);
}
