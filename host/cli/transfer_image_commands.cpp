// `facebooth transfer-image`: a source's expression (two photographs of one face) mapped onto a
// photograph of another face by seed 002's 2D expression analogy (algo/transfer/
// image_transfer.hpp): landmark warp plus the vertex-tent-coordinate solve for the luminance.
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "algo/transfer/image_transfer.hpp"
#include "host/cli/commands.hpp"
#include "host/cli/tracker_setup.hpp"
#include "storage/durable_file.hpp"
#include "storage/export/png_file.hpp"

namespace fb::cli {

namespace {

namespace fs = std::filesystem;

Result<ColorImage> read_png(const fs::path& path, const char* option) {
  if (!fs::exists(path))
    return fail(std::string("--") + option + " " + path.string() + ": no such file");
  auto bytes = read_file_bytes(path);
  if (!bytes) return bytes.failure();
  auto image = decode_png(*bytes);
  if (!image)
    return fail(std::string("--") + option + " " + path.string() +
                " is not a PNG image we can read (" + image.error().message + ")");
  return image;
}

// 68 lines 'x y' (image px, iBUG order).
Result<Landmarks68> read_landmarks(const fs::path& path) {
  std::ifstream in(path);
  if (!in) return fail("cannot read the landmark file " + path.string());
  Landmarks68 points{};
  std::string line;
  std::size_t n = 0;
  while (std::getline(in, line)) {
    if (line.find_first_not_of(" \t\r") == std::string::npos || line[0] == '#') continue;
    std::istringstream s(line);
    double x = 0, y = 0;
    if (!(s >> x >> y) || !std::isfinite(x) || !std::isfinite(y))
      return fail(path.string() + ": each line must be 'x y' (pixels): '" + line + "'");
    if (n == 68) return fail(path.string() + " has more than 68 points");
    points[n++] = {x, y};
  }
  if (n != 68)
    return fail(path.string() + " has " + std::to_string(n) +
                " points: give the 68 iBUG landmarks, one 'x y' line each");
  return points;
}

std::vector<std::string> split_commas(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream s(text);
  std::string item;
  while (std::getline(s, item, ',')) out.push_back(item);
  return out;
}

int run_transfer_image(const ParsedOptions& options) {
  const std::array<const char*, 3> names = {"source-neutral", "source-expr", "target"};
  for (const char* n : names)
    if (options.get(n).empty()) return report_failure({std::string("--") + n + " is required"});
  const fs::path out = fs::absolute(options.get("out"));
  if (options.get("out").empty()) return report_failure({"--out is required (the PNG to write)"});
  if (fs::exists(out) && !options.flag("force"))
    return report_failure(
        {out.string() + " already exists: choose another --out, or pass --force to replace it"});
  if (!options.get("warped").empty() && fs::exists(options.get("warped")) && !options.flag("force"))
    return report_failure(
        {options.get("warped") + " already exists: choose another --warped, or pass --force"});
  std::array<FacePhoto, 3> photos;
  for (std::size_t i = 0; i < 3; ++i) {
    auto image = read_png(options.get(names[i]), names[i]);
    if (!image) return report_failure(image.error());
    photos[i].image = std::move(*image);
  }
  const auto files = split_commas(options.get("landmarks"));
  if (!files.empty() && files.size() != 3)
    return report_failure(
        {"--landmarks takes three files, comma-separated: the source neutral's, "
         "the source expression's and the target's"});
  std::string landmark_source = "given";
  if (!files.empty()) {
    for (std::size_t i = 0; i < 3; ++i) {
      auto points = read_landmarks(files[i]);
      if (!points) return report_failure(points.error());
      photos[i].points = *points;
    }
  } else {
    landmark_source = "dlib";
    auto detector = load_landmark_detector(options.get("shape-predictor"));
    if (!detector) return report_failure(detector.error());
    for (std::size_t i = 0; i < 3; ++i) {
      detector->reset_tracking();  // three unrelated photographs
      auto found = detector->detect(photos[i].image);
      if (!found)
        return report_failure({"no face found in --" + std::string(names[i]) + " " +
                               options.get(names[i]) +
                               ": use a frontal photograph with the face at least ~80 px wide, or "
                               "give the 68 landmarks with --landmarks"});
      for (std::size_t k = 0; k < 68; ++k) photos[i].points[k] = found->points[k];
    }
  }
  ImageTransferOptions o;
  auto height = options.get_double("luminance-height");
  if (!height || !(*height > 0)) return report_failure({"--luminance-height must be > 0"});
  o.luminance_height = *height;
  auto tolerance = options.get_double("tolerance");
  if (!tolerance || !(*tolerance > 0 && *tolerance < 1))
    return report_failure({"--tolerance must be in (0, 1)"});
  o.tolerance = *tolerance;
  auto result = transfer_image_expression(photos[0], photos[1], photos[2], o);
  if (!result) return report_failure(result.error());
  auto png = encode_png(result->image);
  if (!png) return report_failure(png.error());
  if (auto ok = write_file_durably(out, *png); !ok) return report_failure(ok.error());
  nlohmann::json j = {{"out", out.string()},
                      {"width", result->image.width},
                      {"height", result->image.height},
                      {"landmarks", landmark_source},
                      {"face_pixels", result->region_pixels},
                      {"iterations", result->iterations},
                      {"warp_ms", result->warp_ms},
                      {"solve_ms", result->solve_ms}};
  if (!options.get("warped").empty()) {
    auto warped = encode_png(result->warped);
    if (!warped) return report_failure(warped.error());
    if (auto ok = write_file_durably(fs::absolute(options.get("warped")), *warped); !ok)
      return report_failure(ok.error());
    j["warped"] = options.get("warped");
  }
  std::cout << j.dump(2) << std::endl;
  return kExitOk;
}

}  // namespace

std::vector<Command> transfer_image_commands() {
  return {
      {{"transfer-image",
        "map the expression of one face's photographs onto a photograph of another face",
        "Seed 002 section VI: the three photographs' 68 landmarks (dlib's, or --landmarks) align "
        "them by similarities; the target is warped piecewise-affinely so that its landmarks "
        "move as the source's did from --source-neutral to --source-expr; then, inside the face "
        "(jaw line to above the brows), each image is a quad mesh over its pixels with the "
        "luminance as height, and the target's luminance is solved so that its vertex tents "
        "deform as the source's do (a sparse least squares, conjugate gradients); the colour "
        "is the warped target's chromaticity plus the source's change of it. Outside the face "
        "the warped target shows, the source's change fading out over 8 px. The two source "
        "photographs must have the same size "
        "(one camera); the target may differ. Writes a PNG of the target's size; JSON summary "
        "on stdout.",
        {{"source-neutral", "A.png", "the source face, neutral", ""},
         {"source-expr", "B.png", "the same face with the expression to transfer", ""},
         {"target", "C.png", "the face to give the expression to, neutral", ""},
         {"out", "D.png", "the result (must not exist unless --force)", ""},
         {"landmarks", "A.txt,B.txt,C.txt",
          "the three photographs' 68 iBUG landmarks, one 'x y' line each (pixels), instead of "
          "dlib's",
          ""},
         {"shape-predictor", "PATH", "dlib's 68-point model (default: Debian libdlib-data's)", ""},
         {"warped", "FILE.png", "also write the target warped by the landmarks only", ""},
         {"luminance-height", "H", "grid height of one luminance level, in pixel widths", "1"},
         {"tolerance", "T", "the luminance solve stops when its residual is T times its start's",
          "3e-3"},
         {"force", "", "replace --out if it exists", ""}}},
       run_transfer_image}};
}

}  // namespace fb::cli
