// A session store holding eval wrinkles' grooves case (subject 1, raised brows) as a
// brow-raiser capture and the same subject without relief or raised brows as the neutral, both
// frames moved into the colour camera's image through the default unit's registration, with
// their 3D landmarks, fitted meshes and (optionally) a rig: what `facebooth wrinkles` reads.
#pragma once

#include <gtest/gtest.h>

#include <filesystem>

#include "drivers/camera/common/device_json.hpp"
#include "sim/lab/wrinkle_case.hpp"
#include "storage/asset_files.hpp"
#include "storage/session_store.hpp"

namespace fb::test {

inline CaptureInput wrinkle_capture_of(const cli::WrinkleCase& c, const FaceModel& model,
                                       const KinectRegistration& registration) {
  CaptureInput in;
  auto frame = cli::wrinkle_case_frame(c, model, registration);
  EXPECT_TRUE(frame) << frame.error().message;
  in.fused_depth = frame->depth_mm;
  in.frames.push_back(std::move(*frame));
  // The case's 2D landmarks are in the depth image; the colour ones are not needed.
  for (int l = 0; l < 68; ++l) {
    const auto& p = c.landmarks_3d[static_cast<std::size_t>(l)];
    in.landmarks.push_back({0.0f, 0.0f, true, static_cast<float>(p.x()), static_cast<float>(p.y()),
                            static_cast<float>(p.z())});
  }
  return in;
}

// The generic rig on the subject's neutral: neutral + each fitting expression of the model.
inline RigData generic_rig(const FaceModel& model, const std::vector<float>& neutral) {
  RigData rig;
  rig.neutral = neutral;
  rig.triangles = model.triangles;
  for (int j = 0; j < model.fitting_expression_count; ++j) {
    std::vector<float> shape = neutral;
    const auto e = model.expression_shape(j);
    for (std::size_t i = 0; i < shape.size(); ++i) shape[i] += e[i];
    rig.shapes.push_back(std::move(shape));
    rig.shape_names.push_back(model.expression_names[static_cast<std::size_t>(j)]);
  }
  return rig;
}

struct WrinkleStore {
  SessionId session = 0;
  SubjectId subject = 0;
};

// Creates the store at `root` (neutral = cases[0], brow_raiser = cases[1]); with `rig`, adds
// the generic rig on the neutral.
inline WrinkleStore make_wrinkle_store(const std::filesystem::path& root, const FaceModel& model,
                                       const cli::WrinkleCase& neutral,
                                       const cli::WrinkleCase& brows, bool rig) {
  const KinectCalibration calibration = KinectCalibration::defaults();
  const KinectRegistration registration(calibration);
  WrinkleStore out;
  auto store = SessionStore::open(root);
  EXPECT_TRUE(store) << store.error().message;
  if (!store) return out;
  out.subject = *store->add_subject("wrinkled");
  out.session = *store->create_session(out.subject, {"neutral", "brow_raiser"});
  EXPECT_TRUE(store->set_session_calibration(out.session, to_device_json(calibration)));
  const cli::WrinkleCase* cases[2] = {&neutral, &brows};
  for (int i = 0; i < 2; ++i) {
    EXPECT_TRUE(store->begin_capture(out.session, i));
    EXPECT_TRUE(
        store->commit_capture(out.session, i, wrinkle_capture_of(*cases[i], model, registration)));
    EXPECT_TRUE(store->add_mesh(out.session, i, i == 0 ? MeshRole::kNeutral : MeshRole::kFitted,
                                i == 0 ? "neutral" : "brow_raiser",
                                {cases[i]->vertices, model.triangles}));
  }
  if (rig) {
    EXPECT_TRUE(store->add_rig(out.subject, out.session, generic_rig(model, neutral.vertices)));
  }
  return out;
}

}  // namespace fb::test
