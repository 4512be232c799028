// faceboothd's TOML config (firmware/daemon/daemon_config): what --config reads.
#include "firmware/daemon/daemon_config.hpp"
#include "tests/fuzz/fuzz_util.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  auto config = fb::parse_daemon_config(fb::fuzz::text(data, size), "fuzz.toml", "/fuzz");
  if (!config) return 0;
  // A config that parses must print (--print-default-config) into TOML that parses again.
  auto again = fb::parse_daemon_config(fb::to_toml(*config), "printed.toml", "/fuzz");
  fb::fuzz::require(again.ok(), "to_toml of a parsed config parses");
  return 0;
}
