// device.json (drivers/camera/common/device_json): a dump's or a unit's calibration.
#include "drivers/camera/common/device_json.hpp"
#include "tests/fuzz/fuzz_util.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  auto calibration = fb::parse_device_json(fb::fuzz::text(data, size));
  if (!calibration) return 0;
  // What parses must write back into text that parses again.
  auto again = fb::parse_device_json(fb::to_device_json(*calibration));
  fb::fuzz::require(again.ok(), "to_device_json of a parsed calibration parses");
  return 0;
}
