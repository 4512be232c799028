// What `export` prints about a written folder; `facebooth-lab eval storage` reports the same.
#pragma once

#include <cstdint>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "algo/core/result.hpp"
#include "storage/export/export_session.hpp"

namespace fb::cli {

// Bytes of the regular files under `dir`.
Result<std::uintmax_t> folder_bytes(const std::filesystem::path& dir);
// path, bytes, files, seconds.
nlohmann::json summary_json(const ExportSummary& s);

}  // namespace fb::cli
