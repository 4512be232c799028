// The wrinkle exemplar set on disk (data/wrinkle_exemplars, written by
// host/convert_exemplars): exemplars.json listing 16-bit height PNGs (mm = (v - 32768) / 16384)
// and 8-bit shading PNGs, all at one pixel size. The only place that reads them for algo/.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
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

// A user's exemplar (issue 40 item 1; `facebooth wrinkles --exemplar`): a height map and a
// colour photograph of the same skin, pixel for pixel.
struct UserExemplarSpec {
  std::filesystem::path height;  // 8- or 16-bit grey PNG (any format OpenCV reads)
  std::filesystem::path colour;  // the skin's colour image, same size
  // mm per grey level about mid-grey (128 or 32768); unset: 1/16384 for 16-bit (the default
  // set's encoding), 1/128 for 8-bit (+-1 mm over the range).
  std::optional<double> mm_per_level;
};

// "HEIGHT:COLOUR[:MM_PER_LEVEL]"; errors say the expected form.
Result<UserExemplarSpec> parse_user_exemplar(const std::string& arg);

// The pair as exemplars at `to_mm_per_px` (the set's pixel size): heights about their mean,
// the colour image's luma (0..1), both resampled from `mm_per_px`, and the rotated copies of
// section 3.1 (0, 30, ..., 150 degrees), named "<height file stem>_<angle>". Errors name the
// file that cannot be read, the sizes that differ, or an image too small to rotate.
Result<std::vector<WrinkleExemplar>> load_user_exemplar(const UserExemplarSpec& spec,
                                                        double mm_per_px, double to_mm_per_px);

}  // namespace fb::cli
