// A synthetic subject built from the face model, standing in for real fitted meshes and rigs
// until fitting and rigging produce them: neutral = model neutral + random identity, blendshape
// j = that neutral + expression delta j, and "fitted" training poses = the rig at known weights.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"
#include "storage/session_store.hpp"
#include "storage/stored_data.hpp"

namespace fb {

struct SyntheticSubjectOptions {
  std::uint64_t seed = 1;
  int pose_count = 20;          // FaceWarehouse's 20 training poses
  float identity_sigma = 1.0f;  // identity coefficients ~ N(0, sigma) in model sigma units
};

struct SyntheticSubject {
  RigData rig;
  std::vector<float> identity;                   // the identity coefficients used
  std::vector<std::string> pose_names;           // pose 0 is "neutral"
  std::vector<std::vector<float>> pose_weights;  // one weight per rig shape
  std::vector<MeshData> poses;                   // rig evaluated at pose_weights
};

Result<SyntheticSubject> make_synthetic_subject(const FaceModel& model,
                                                const SyntheticSubjectOptions& options);

// Colour and frame size of the synthetic captures stored by store_synthetic_subject.
struct SyntheticCaptureOptions {
  int width = 160;
  int height = 120;
  int frames_per_capture = 2;
};

// Puts a synthetic subject into a store as a finished session: one done capture per pose (small
// synthetic frames: depth ramp and a colour pattern), the rig, and the fitted meshes. Returns
// the session id.
Result<SessionId> store_synthetic_subject(SessionStore& store, const SyntheticSubject& subject,
                                          const std::string& name,
                                          const SyntheticCaptureOptions& capture = {});

}  // namespace fb
