// The one encoding of an RGB-D frame on disk: the record of the session store's .fbseq files
// and of the device's take spool (firmware/daemon/frame_spool). A fixed 56-byte header, then the
// depth (u16 mm), raw disparity (u16) and colour (RGB8) pixels, all little-endian (the store's
// static_assert). The spool leaves the disparity out (its header says 0 x 0).
#pragma once

#include <cstddef>
#include <cstdint>

#include "algo/core/frame.hpp"
#include "algo/core/result.hpp"

namespace fb::frame_record {

struct Header {
  std::uint64_t index;
  double depth_host_time_s;
  double color_host_time_s;
  std::uint32_t depth_device_timestamp;
  std::uint32_t color_device_timestamp;
  std::int32_t depth_w, depth_h, raw_w, raw_h, color_w, color_h;
};
static_assert(sizeof(Header) == 56, "the record header is part of the file format");

Header header_of(const RgbdFrame& frame, bool with_raw_disparity);
// Image sizes a frame can have (a damaged or foreign file fails this before any allocation).
bool plausible(const Header& header);
// Bytes of pixels after the header.
std::uint64_t pixel_bytes(const Header& header);
// The frame's fields from the header and its images sized by it (no allocation once sized).
void prepare(const Header& header, RgbdFrame& out);

template <class Pixel>
std::size_t bytes_of(const Image<Pixel>& image) {
  return image.pixels.size() * sizeof(Pixel);
}

// Writes one record through `sink(const void* data, std::size_t size) -> Result<void>`.
template <class Sink>
Result<void> write(const RgbdFrame& f, bool with_raw_disparity, Sink&& sink) {
  const Header h = header_of(f, with_raw_disparity);
  if (auto r = sink(&h, sizeof h); !r) return r;
  if (auto r = sink(f.depth_mm.pixels.data(), bytes_of(f.depth_mm)); !r) return r;
  if (with_raw_disparity) {
    if (auto r = sink(f.raw_disparity.pixels.data(), bytes_of(f.raw_disparity)); !r) return r;
  }
  return sink(f.color.pixels.data(), bytes_of(f.color));
}

// Reads the pixels that follow `header` into `out` through
// `source(void* data, std::size_t size) -> bool` (false: a short read).
template <class Source>
bool read_pixels(const Header& header, RgbdFrame& out, Source&& source) {
  prepare(header, out);
  return source(out.depth_mm.pixels.data(), bytes_of(out.depth_mm)) &&
         source(out.raw_disparity.pixels.data(), bytes_of(out.raw_disparity)) &&
         source(out.color.pixels.data(), bytes_of(out.color));
}

}  // namespace fb::frame_record
