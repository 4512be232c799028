// facebooth guide thumbnails: the guide expressions G0..G19 rendered as PNG thumbnails for the
// kiosk (the face model with each recipe's weights, flat-shaded).
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "algo/guide/guide_expressions.hpp"
#include "algo/render/rasterizer.hpp"
#include "host/cli/commands.hpp"
#include "host/cli/frame_png.hpp"
#include "host/cli/guide_files.hpp"
#include "storage/asset_files.hpp"

namespace fb::cli {
namespace {

int run_guide_thumbnails(const ParsedOptions& options) {
  const std::filesystem::path dir = options.get("out");
  if (dir.empty()) return report_failure({"--out DIR is required"});
  auto size = options.get_int("size");
  if (!size || *size < 32 || *size > 2048) return report_failure({"--size must be 32..2048"});
  auto model = load_face_model();
  if (!model) return report_failure(model.error());
  auto guide = load_guide(*model, options.get("guide"));
  if (!guide) return report_failure(guide.error());
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) return report_failure({"cannot create " + dir.string()});
  const int n = static_cast<int>(*size);
  PinholeIntrinsics k;
  k.width = k.height = n;
  k.fx = k.fy = n * 2.2;  // a 25 cm high window at 55 cm
  k.cx = k.cy = (n - 1) * 0.5;
  // Model frame -> camera: 180 deg about x (face towards the camera), centred on the landmarks.
  std::vector<float> g0(static_cast<std::size_t>(model->vertex_count) * 3);
  model->evaluate({}, {}, g0);
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (auto v : model->landmark_vertices)
    centre += Eigen::Vector3d(g0[3 * v], g0[3 * v + 1], g0[3 * v + 2]);
  centre /= 68.0;
  nlohmann::json files = nlohmann::json::array();
  RasterBuffers rb;
  for (const auto& ge : guide->expressions) {
    auto mesh = guide_mesh(ge, *model);
    if (!mesh) return report_failure(mesh.error());
    std::vector<Eigen::Vector3f> v(static_cast<std::size_t>(model->vertex_count));
    for (int i = 0; i < model->vertex_count; ++i) {
      const Eigen::Vector3d p =
          Eigen::Vector3d((*mesh)[3 * i], (*mesh)[3 * i + 1], (*mesh)[3 * i + 2]) - centre;
      v[static_cast<std::size_t>(i)] = Eigen::Vector3f(p.x(), -p.y(), 550.0 - p.z());
    }
    rb.reset(n, n);
    if (auto ok = rasterize(k, v, model->triangles, RasterOptions{}, rb); !ok)
      return report_failure(ok.error());
    cv::Mat img(n, n, CV_8UC3, cv::Scalar(235, 235, 235));
    // Direction towards the light: from the camera side (-z), a little up (-y) and to the left.
    const Eigen::Vector3f to_light = Eigen::Vector3f(0.3f, -0.4f, -1.0f).normalized();
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) {
        const std::int32_t t = rb.triangle[rb.index(x, y)];
        if (t == kNoTriangle) continue;
        const auto a = model->triangles[3 * t], b = model->triangles[3 * t + 1],
                   c = model->triangles[3 * t + 2];
        Eigen::Vector3f nn = (v[b] - v[a]).cross(v[c] - v[a]).normalized();
        if (nn.z() > 0) nn = -nn;                                            // towards the camera
        const float shade = 0.3f + 0.7f * std::max(0.0f, nn.dot(to_light));  // ambient + Lambert
        img.at<cv::Vec3b>(y, x) = cv::Vec3b(static_cast<std::uint8_t>(150 * shade + 20),
                                            static_cast<std::uint8_t>(175 * shade + 20),
                                            static_cast<std::uint8_t>(215 * shade + 25));
      }
    char name[96];
    std::snprintf(name, sizeof name, "G%02d_%s.png", ge.id, ge.name.c_str());
    if (auto ok = write_image_file(dir / name, img); !ok) return report_failure(ok.error());
    files.push_back(
        {{"id", ge.id}, {"name", ge.name}, {"label", ge.label}, {"file", (dir / name).string()}});
  }
  std::cout << nlohmann::json{{"thumbnails", files}}.dump(2) << std::endl;
  return kExitOk;
}

}  // namespace

std::vector<Command> guide_commands() {
  const OptionSpec guide_opt{"guide", "FILE",
                             "guide recipes (default: DATA_DIR/guide_expressions.json)", ""};
  return {
      {{"guide thumbnails",
        "render the guide expressions G0..G19 as PNG thumbnails for the kiosk",
        "",
        {{"out", "DIR", "output directory", ""},
         {"size", "PX", "thumbnail side", "256"},
         guide_opt}},
       run_guide_thumbnails},
  };
}

}  // namespace fb::cli
