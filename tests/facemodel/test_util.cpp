#include "tests/facemodel/test_util.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <fstream>
#include <iterator>

namespace fb::test {

const std::vector<std::byte>& asset_bytes() {
  static const std::vector<std::byte> bytes = [] {
    std::ifstream in(FB_DATA_DIR "/facemodel.fbfm", std::ios::binary);
    std::vector<char> chars((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::vector<std::byte> out(chars.size());
    std::memcpy(out.data(), chars.data(), chars.size());
    return out;
  }();
  return bytes;
}

const FaceModel& asset_model() {
  static const FaceModel model = [] {
    auto r = parse_face_model(asset_bytes());
    if (!r) {
      ADD_FAILURE() << "the committed asset does not parse: " << r.error().message;
      return FaceModel{};
    }
    return std::move(r).value();
  }();
  return model;
}

std::filesystem::path source_dir() {
  std::filesystem::path dir = std::filesystem::path(FB_SHARED_DIR) / "facemodel" / "ict-facekit";
  std::error_code ec;
  if (!std::filesystem::is_regular_file(dir / "FaceXModel" / "generic_neutral_mesh.obj", ec)) {
    return {};
  }
  return dir;
}

}  // namespace fb::test
