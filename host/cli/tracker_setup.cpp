#include "host/cli/tracker_setup.hpp"

#include <filesystem>
#include <fstream>
#include <iostream>
#include <span>

#include "storage/durable_file.hpp"

namespace fb::cli {

Result<LandmarkDetector> load_landmark_detector(const std::string& option) {
  const std::filesystem::path path = option.empty() ? kShapePredictor : option;
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    return fail("cannot read the landmark model " + path.string() +
                " (install Debian's libdlib-data or pass --shape-predictor PATH)");
  }
  return LandmarkDetector::create(in);
}

std::string BilinearSubjectModel::describe() const {
  return "bilinear model " + path + " (" + std::to_string(bilinear.id_knobs) + " x " +
         std::to_string(bilinear.exp_knobs) + " knobs, " +
         std::to_string(tracking.face.identity_count) + " identity modes)";
}

std::string BilinearSubjectModel::limitation() const {
  int named = 0;
  for (int row : tracking.expression_row) named += row >= 0 ? 1 : 0;
  const int shapes = static_cast<int>(tracking.expression_row.size());
  std::string note;
  if (named < shapes) {
    note = std::to_string(shapes - named) + " of the face model's " + std::to_string(shapes) +
           " fitting shapes are not in the model and keep the generic blendshapes";
  }
  if (bilinear.exp_knobs >= named) return note;
  // u_e - u_0 of `named` shapes in exp_knobs dimensions: the blendshapes are linearly dependent.
  return (note.empty() ? "" : note + "; ") + "the model keeps " +
         std::to_string(bilinear.exp_knobs) + " expression knobs for " + std::to_string(named) +
         " blendshapes, so the subject's blendshapes span only " +
         std::to_string(bilinear.exp_knobs) +
         " dimensions and the weights are not unique; for tracking, build it with "
         "`facebooth model build --exp-knobs " +
         std::to_string(bilinear.expression_count) + "`";
}

Result<std::unique_ptr<BilinearSubjectModel>> load_bilinear_subject_model(
    const std::string& path, const FaceModel& topology, const std::string& command) {
  std::cerr << command << ": loading the bilinear model " << path << "...\n";
  auto bytes = read_file_bytes(path);
  if (!bytes) {
    return fail(bytes.error().message +
                " (a bilinear model is written by `facebooth model build --out FILE`)");
  }
  auto parsed = parse_bilinear_model(std::as_bytes(std::span(*bytes)));
  if (!parsed) return fail(path + ": " + parsed.error().message);
  auto out = std::make_unique<BilinearSubjectModel>();
  out->path = path;
  out->bilinear = std::move(*parsed);
  auto tracking = make_bilinear_tracking_model(out->bilinear, topology);
  if (!tracking) return fail(path + ": " + tracking.error().message);
  out->tracking = std::move(*tracking);
  out->blendshapes.emplace(out->bilinear, out->tracking);
  if (const std::string note = out->limitation(); !note.empty())
    std::cerr << command << ": note: " << note << "\n";
  return out;
}

}  // namespace fb::cli
