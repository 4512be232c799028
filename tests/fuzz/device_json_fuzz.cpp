// device.json (drivers/camera/common/device_json): a dump's or a unit's calibration.
#include "drivers/camera/common/device_json.hpp"
#include "tests/fuzz/fuzz_util.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  auto calibration = fb::parse_device_json(fb::fuzz::text(data, size));
  if (!calibration) return 0;
  // What parses must write back into text that reads back the same.
  const std::string written = fb::to_device_json(*calibration);
  auto again = fb::parse_device_json(written);
  fb::fuzz::require(again.ok(), "to_device_json of a parsed calibration parses");
  fb::fuzz::require(fb::to_device_json(*again) == written,
                    "to_device_json of the re-read calibration is the same");
  return 0;
}
