// What `export` prints about a written folder, and the synthetic subject it exports with
// --from-face-model; `facebooth-lab eval storage` reports and builds the same.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"
#include "host/cli/command_line.hpp"
#include "storage/export/export_session.hpp"
#include "storage/export/synthetic_subject.hpp"

namespace fb::cli {

// Bytes of the regular files under `dir`.
Result<std::uintmax_t> folder_bytes(const std::filesystem::path& dir);
// path, bytes, files, seconds.
nlohmann::json summary_json(const ExportSummary& s);

// The face model of --face-model (the installed one when empty) and a synthetic subject of it
// with its identity drawn from `seed`; `log` starts the progress line naming the model's path.
struct FaceModelSubject {
  std::string model_path;
  FaceModel model;
  SyntheticSubject subject;
};
Result<FaceModelSubject> face_model_subject(const ParsedOptions& options, std::uint64_t seed,
                                            std::string_view log);

}  // namespace fb::cli
