// The shipped exemplar set read back through the host's loader (real files in data/), and the
// error a user sees for a folder that is not one.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>

#include "host/cli/wrinkle_exemplar_files.hpp"

namespace fb::cli {
namespace {

TEST(ExemplarFiles, TheShippedSetLoadsWithItsSizesAndDepths) {
  const auto set = load_exemplar_set(std::filesystem::path(FB_DATA_DIR) / "wrinkle_exemplars");
  ASSERT_TRUE(set.ok()) << set.error().message;
  EXPECT_EQ(set->mm_per_px, 0.25);
  ASSERT_EQ(set->exemplars.size(), 24u);
  const auto& f = set->exemplars.front();
  EXPECT_EQ(f.name, "forehead_0");
  EXPECT_EQ(f.height_mm.width, 348);  // exemplars.json
  EXPECT_EQ(f.height_mm.height, 139);
  // The forehead's relief: 99th percentile |h| 0.4 mm by construction; shading in (0, 1).
  std::vector<float> a;
  for (float v : f.height_mm.pixels) a.push_back(std::abs(v));
  std::nth_element(a.begin(), a.begin() + static_cast<long>(0.99 * a.size()), a.end());
  EXPECT_NEAR(a[static_cast<std::size_t>(0.99 * a.size())], 0.4, 0.01);
  for (float v : f.luminance.pixels) ASSERT_TRUE(v > 0.0f && v < 1.0f);
}

TEST(ExemplarFiles, AFolderWithoutAListSaysWhatToDo) {
  const auto set = load_exemplar_set(std::filesystem::temp_directory_path());
  ASSERT_FALSE(set.ok());
  EXPECT_NE(set.error().message.find("facebooth-convert-exemplars"), std::string::npos);
}

}  // namespace
}  // namespace fb::cli
