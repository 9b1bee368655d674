#include "core/formats/sequence.h"

#include <algorithm>
#include <cmath>
#include <string_view>
#include <utility>

#include <opencv2/core.hpp>

#include "core/base/capacity.h"

namespace st {
namespace {

// An opencv-matrix node (rows, cols, data) read as doubles. Parsed here
// rather than with `node >> cv::Mat`, which allocates rows x cols as written
// (a corrupt "cols: 4000000000" would ask for gigabytes).
constexpr int kMaxMatrixEntries = 16;
bool read_matrix(const cv::FileNode& node, cv::Mat* out) {
  if (node.empty() || !node.isMap()) return false;
  const cv::FileNode rows = node["rows"], cols = node["cols"], data = node["data"];
  if (!rows.isInt() || !cols.isInt() || !data.isSeq()) return false;
  const int r = static_cast<int>(rows), c = static_cast<int>(cols);
  if (r <= 0 || c <= 0 || r > kMaxMatrixEntries || c > kMaxMatrixEntries || r * c > kMaxMatrixEntries ||
      data.size() != static_cast<std::size_t>(r * c))
    return false;
  cv::Mat m(r, c, CV_64F);
  int i = 0;
  for (cv::FileNodeIterator it = data.begin(); it != data.end(); ++it, ++i) {
    const cv::FileNode v = *it;
    if (!v.isInt() && !v.isReal()) return false;
    m.at<double>(i / c, i % c) = static_cast<double>(v);
  }
  *out = m;
  return true;
}

Status read_camera(const cv::FileStorage& fs, SequenceConfig* c) {
  cv::Mat K, d;
  if (!read_matrix(fs["camera_matrix"], &K) || K.rows != 3 || K.cols != 3)
    return make_error("sequence.yaml: camera_matrix must be a 3x3 opencv-matrix");
  if (std::abs(K.at<double>(0, 1)) > 1e-9 || std::abs(K.at<double>(1, 0)) > 1e-9 ||
      K.at<double>(2, 0) != 0.0 || K.at<double>(2, 1) != 0.0 || K.at<double>(2, 2) != 1.0)
    return make_error("sequence.yaml: camera_matrix must be [fx 0 cx; 0 fy cy; 0 0 1] (no skew)");
  c->K = Pinhole{K.at<double>(0, 0), K.at<double>(1, 1), K.at<double>(0, 2), K.at<double>(1, 2),
                 c->width, c->height};
  if (!read_matrix(fs["distortion_coefficients"], &d))
    return make_error("sequence.yaml: distortion_coefficients missing or malformed (1x5 opencv-matrix; "
                      "all zero for an ideal pinhole)");
  const int n = static_cast<int>(d.total());
  if (n != 4 && n != 5 && n != 8)
    return make_error("sequence.yaml: distortion_coefficients must have 4, 5 or 8 values, got " +
                      std::to_string(n));
  c->distortion.count = n;
  for (int i = 0; i < n; ++i) c->distortion.k[static_cast<std::size_t>(i)] = d.at<double>(i);
  return CameraModel::validate(c->K, c->distortion);
}

Status read_pose(const cv::FileStorage& fs, SequenceConfig* c) {
  cv::Mat T;
  if (!read_matrix(fs["T_camera_model_init"], &T) || T.rows != 4 || T.cols != 4)
    return make_error("sequence.yaml: T_camera_model_init must be a 4x4 opencv-matrix");
  Mat4 M;
  for (int r = 0; r < 4; ++r)
    for (int k = 0; k < 4; ++k) M(r, k) = T.at<double>(r, k);
  if (!M.allFinite()) return make_error("sequence.yaml: T_camera_model_init has non-finite values");
  if ((M.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).norm() > 1e-9)
    return make_error("sequence.yaml: T_camera_model_init's last row must be 0 0 0 1");
  const Mat3 R = M.topLeftCorner<3, 3>();
  const double err = (R.transpose() * R - Mat3::Identity()).norm();
  if (err > kMaxRotationError || R.determinant() <= 0.0)
    return make_error("sequence.yaml: T_camera_model_init is not rigid (|R^T R - I| = " +
                      std::to_string(err) + ", det R = " + std::to_string(R.determinant()) +
                      "): it must be a rotation + translation, without scale or mirror");
  c->T_init_reorthonormalised = err > 1e-12;
  c->T_camera_model_init = SE3(c->T_init_reorthonormalised ? orthonormalize(R) : R,
                               M.topRightCorner<3, 1>());
  return Status::Ok();
}

std::string read_string(const cv::FileStorage& fs, const char* key) {
  const cv::FileNode n = fs[key];
  return n.isString() ? static_cast<std::string>(n) : std::string();
}

Status read_scalars(const cv::FileStorage& fs, bool need_files, SequenceConfig* c) {
  const cv::FileNode w = fs["image_width"], h = fs["image_height"], f = fs["fps"];
  if (!w.isInt() || !h.isInt()) return make_error("sequence.yaml: image_width and image_height must be integers");
  c->width = static_cast<int>(w);
  c->height = static_cast<int>(h);
  if (c->width <= 0 || c->height <= 0 || c->width > kMaxImageWidth || c->height > kMaxImageHeight)
    return make_error("sequence.yaml: image size " + std::to_string(c->width) + "x" +
                      std::to_string(c->height) + " is outside 1x1.." +
                      std::to_string(kMaxImageWidth) + "x" + std::to_string(kMaxImageHeight));
  const bool fps_given = f.isReal() || f.isInt();
  if (!fps_given && need_files) return make_error("sequence.yaml: fps missing (frames per second)");
  c->fps = fps_given ? static_cast<double>(f) : 0.0;
  if (fps_given && (!std::isfinite(c->fps) || c->fps <= 0.0 || c->fps > 10000.0))
    return make_error("sequence.yaml: fps must be in (0, 10000], got " + std::to_string(c->fps));
  c->video = read_string(fs, "video");
  c->mesh = read_string(fs, "mesh");
  c->groundtruth = read_string(fs, "groundtruth");
  c->markers = read_string(fs, "markers");
  if (need_files && (c->video.empty() || c->mesh.empty()))
    return make_error("sequence.yaml: 'video' and 'mesh' file names are required");
  // A name that cv::FileStorage would take for structure when the file is
  // written back ('{' '}' '[' ']' first: fuzz_sequence_yaml found "}ideo.y4m"
  // throwing in format_sequence_yaml), or that holds control characters,
  // is no file name a sequence needs.
  for (const auto& [key, name] : {std::pair<const char*, const std::string*>{"video", &c->video},
                                  {"mesh", &c->mesh}, {"groundtruth", &c->groundtruth},
                                  {"markers", &c->markers}}) {
    const bool structural = !name->empty() && std::string_view("{}[]").find(name->front()) != std::string_view::npos;
    const bool control = std::any_of(name->begin(), name->end(), [](char ch) {
      return static_cast<unsigned char>(ch) < 0x20 || ch == 0x7f;
    });
    if (structural || control)
      return make_error(std::string("sequence.yaml: '") + key + "' is not a usable file name (it starts with one of {}[] "
                        "or holds control characters)");
  }
  return Status::Ok();
}

bool is_key_start(char ch) { return (ch >= 'A' && ch <= 'Z') || (ch >= 'a' && ch <= 'z') || ch == '_'; }
bool is_key_char(char ch) { return is_key_start(ch) || (ch >= '0' && ch <= '9') || ch == '-'; }

// sequence.yaml is a flat map: top-level "key: value" lines, indented
// continuation lines (matrices), comments, "%YAML" and "---". Anything
// else is refused before cv::FileStorage sees it: OpenCV 4.6's YAML reader
// loops forever on some malformed top-level lines (found by
// fuzz_sequence_yaml, e.g. "---x: 1" followed by "-]--/y: 64").
Status check_yaml_shape(std::string_view text) {
  int number = 0;
  for (std::size_t pos = 0; pos < text.size();) {
    std::size_t eol = text.find('\n', pos);
    if (eol == std::string_view::npos) eol = text.size();
    std::string_view line = text.substr(pos, eol - pos);
    pos = eol + 1;
    ++number;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    for (char ch : line)
      if ((static_cast<unsigned char>(ch) < 0x20 && ch != '\t') || ch == 0x7f)
        return make_error("sequence.yaml line " + std::to_string(number) +
                          " contains control characters (not a text file?)");
    if (line.empty() || line.front() == ' ' || line.front() == '#' || line == "---" ||
        line == "..." || line.substr(0, 5) == "%YAML")
      continue;
    std::size_t k = 0;
    if (!is_key_start(line[0])) k = line.size();
    while (k < line.size() && is_key_char(line[k])) ++k;
    while (k < line.size() && line[k] == ' ') ++k;
    if (k < line.size() && line[k] == ':' && (k + 1 == line.size() || line[k + 1] == ' ')) continue;
    return make_error("sequence.yaml line " + std::to_string(number) +
                      ": expected 'key: value' (a flat OpenCV YAML map), found '" +
                      std::string(line.substr(0, 40)) + "'");
  }
  return Status::Ok();
}

// need_files: a sequence (fps, video and mesh required); else a camera
// calibration (fps optional, names ignored).
Result<SequenceConfig> parse_yaml(std::string_view text, bool need_files) {
  if (text.empty()) return make_error("sequence.yaml is empty");
  if (Status shape = check_yaml_shape(text); !shape) return Error{shape.message()};
  SequenceConfig c;
  try {
    cv::FileStorage fs(std::string(text), cv::FileStorage::READ | cv::FileStorage::MEMORY);
    if (!fs.isOpened()) return make_error("sequence.yaml could not be parsed as OpenCV YAML");
    if (Status s = read_scalars(fs, need_files, &c); !s) return Error{s.message()};
    if (Status s = read_camera(fs, &c); !s) return Error{"sequence.yaml: " + s.message()};
    if (Status s = read_pose(fs, &c); !s) return Error{s.message()};
  } catch (const cv::Exception& e) {
    return make_error("sequence.yaml is not valid OpenCV YAML: " + e.msg);
  } catch (const std::exception& e) {
    return make_error(std::string("sequence.yaml could not be read: ") + e.what());
  }
  return c;
}

}  // namespace

Result<SequenceConfig> parse_sequence_yaml(std::string_view text) { return parse_yaml(text, true); }

Result<SequenceConfig> parse_calibration_yaml(std::string_view text) {
  auto c = parse_yaml(text, false);
  if (c) return c;
  // The messages name sequence.yaml (camera errors twice, as a prefix of
  // a prefixed message); here the file is a calibration.
  std::string message = c.message();
  for (std::size_t at; (at = message.find("sequence.yaml: sequence.yaml")) != std::string::npos;) message.erase(at, 15);
  for (std::size_t at; (at = message.find("sequence.yaml")) != std::string::npos;)
    message.replace(at, 13, "calibration file");
  return make_error(std::move(message));
}

std::string format_sequence_yaml(const SequenceConfig& c) {
  cv::FileStorage fs(".yaml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY);
  fs << "image_width" << c.width << "image_height" << c.height;
  const cv::Mat K = (cv::Mat_<double>(3, 3) << c.K.fx, 0, c.K.cx, 0, c.K.fy, c.K.cy, 0, 0, 1);
  fs << "camera_matrix" << K;
  const int n = c.distortion.count == 0 ? 5 : c.distortion.count;
  cv::Mat d(1, n, CV_64F);
  for (int i = 0; i < n; ++i) d.at<double>(i) = i < c.distortion.count ? c.distortion.k[static_cast<std::size_t>(i)] : 0.0;
  fs << "distortion_coefficients" << d;
  fs << "fps" << c.fps << "video" << c.video << "mesh" << c.mesh;
  const Mat4 T = c.T_camera_model_init.matrix();
  cv::Mat Tm(4, 4, CV_64F);
  for (int r = 0; r < 4; ++r)
    for (int k = 0; k < 4; ++k) Tm.at<double>(r, k) = T(r, k);
  fs << "T_camera_model_init" << Tm;
  if (!c.groundtruth.empty()) fs << "groundtruth" << c.groundtruth;
  if (!c.markers.empty()) fs << "markers" << c.markers;
  return fs.releaseAndGetString();
}

}  // namespace st
