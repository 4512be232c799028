#include "firmware/daemon/live_preview.hpp"

#include <utility>

namespace fb {
namespace {

void downsample(const RgbdFrame& frame, ColorImage& out) {
  const int w = frame.color.width / 2, h = frame.color.height / 2;
  out.resize(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) out.at(x, y) = frame.color.at(2 * x, 2 * y);
}

}  // namespace

void LivePreview::show(const RgbdFrame& frame, const FaceBox& box) {
  if (frame.color.width / 2 <= 0 || frame.color.height / 2 <= 0) return;
  std::lock_guard lock(mutex_);
  ColorImage& out = picture_;
  downsample(frame, out);
  const Rgb8 green{40, 220, 90};
  const int x0 = box.rect.x0 / 2, y0 = box.rect.y0 / 2, x1 = box.rect.x1 / 2 - 1,
            y1 = box.rect.y1 / 2 - 1;
  for (int x = x0; x <= x1; ++x)
    for (int y : {y0, y1})
      if (out.contains(x, y)) out.at(x, y) = green;
  for (int y = y0; y <= y1; ++y)
    for (int x : {x0, x1})
      if (out.contains(x, y)) out.at(x, y) = green;
}

void LivePreview::show(const RgbdFrame& frame) {
  std::lock_guard lock(mutex_);
  downsample(frame, picture_);
}

ColorImage LivePreview::picture() const {
  std::lock_guard lock(mutex_);
  return picture_;
}

void LivePreview::set_capture_bmp(std::string bmp) {
  std::lock_guard lock(mutex_);
  capture_bmp_ = std::move(bmp);
}

std::string LivePreview::capture_bmp() const {
  std::lock_guard lock(mutex_);
  return capture_bmp_;
}

}  // namespace fb
