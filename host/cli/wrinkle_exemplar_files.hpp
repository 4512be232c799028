// The wrinkle exemplar set on disk (data/wrinkle_exemplars, written by
// host/convert_exemplars): exemplars.json listing 16-bit height PNGs (mm = (v - 32768) / 16384)
// and 8-bit shading PNGs, all at one pixel size. The only place that reads them for algo/.
#pragma once

#include <filesystem>
#include <vector>

#include "algo/core/result.hpp"
#include "algo/wrinkles/texture_synthesis.hpp"

namespace fb::cli {

struct ExemplarSet {
  double mm_per_px = 0.0;
  std::vector<WrinkleExemplar> exemplars;  // name: "<region>_<angle>", e.g. "forehead_90"
};

// data_directory() / "wrinkle_exemplars".
std::filesystem::path default_exemplar_directory();

Result<ExemplarSet> load_exemplar_set(const std::filesystem::path& directory);

}  // namespace fb::cli
