// The subject's texture of a stored session (issue 37): each textured capture's fitted mesh,
// its take's frames and 3D landmarks, the unit calibration the session recorded, through
// algo/texture's take_texture; the atlas is stored with the session as a PNG.
#pragma once

#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"
#include "algo/texture/take_texture.hpp"
#include "algo/texture/texel_map.hpp"
#include "storage/session_store.hpp"

namespace fb::cli {

struct CaptureTextureReport {
  int capture_index = 0;
  std::string expression;
  std::optional<TextureId> stored;  // when saved
  int frames = 0;
  int frames_aligned = 0;
  int views = 0;
  double observed_fraction = 0.0;  // of the atlas's covered texels
  double seconds = 0.0;
};

// The newest fitted mesh of each capture of `session` (a neutral mesh counts for its capture,
// 0 when it names none), by capture index.
Result<std::map<int, MeshId>> fitted_meshes(const SessionStore& store, SessionId session);

// What texturing a session, or adding its wrinkle detail, starts from: the unit calibration it
// recorded (`note` says when the defaults stand in), the atlas's texel map at `size` texels a
// tile, the newest fitted mesh of each capture (the neutral, capture 0, among them) and its
// captures.
struct SessionAtlasInputs {
  std::string note;
  KinectCalibration calibration;
  std::vector<float> uvs;
  TexelMap map;
  std::map<int, MeshId> meshes;
  std::vector<CaptureInfo> captures;
};
Result<SessionAtlasInputs> session_atlas_inputs(const SessionStore& store, const SessionInfo& info,
                                                const FaceModel& model, int size);

// The unit calibration a session recorded, or the defaults (with `note` saying so).
Result<KinectCalibration> session_calibration(const SessionInfo& session, std::string& note);

// Builds the texture of capture `capture_index` of a session from its newest fitted mesh.
Result<TakeTexture> texture_capture(const SessionStore& store, SessionId session, int capture_index,
                                    const FaceModel& model, const TexelMap& map,
                                    const KinectRegistration& registration,
                                    const TakeTextureOptions& options = {});

// The captures with a fitted mesh, neutral first: the subject texture (from the neutral's take)
// and, with `expressions`, one per other capture. `save`: stored in the session (PNG).
// `progress(done, total)` after each capture.
Result<std::vector<CaptureTextureReport>> texture_session(
    SessionStore& store, SessionId session, const FaceModel& model, int size, bool expressions,
    bool save, const std::function<void(int, int)>& progress = {});

}  // namespace fb::cli
