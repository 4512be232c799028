// faceboothd's TOML config (firmware/daemon/daemon_config): what --config reads.
#include "firmware/daemon/daemon_config.hpp"
#include "tests/fuzz/fuzz_util.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  auto config = fb::parse_daemon_config(fb::fuzz::text(data, size), "fuzz.toml", "/fuzz");
  if (!config) return 0;
  // A config that parses must print (--print-default-config) into TOML that reads back the same.
  const std::string printed = fb::to_toml(*config);
  auto again = fb::parse_daemon_config(printed, "printed.toml", "/fuzz");
  fb::fuzz::require(again.ok(), "to_toml of a parsed config parses");
  fb::fuzz::require(fb::to_toml(*again) == printed, "to_toml of the re-read config is the same");
  return 0;
}
