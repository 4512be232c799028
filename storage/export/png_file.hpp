// Image files for exports: PNG colour frames (libpng's simplified API: no setjmp/longjmp
// crossing C++ frames) and 16-bit PGM depth maps (millimetres).
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "algo/core/image.hpp"
#include "algo/core/result.hpp"

namespace fb {

Result<std::vector<std::uint8_t>> encode_png(const ColorImage& image);
Result<ColorImage> decode_png(const std::vector<std::uint8_t>& bytes);
// encode_png() written to `path`; the error names the file and what to check.
Result<void> write_png_file(const std::filesystem::path& path, const ColorImage& image);

// Binary PGM (P5), maxval 65535, big-endian samples as the format requires: a depth map in mm.
std::string encode_pgm16(const DepthImage& image);

}  // namespace fb
