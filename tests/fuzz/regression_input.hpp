// The inputs the fuzz targets crashed on, kept in tests/fuzz/regressions/<target>/ (the targets
// replay them too). A GoogleTest regression test reads its input with this; the first byte of
// inputs of the targets that pick a part by it is dropped with `skip_selector`.
#pragma once

#include <gtest/gtest.h>

#include <fstream>
#include <iterator>
#include <string>

namespace fb::test {

inline std::string fuzz_regression(const std::string& target, const std::string& name,
                                   bool skip_selector = false) {
  const std::string path =
      std::string(FB_SOURCE_DIR) + "/tests/fuzz/regressions/" + target + "/" + name;
  std::ifstream in(path, std::ios::binary);
  EXPECT_TRUE(in.good()) << "missing fuzz regression input " << path;
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (skip_selector && !bytes.empty()) bytes.erase(0, 1);
  return bytes;
}

}  // namespace fb::test
