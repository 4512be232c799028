// The Khronos glTF validator (node + tools/node_modules/gltf-validator) on a .glb, for tests
// whose target defines FB_NODE_PATH, FB_GLTF_VALIDATOR_MODULE and FB_GLTF_VALIDATE_SCRIPT
// (tests/common/CMakeLists.txt: fb_use_gltf_validator).
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "tests/common/run_command.hpp"

namespace fb::test {

// The validator's report, or nullopt with `skip` saying why it could not run.
inline std::optional<nlohmann::json> validate_gltf(const std::filesystem::path& glb,
                                                   std::string& skip) {
  if (std::string(FB_NODE_PATH).empty()) {
    skip = "node is not installed (scripts/install-deps installs it)";
    return std::nullopt;
  }
  if (!std::filesystem::exists(FB_GLTF_VALIDATOR_MODULE)) {
    skip = "the Khronos glTF validator is missing from " FB_GLTF_VALIDATOR_MODULE
           ": run scripts/install-deps (npm ci --prefix tools)";
    return std::nullopt;
  }
  const auto validated = run_command(std::string(FB_NODE_PATH) + " " + FB_GLTF_VALIDATE_SCRIPT +
                                         " " + FB_GLTF_VALIDATOR_MODULE + " " + glb.string(),
                                     Stderr::kMerged);
  EXPECT_EQ(validated.exit_code, 0) << validated.out;
  auto report = nlohmann::json::parse(validated.out, nullptr, false);
  EXPECT_FALSE(report.is_discarded()) << validated.out;
  if (validated.exit_code != 0 || report.is_discarded()) return std::nullopt;
  return report;
}

}  // namespace fb::test
