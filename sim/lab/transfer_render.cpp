// `facebooth-lab render transfer`: the README's picture of the 3D transfer (issue 39). Reads
// the OBJ folders `facebooth export --format obj` and `facebooth transfer --format obj` write
// and draws them with the project's rasterizer (algo/render), shaded grey, frontal: one row per
// folder (the source, the transfer onto the target, optionally the target's own shapes as the
// truth), one column per expression after the neutral.
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include "algo/core/mesh_normals.hpp"
#include "algo/render/rasterizer.hpp"
#include "sim/lab/lab_commands.hpp"
#include "sim/lab/raster_pixels.hpp"
#include "sim/lab/transfer_image_lab.hpp"
#include "storage/export/mesh_files.hpp"
#include "storage/export/png_file.hpp"

namespace fb::cli {

namespace {

namespace fs = std::filesystem;

// NAME's file in an OBJ folder: neutral.obj, or blendshapes/NN_NAME.obj (the export layout).
Result<fs::path> mesh_file(const fs::path& dir, const std::string& name) {
  if (name == "neutral") {
    if (fs::is_regular_file(dir / "neutral.obj")) return dir / "neutral.obj";
    return fail((dir / "neutral.obj").string() +
                " not found: give a folder written by facebooth export or transfer --format obj");
  }
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir / "blendshapes", ec)) {
    const std::string stem = e.path().stem().string();
    const auto cut = stem.find('_');
    if (e.path().extension() == ".obj" && cut != std::string::npos && stem.substr(cut + 1) == name)
      return e.path();
  }
  return fail(dir.string() + " has no blendshapes/NN_" + name +
              ".obj: check --shapes against the folder's names");
}

// Where a row's meshes are seen from: the neutral's front (vertices within `depth` mm of its
// nearest point to a viewer on +z) fitted into a square panel.
struct View {
  Eigen::Vector3f centre = Eigen::Vector3f::Zero();
  float half_size = 100;
};

View frame_front(const MeshData& neutral, float depth) {
  float zmax = -1e30f;
  for (int v = 0; v < neutral.vertex_count(); ++v)
    zmax = std::max(zmax, neutral.positions[3 * static_cast<std::size_t>(v) + 2]);
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(1e30f), hi = -lo;
  for (int v = 0; v < neutral.vertex_count(); ++v) {
    const Eigen::Vector3f p(neutral.positions.data() + 3 * static_cast<std::size_t>(v));
    if (p.z() < zmax - depth) continue;
    lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  }
  View view;
  view.centre = (lo + hi) / 2;
  view.half_size = 0.55f * std::max(hi.x() - lo.x(), hi.y() - lo.y());
  return view;
}

// The mesh seen from +z (the face model's front: +x the subject's left, +y up), orthographic
// enough at 2 m, lit from the upper left; grey background.
ColorImage render_mesh(const MeshData& mesh, const View& view, int side) {
  constexpr float kDistance = 2000;
  PinholeIntrinsics k;
  k.width = k.height = side;
  k.fx = k.fy = kDistance * side / (2.0 * view.half_size);
  k.cx = k.cy = (side - 1) / 2.0;
  std::vector<Eigen::Vector3f> posed(static_cast<std::size_t>(mesh.vertex_count()));
  for (std::size_t v = 0; v < posed.size(); ++v) {
    const Eigen::Vector3f p = Eigen::Vector3f(mesh.positions.data() + 3 * v) - view.centre;
    posed[v] = {p.x(), -p.y(), kDistance - p.z()};  // camera: x right, y down, z forward
  }
  const std::vector<float> normals = vertex_normals(mesh.positions, mesh.triangles);
  RasterBuffers raster;
  raster.reset(side, side);
  ColorImage out;
  out.resize(side, side);
  std::fill(out.pixels.begin(), out.pixels.end(), Rgb8{70, 74, 80});
  if (!rasterize(k, posed, mesh.triangles, {}, raster)) return out;
  const Eigen::Vector3f light = Eigen::Vector3f(-0.4f, 0.5f, 1.0f).normalized();  // model frame
  for_each_covered_pixel(raster, [&](const RasterPixel& p) {
    const Eigen::Vector3f n = interpolate(normals, mesh.triangles, p);
    const float shade = 0.25f + 0.75f * std::max(0.0f, n.normalized().dot(light));
    out.at(p.x, p.y) =
        Rgb8{static_cast<std::uint8_t>(225 * shade), static_cast<std::uint8_t>(205 * shade),
             static_cast<std::uint8_t>(190 * shade)};
  });
  return out;
}

std::vector<std::string> split_names(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream in(text);
  for (std::string s; std::getline(in, s, ',');)
    if (!s.empty()) out.push_back(s);
  return out;
}

// One row: the folder's neutral and `shapes`, framed by its own neutral.
Result<std::vector<ColorImage>> render_row(const fs::path& dir,
                                           const std::vector<std::string>& shapes, int side) {
  std::vector<ColorImage> row;
  View view;
  for (std::size_t i = 0; i <= shapes.size(); ++i) {
    auto file = mesh_file(dir, i == 0 ? "neutral" : shapes[i - 1]);
    if (!file) return file.failure();
    auto mesh = read_obj(*file);
    if (!mesh) return mesh.failure();
    if (i == 0) view = frame_front(mesh->mesh, 40);
    row.push_back(render_mesh(mesh->mesh, view, side));
  }
  return row;
}

Result<void> write_sheet(const std::string& path, const std::vector<std::vector<ColorImage>>& rows,
                         int side) {
  constexpr int kGap = 4;
  const int cols = static_cast<int>(rows.front().size()), nrows = static_cast<int>(rows.size());
  ColorImage sheet;
  sheet.resize(cols * side + (cols - 1) * kGap, nrows * side + (nrows - 1) * kGap);
  std::fill(sheet.pixels.begin(), sheet.pixels.end(), Rgb8{255, 255, 255});
  for (int r = 0; r < nrows; ++r)
    for (int c = 0; c < cols; ++c)
      for (int y = 0; y < side; ++y)
        for (int x = 0; x < side; ++x)
          sheet.at(c * (side + kGap) + x, r * (side + kGap) + y) =
              rows[static_cast<std::size_t>(r)][static_cast<std::size_t>(c)].at(x, y);
  return write_png_file(path, sheet);
}

int run_render_transfer(const ParsedOptions& options) {
  const std::string png = options.get("png");
  const auto shapes = split_names(options.get("shapes"));
  auto side = options.get_int("size");
  if (png.empty() || options.get("source").empty() || options.get("target").empty() ||
      shapes.empty() || !side || *side < 32 || *side > 2048)
    return report_failure(
        {"--source DIR --target DIR --png FILE, --shapes A,B,... and "
         "--size 32..2048 are required"});
  std::vector<std::vector<ColorImage>> rows;
  for (const char* folder : {"source", "target", "truth"}) {
    if (options.get(folder).empty()) continue;
    auto row = render_row(options.get(folder), shapes, static_cast<int>(*side));
    if (!row) return report_failure(row.error());
    rows.push_back(std::move(*row));
  }
  if (auto ok = write_sheet(png, rows, static_cast<int>(*side)); !ok)
    return report_failure(ok.error());
  std::cout << "wrote " << png << ": " << rows.size() << " rows x " << shapes.size() + 1
            << " panels\n";
  return kExitOk;
}

}  // namespace

Command render_transfer_command() {
  return {{"render transfer",
           "picture of a 3D expression transfer: source, result (and truth) side by side",
           "Reads OBJ folders as facebooth export and facebooth transfer --format obj write them "
           "(neutral.obj, blendshapes/NN_NAME.obj) and draws each row's neutral and --shapes "
           "with the project's rasterizer, frontal, shaded: row 1 --source, row 2 --target (the "
           "transfer's output), row 3 --truth when given.",
           {{"source", "DIR", "the source's OBJ folder", ""},
            {"target", "DIR", "the transfer's OBJ folder", ""},
            {"truth", "DIR", "optional: the target's own expressions (a third row)", ""},
            {"shapes", "A,B,...", "expression names",
             "jawOpen,mouthSmile_L,mouthPucker,browInnerUp_L,eyeBlink_R"},
            {"size", "PX", "panel side", "220"},
            {"png", "FILE", "where to write the picture", ""}}},
          run_render_transfer};
}

}  // namespace fb::cli
