#include "host/cli/frame_png.hpp"

#include <algorithm>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

namespace fb::cli {

Result<void> write_image_file(const std::filesystem::path& path, const cv::Mat& image) {
  try {
    if (!cv::imwrite(path.string(), image))
      return fail("could not write " + path.string() + " (check the folder and the extension)");
  } catch (const cv::Exception& e) {
    return fail("could not write " + path.string() + ": " + e.what());
  }
  return success();
}
namespace {

// False colour over the 2nd..98th percentile of valid depth so that a face at 0.7 m in front of
// a wall at 1.2 m still shows relief; invalid pixels stay black.
cv::Mat depth_panel(const DepthImage& depth) {
  cv::Mat panel(depth.height, depth.width, CV_8UC3, cv::Scalar(0, 0, 0));
  std::vector<std::uint16_t> valid;
  valid.reserve(depth.pixels.size());
  for (auto d : depth.pixels) {
    if (d != 0) valid.push_back(d);
  }
  if (valid.empty()) return panel;
  auto nth = [&](double q) {
    auto it = valid.begin() + static_cast<long>(q * static_cast<double>(valid.size() - 1));
    std::nth_element(valid.begin(), it, valid.end());
    return static_cast<double>(*it);
  };
  const double near = nth(0.02), far = std::max(nth(0.98), near + 1.0);
  cv::Mat gray(depth.height, depth.width, CV_8UC1, cv::Scalar(0));
  cv::Mat mask(depth.height, depth.width, CV_8UC1, cv::Scalar(0));
  for (int y = 0; y < depth.height; ++y) {
    for (int x = 0; x < depth.width; ++x) {
      const auto d = depth.at(x, y);
      if (d == 0) continue;
      const double t = std::clamp((d - near) / (far - near), 0.0, 1.0);
      gray.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(255.0 * (1.0 - t));
      mask.at<std::uint8_t>(y, x) = 255;
    }
  }
  cv::Mat coloured;
  cv::applyColorMap(gray, coloured, cv::COLORMAP_TURBO);
  coloured.copyTo(panel, mask);
  return panel;
}

cv::Mat color_panel(const ColorImage& color) {
  cv::Mat rgb(color.height, color.width, CV_8UC3, const_cast<Rgb8*>(color.pixels.data()));
  cv::Mat bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  return bgr;
}

cv::Mat overlay_panel(const RgbdFrame& frame, const KinectRegistration& registration) {
  DepthImage registered;
  registration.register_depth_to_color(frame.depth_mm, registered);
  cv::Mat panel = color_panel(frame.color) * 0.6;
  // Mark the near side of depth jumps (> 5 % of the depth). Registration leaves unmapped gaps
  // beside silhouettes, so look past up to 8 empty pixels for the neighbouring measurement.
  constexpr int kDirections[4][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}};
  constexpr int kMaxGap = 8;
  for (int y = 0; y < registered.height; ++y) {
    for (int x = 0; x < registered.width; ++x) {
      const int d = registered.at(x, y);
      if (d == 0) continue;
      bool edge = false;
      for (const auto& step : kDirections) {
        for (int k = 1; k <= kMaxGap + 1 && !edge; ++k) {
          const int nx = x + k * step[0], ny = y + k * step[1];
          if (!registered.contains(nx, ny)) break;
          const int n = registered.at(nx, ny);
          if (n == 0) continue;
          edge = n - d > d / 20;
          break;
        }
      }
      if (edge) panel.at<cv::Vec3b>(y, x) = cv::Vec3b(255, 0, 255);
    }
  }
  return panel;
}

}  // namespace

Result<void> write_frame_png(const RgbdFrame& frame, const std::filesystem::path& path,
                             const FramePngOptions& options) {
  if (frame.depth_mm.empty() || frame.color.empty()) {
    return fail("the frame has no depth or no colour image; nothing to draw");
  }
  std::vector<cv::Mat> panels{depth_panel(frame.depth_mm), color_panel(frame.color)};
  if (options.registration != nullptr)
    panels.push_back(overlay_panel(frame, *options.registration));
  const int height = std::max(panels[0].rows, panels[1].rows);
  for (auto& panel : panels) {
    if (panel.rows != height)
      cv::resize(panel, panel, cv::Size(panel.cols * height / panel.rows, height));
  }
  cv::Mat joined;
  cv::hconcat(panels, joined);
  try {
    if (!cv::imwrite(path.string(), joined)) {
      return fail("could not write '" + path.string() +
                  "': check the directory exists and is writable");
    }
  } catch (const cv::Exception& e) {
    return fail("could not write '" + path.string() + "': " + e.what());
  }
  return success();
}

}  // namespace fb::cli
