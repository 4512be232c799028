// facebooth-lab eval fit --png: error maps (paper Fig. 2 style), |mesh depth - fused depth| per
// pixel over the face, of the first neutral fit (initial | refined), and the depth confidence the
// fit weighted its depth term with.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "algo/core/figure_text.hpp"
#include "algo/render/rasterizer.hpp"
#include "host/cli/frame_png.hpp"
#include "sim/lab/fit_eval_parts.hpp"

namespace fb::cli::fit_eval {
namespace {

cv::Mat error_panel(const FaceModel& model, std::span<const float> mesh, const RigidPose& pose,
                    const Capture& c, const PixelRect& box, double scale_mm,
                    const std::string& title, double rms) {
  std::vector<Eigen::Vector3f> v(static_cast<std::size_t>(model.vertex_count));
  for (int i = 0; i < model.vertex_count; ++i)
    v[static_cast<std::size_t>(i)] =
        pose.apply({mesh[3 * i], mesh[3 * i + 1], mesh[3 * i + 2]}).cast<float>();
  // Face triangles only (all three vertices in the face region).
  std::vector<std::uint32_t> tris;
  for (std::size_t t = 0; t + 2 < model.triangles.size(); t += 3)
    if (model.triangles[t] < static_cast<std::uint32_t>(model.face_vertex_count) &&
        model.triangles[t + 1] < static_cast<std::uint32_t>(model.face_vertex_count) &&
        model.triangles[t + 2] < static_cast<std::uint32_t>(model.face_vertex_count))
      tris.insert(tris.end(), {model.triangles[t], model.triangles[t + 1], model.triangles[t + 2]});
  RasterBuffers rb;
  rb.reset(c.intrinsics.width, c.intrinsics.height);
  (void)rasterize(c.intrinsics, v, tris, RasterOptions{}, rb);
  cv::Mat out(box.height(), box.width(), CV_8UC3, cv::Scalar(0, 0, 0));
  for (int y = 0; y < box.height(); ++y)
    for (int x = 0; x < box.width(); ++x) {
      const int px = box.x0 + x, py = box.y0 + y;
      if (!rb.covered(px, py)) continue;
      const float f = c.fused.depth_mm.at(px, py);
      if (!(f > 0)) {
        out.at<cv::Vec3b>(y, x) = {60, 60, 60};
        continue;
      }
      const double e = std::abs(rb.depth[rb.index(px, py)] - f);
      cv::Mat p(1, 1, CV_8U, cv::Scalar(std::clamp(e / scale_mm, 0.0, 1.0) * 255.0));
      cv::Mat col;
      cv::applyColorMap(p, col, cv::COLORMAP_JET);
      out.at<cv::Vec3b>(y, x) = col.at<cv::Vec3b>(0, 0);
    }
  cv::Mat big;
  cv::resize(out, big, cv::Size(), 2.0, 2.0, cv::INTER_NEAREST);
  cv::Mat framed(big.rows + 30, big.cols, CV_8UC3, cv::Scalar(255, 255, 255));
  big.copyTo(framed(cv::Rect(0, 30, big.cols, big.rows)));
  char text[160];
  std::snprintf(text, sizeof text, "%s: RMS %s mm (0-%.1f mm)", title.c_str(),
                figure_text(rms).c_str(), scale_mm);
  cv::putText(framed, text, cv::Point(4, 20), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0),
              1, cv::LINE_AA);
  return framed;
}

}  // namespace

Result<void> write_fit_pngs(const ParsedOptions& options, const FaceModel& model,
                            const FitResult& neutral, const Capture& cap) {
  const double scale = 3.0;
  const std::filesystem::path png = options.get("png");
  if (!png.empty() && !cap.confidence.empty()) {
    // The depth confidence the fit weighted its depth term with (white = 1).
    cv::Mat conf(cap.confidence.height, cap.confidence.width, CV_8UC1);
    for (int y = 0; y < conf.rows; ++y)
      for (int x = 0; x < conf.cols; ++x)
        conf.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(
            std::lround(255.0f * std::clamp(cap.confidence.at(x, y), 0.0f, 1.0f)));
    std::filesystem::path cpng = png;
    cpng.replace_extension(".confidence.png");
    if (auto ok = write_image_file(cpng, conf); !ok) return ok.failure();
  }
  if (!png.empty()) {
    cv::Mat a = error_panel(model, neutral.initial_vertices, neutral.camera_from_model, cap,
                            cap.box.rect, scale, "initial (PCA)", neutral.rms_to_depth_mm_initial);
    cv::Mat b = error_panel(model, neutral.vertices, neutral.camera_from_model, cap, cap.box.rect,
                            scale, "refined", neutral.rms_to_depth_mm);
    cv::Mat row;
    cv::hconcat(std::vector<cv::Mat>{a, cv::Mat(a.rows, 10, CV_8UC3, cv::Scalar(255, 255, 255)), b},
                row);
    if (auto ok = write_image_file(png, row); !ok) return ok.failure();
  }
  return success();
}

}  // namespace fb::cli::fit_eval
