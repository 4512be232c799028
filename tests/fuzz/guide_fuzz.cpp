// The guide recipes JSON: algo/guide's parser (data/guide_expressions.json) and the daemon's
// reading of the same file into kiosk steps (firmware/daemon/guide_steps). Both read each input.
#include "algo/guide/guide_expressions.hpp"
#include "firmware/daemon/guide_steps.hpp"
#include "tests/fuzz/fuzz_util.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto text = fb::fuzz::text(data, size);
  auto guide = fb::parse_guide_expressions(text);
  if (guide) {
    for (std::size_t i = 0; i < guide->expressions.size(); ++i)
      fb::fuzz::require(guide->find(guide->expressions[i].name) == static_cast<int>(i),
                        "each parsed expression is found by its name at its id");
  }
  (void)fb::parse_guide_steps(text);
  return 0;
}
