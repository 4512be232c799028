// The committed face model asset (data/facemodel.fbfm), loaded once per test binary. When it
// cannot be loaded the calling test fails with the loader's message and gets an empty model.
#pragma once

#include <gtest/gtest.h>

#include <utility>

#include "algo/facemodel/face_model.hpp"
#include "storage/asset_files.hpp"

namespace fb::test {

inline const FaceModel& face_model() {
  static const FaceModel loaded = [] {
    auto m = load_face_model();
    if (!m) {
      ADD_FAILURE() << m.error().message;
      return FaceModel{};
    }
    return std::move(*m);
  }();
  return loaded;
}

}  // namespace fb::test
