// Images: ImageView borrows, Image owns. Strides are in elements.
// Image::allocate() is for configure(); nothing on the hot path resizes.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace st {

template <class T>
struct ImageView {
  T* data = nullptr;
  int width = 0;
  int height = 0;
  std::ptrdiff_t stride = 0;  // elements between rows

  ImageView() = default;
  ImageView(T* d, int w, int h, std::ptrdiff_t s) : data(d), width(w), height(h), stride(s) {}
  ImageView(T* d, int w, int h) : ImageView(d, w, h, w) {}
  // A view of T converts to a view of const T.
  template <class U>
  ImageView(const ImageView<U>& o)  // NOLINT: implicit on purpose
    requires std::is_same_v<const U, T>
      : data(o.data), width(o.width), height(o.height), stride(o.stride) {}

  bool empty() const { return data == nullptr || width <= 0 || height <= 0; }
  T* row(int y) const { return data + y * stride; }
  T& operator()(int x, int y) const { return data[y * stride + x]; }
  bool contains(int x, int y) const { return x >= 0 && y >= 0 && x < width && y < height; }
  ImageView sub(int x, int y, int w, int h) const { return ImageView(row(y) + x, w, h, stride); }
};

template <class T>
class Image {
 public:
  Image() = default;
  Image(int w, int h) { allocate(w, h); }
  void allocate(int w, int h) {
    width_ = w;
    height_ = h;
    buf_.assign(static_cast<std::size_t>(w) * static_cast<std::size_t>(h), T{});
  }
  void fill(const T& v) { std::fill(buf_.begin(), buf_.end(), v); }
  ImageView<T> view() { return ImageView<T>(buf_.data(), width_, height_, width_); }
  ImageView<const T> view() const { return ImageView<const T>(buf_.data(), width_, height_, width_); }
  ImageView<const T> cview() const { return view(); }
  T* data() { return buf_.data(); }
  const T* data() const { return buf_.data(); }
  int width() const { return width_; }
  int height() const { return height_; }
  bool empty() const { return buf_.empty(); }
  T& operator()(int x, int y) { return buf_[static_cast<std::size_t>(y) * width_ + x]; }
  const T& operator()(int x, int y) const { return buf_[static_cast<std::size_t>(y) * width_ + x]; }

 private:
  std::vector<T> buf_;
  int width_ = 0;
  int height_ = 0;
};

using GrayView = ImageView<const std::uint8_t>;

// The chroma planes of a 4:2:0 frame, U (Cb) and V (Cr), each
// (width + 1) / 2 x (height + 1) / 2 of the luma's width x height, 128 =
// neutral. Empty (either plane) = no chroma: a Cmono video, or a caller
// that has none.
struct ChromaView {
  GrayView u, v;
  bool empty() const { return u.empty() || v.empty(); }
};

}  // namespace st
