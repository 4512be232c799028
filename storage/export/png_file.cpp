#include "storage/export/png_file.hpp"

#include <png.h>

#include <cstring>
#include <fstream>
#include <memory>

namespace fb {

namespace {
// png_image owns internal state until png_image_free; this keeps that exception-safe.
struct PngImageFree {
  void operator()(png_image* image) const { png_image_free(image); }
};
}  // namespace

Result<std::vector<std::uint8_t>> encode_png(const ColorImage& image) {
  if (image.empty()) return fail("cannot encode an empty image as PNG");
  png_image png;
  std::memset(&png, 0, sizeof png);
  png.version = PNG_IMAGE_VERSION;
  png.width = static_cast<png_uint_32>(image.width);
  png.height = static_cast<png_uint_32>(image.height);
  png.format = PNG_FORMAT_RGB;
  const std::unique_ptr<png_image, PngImageFree> guard(&png);
  png_alloc_size_t size = 0;
  if (!png_image_write_to_memory(&png, nullptr, &size, 0, image.pixels.data(), 0, nullptr)) {
    return fail(std::string("PNG encoding failed: ") + png.message);
  }
  std::vector<std::uint8_t> out(size);
  if (!png_image_write_to_memory(&png, out.data(), &size, 0, image.pixels.data(), 0, nullptr)) {
    return fail(std::string("PNG encoding failed: ") + png.message);
  }
  out.resize(size);
  return out;
}

Result<void> write_png_file(const std::filesystem::path& path, const ColorImage& image) {
  auto png = encode_png(image);
  if (!png) return png.failure();
  std::ofstream f(path, std::ios::binary);
  f.write(reinterpret_cast<const char*>(png->data()), static_cast<std::streamsize>(png->size()));
  if (!f)
    return fail("could not write " + path.string() + "; check the folder exists and is writable");
  return success();
}

Result<ColorImage> decode_png(const std::vector<std::uint8_t>& bytes) {
  png_image png;
  std::memset(&png, 0, sizeof png);
  png.version = PNG_IMAGE_VERSION;
  const std::unique_ptr<png_image, PngImageFree> guard(&png);
  if (!png_image_begin_read_from_memory(&png, bytes.data(), bytes.size())) {
    return fail(std::string("not a readable PNG: ") + png.message);
  }
  png.format = PNG_FORMAT_RGB;
  ColorImage image;
  image.resize(static_cast<int>(png.width), static_cast<int>(png.height));
  if (!png_image_finish_read(&png, nullptr, image.pixels.data(), 0, nullptr)) {
    return fail(std::string("PNG decoding failed: ") + png.message);
  }
  return image;
}

std::string encode_pgm16(const DepthImage& image) {
  std::string out =
      "P5\n" + std::to_string(image.width) + " " + std::to_string(image.height) + "\n65535\n";
  out.reserve(out.size() + image.pixels.size() * 2);
  for (std::uint16_t v : image.pixels) {
    out.push_back(static_cast<char>(v >> 8));
    out.push_back(static_cast<char>(v & 0xff));
  }
  return out;
}

}  // namespace fb
