// An export assembled in a hidden temporary folder next to its destination and renamed into
// place only when complete, with a manifest.json listing every file's size and SHA-256. An
// interrupted export therefore never looks complete: at worst a `.tmp-*` folder is left.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "algo/core/result.hpp"

namespace fb {

inline constexpr int kExportManifestVersion = 1;

struct ExportManifest {
  std::string what;  // "facewarehouse", "glb", "obj", "ply", a take's "livelink_csv[+glb]"
  std::map<std::string, std::string> source;   // session/subject/store, or face_model/seed
  std::map<std::string, std::string> details;  // counts, units, conventions
};

struct ExportedFile {
  std::string path;  // relative to the export folder, '/' separated
  std::uint64_t bytes = 0;
  std::string sha256;
};

class ExportFolder {
 public:
  // Fails when `destination` exists, unless `overwrite` (then it is replaced at finish()).
  static Result<ExportFolder> create(const std::filesystem::path& destination, bool overwrite);
  ExportFolder(ExportFolder&&) noexcept;
  ExportFolder& operator=(ExportFolder&&) = delete;
  // Removes the temporary folder unless finish() succeeded.
  ~ExportFolder();

  // Writes one file (creating sub-folders) and records its checksum.
  Result<void> write_file(const std::string& relative_path, std::span<const std::uint8_t> bytes);
  Result<void> write_text(const std::string& relative_path, std::string_view text) {
    return write_file(relative_path,
                      {reinterpret_cast<const std::uint8_t*>(text.data()), text.size()});
  }
  // Writes manifest.json, syncs, and renames the folder to its destination.
  Result<void> finish(const ExportManifest& manifest);

  const std::vector<ExportedFile>& files() const { return files_; }
  std::uint64_t total_bytes() const;
  const std::filesystem::path& destination() const { return destination_; }

 private:
  ExportFolder() = default;
  std::filesystem::path destination_;
  std::filesystem::path temp_;
  bool overwrite_ = false;
  bool finished_ = false;
  std::vector<ExportedFile> files_;
};

// Reads a manifest back and checks every listed file's size and SHA-256 (for tests and users).
Result<std::vector<ExportedFile>> verify_export_folder(const std::filesystem::path& folder);

}  // namespace fb
