// PNG encoding of colour frames for exports (libpng's simplified API: no setjmp/longjmp
// crossing C++ frames).
#pragma once

#include <cstdint>
#include <vector>

#include "algo/core/image.hpp"
#include "algo/core/result.hpp"

namespace fb {

Result<std::vector<std::uint8_t>> encode_png(const ColorImage& image);
Result<ColorImage> decode_png(const std::vector<std::uint8_t>& bytes);

}  // namespace fb
