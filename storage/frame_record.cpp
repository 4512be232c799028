#include "storage/frame_record.hpp"

namespace fb::frame_record {

Header header_of(const RgbdFrame& f, bool with_raw_disparity) {
  return {f.index,
          f.depth_host_time_s,
          f.color_host_time_s,
          f.depth_device_timestamp,
          f.color_device_timestamp,
          f.depth_mm.width,
          f.depth_mm.height,
          with_raw_disparity ? f.raw_disparity.width : 0,
          with_raw_disparity ? f.raw_disparity.height : 0,
          f.color.width,
          f.color.height};
}

bool plausible(const Header& h) {
  for (std::int32_t v : {h.depth_w, h.depth_h, h.raw_w, h.raw_h, h.color_w, h.color_h})
    if (v < 0 || v > 16384) return false;
  return true;
}

std::uint64_t pixel_bytes(const Header& h) {
  auto area = [](std::int32_t w, std::int32_t h) {
    return static_cast<std::uint64_t>(w) * static_cast<std::uint64_t>(h);
  };
  return area(h.depth_w, h.depth_h) * sizeof(std::uint16_t) +
         area(h.raw_w, h.raw_h) * sizeof(std::uint16_t) + area(h.color_w, h.color_h) * sizeof(Rgb8);
}

void prepare(const Header& h, RgbdFrame& out) {
  out.index = h.index;
  out.depth_host_time_s = h.depth_host_time_s;
  out.color_host_time_s = h.color_host_time_s;
  out.depth_device_timestamp = h.depth_device_timestamp;
  out.color_device_timestamp = h.color_device_timestamp;
  out.depth_mm.resize(h.depth_w, h.depth_h);
  out.raw_disparity.resize(h.raw_w, h.raw_h);
  out.color.resize(h.color_w, h.color_h);
}

}  // namespace fb::frame_record
