#include "storage/asset_files.hpp"

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <system_error>
#include <vector>

namespace fb {
namespace {

constexpr const char* kFaceModelFile = "facemodel.fbfm";

std::string env_data_dir() {
  const char* v = std::getenv("FACEBOOTH_DATA_DIR");
  return v != nullptr ? std::string(v) : std::string();
}

bool file_exists(const std::filesystem::path& p) {
  std::error_code ec;
  return std::filesystem::is_regular_file(p, ec);
}

// Explains, for error messages, which directories data_directory() considered and why it
// picked the one it did, so a user can tell a wrong $FACEBOOTH_DATA_DIR from a missing asset.
std::string search_description() {
  const std::string env = env_data_dir();
  std::string s = "$FACEBOOTH_DATA_DIR ";
  s += env.empty() ? "is not set" : "= " + env;
  s += "; installed directory " FB_INSTALLED_DATA_DIR;
  s += file_exists(std::filesystem::path(FB_INSTALLED_DATA_DIR) / kFaceModelFile)
           ? " has the face model"
           : " has no face model";
  s += "; source tree directory " FB_DATA_DIR;
  return s;
}

}  // namespace

std::filesystem::path data_directory() {
  if (std::string env = env_data_dir(); !env.empty()) return env;
  const std::filesystem::path installed(FB_INSTALLED_DATA_DIR);
  if (file_exists(installed / kFaceModelFile)) return installed;
  return FB_DATA_DIR;
}

std::filesystem::path default_face_model_path() {
  return data_directory() / kFaceModelFile;
}

std::filesystem::path default_guide_path() {
  return data_directory() / "guide_expressions.json";
}

Result<GuideSet> load_guide_expressions(const FaceModel& model, const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    return fail("cannot read the guide expressions " + path.string() + " (the data directory is " +
                data_directory().string() +
                "; set $FACEBOOTH_DATA_DIR to the directory holding guide_expressions.json)");
  }
  std::ostringstream text;
  text << in.rdbuf();
  auto guide = parse_guide_expressions(text.str());
  if (!guide) return fail(path.string() + ": " + guide.error().message);
  if (auto valid = validate_guide(*guide, model); !valid) {
    return fail(path.string() + ": " + valid.error().message);
  }
  return std::move(*guide);
}

Result<FaceModel> load_face_model(const std::filesystem::path& path) {
  const std::string fix =
      " Run `facebooth-convert-facemodel --out " + path.string() +
      "` (it reads ../shared/facemodel/ict-facekit by default), or set $FACEBOOTH_DATA_DIR to "
      "the directory holding facemodel.fbfm.";
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    return fail("face model not found at " + path.string() + " (" + search_description() + ")." +
                fix);
  }
  if (!std::filesystem::is_regular_file(path, ec)) {
    return fail("face model path " + path.string() + " is not a regular file." + fix);
  }
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) return fail("cannot open the face model " + path.string() + " (permissions?)." + fix);
  const std::streamoff size = in.tellg();
  if (size < 0) return fail("cannot determine the size of " + path.string() + "." + fix);
  std::vector<std::byte> bytes(static_cast<std::size_t>(size));
  in.seekg(0);
  if (size > 0 && !in.read(reinterpret_cast<char*>(bytes.data()), size)) {
    return fail("error while reading the face model " + path.string() + "." + fix);
  }
  auto model = parse_face_model(bytes);
  if (!model) return fail(path.string() + ": " + model.error().message);
  return model;
}

std::filesystem::path default_landmark_embedding_path() {
  return data_directory() / "dlib_landmark_embedding.csv";
}

Result<LandmarkEmbedding> load_landmark_embedding(const FaceModel& model,
                                                  const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in)
    return fail("cannot read dlib's landmark embedding " + path.string() +
                " (the data directory is " + data_directory().string() +
                "; set $FACEBOOTH_DATA_DIR to the directory holding dlib_landmark_embedding.csv)");
  std::ostringstream text;
  text << in.rdbuf();
  auto embedding = parse_landmark_embedding(text.str(), model);
  if (!embedding) return fail(path.string() + ": " + embedding.error().message);
  return embedding;
}

Result<std::optional<LandmarkEmbedding>> landmark_embedding_beside(
    const FaceModel& model, const std::filesystem::path& model_path) {
  const std::filesystem::path path = model_path.parent_path() / "dlib_landmark_embedding.csv";
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return std::optional<LandmarkEmbedding>{};
  auto embedding = load_landmark_embedding(model, path);
  if (!embedding) return embedding.failure();
  return std::optional<LandmarkEmbedding>(*embedding);
}

}  // namespace fb
