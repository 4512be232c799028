// What the lab's `eval track` and `bench track` share: running the tracker over a rendered
// synthetic take frame by frame (errors against the truth, stage times, thread CPU time, the
// frame-to-OSC latency) and the `--set` tracker overrides. dlib and bilinear-model loading,
// which `track` uses too, are in host/cli/tracker_setup.hpp.
#pragma once

#include <chrono>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "algo/bilinear/bilinear_model.hpp"
#include "algo/core/clock.hpp"
#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"
#include "algo/tracking/arkit.hpp"
#include "algo/tracking/bilinear_subject.hpp"
#include "algo/tracking/detected_landmarks.hpp"
#include "algo/tracking/face_tracker.hpp"
#include "firmware/streaming/vmc_sender.hpp"
#include "host/cli/stats.hpp"
#include "host/cli/tracker_setup.hpp"
#include "sim/subject/synthetic_take.hpp"

namespace fb::cli {

double thread_cpu_ms();  // CPU time of the calling thread

// --set key=value[,key=value...]: tracker options by their TrackerOptions names (booleans as
// 0 / 1), for side-by-side runs of two option sets.
Result<TrackerOptions> tracker_overrides(const std::string& text);

struct FrameResult {
  TrackState state = TrackState::kSearching;
  bool calibrated = false;
  std::vector<float> abs_error;  // per model fitting shape
  // Per shape, with WeightSolverOptions::report_weight_sigma: the weight's data-only standard error
  // (TrackReport::weight_sigma); empty otherwise.
  std::vector<float> weight_sigma;
  double rotation_error_deg = 0, centre_error_mm = 0, origin_error_mm = 0;
  double raw_rotation_error_deg = 0, raw_centre_error_mm = 0;
  TrackTimes times;
  double cpu_ms = 0;       // thread CPU time of track()
  double latency_ms = -1;  // frame arrival -> OSC datagrams sent (when a sender is given)
  int landmarks_used = 0;
  double landmark_ms = 0;  // dlib detection + mapping (RunOptions::dlib), not in `times`
  // dlib's points against the truth (interior points 17-67 it placed): sum of squared per-axis
  // pixel errors and how many axes.
  double landmark_sq_error_px2 = 0;
  int landmark_axes = 0;
  bool detected = false;
  // TrackReport::occluded / occluded_fraction: what the tracker says something in front of the
  // face hides.
  bool occluded = false;
  float occluded_fraction = 0.0f;
  RigidPose estimate, truth;  // filtered estimate and truth (camera_from_model)
};

struct RunOptions {
  bool landmarks = true;
  TrackLandmarkSource* dlib = nullptr;  // landmarks from dlib on the colour images instead
  // Without landmarks (depth-only runs): dlib on the colour image while the tracker has no face
  // or calibrates, as `track --reacquire dlib` and the device do; null = depth alone.
  TrackLandmarkSource* reacquire = nullptr;
  bool known_identity = false;  // load the true identity instead of calibrating
  VmcSender* sender = nullptr;
  std::vector<float>* identity_out = nullptr;  // the tracker's identity after the take
  // Calibrate with a bilinear model instead of the face model's identity PCA (not with
  // known_identity, whose coefficients are the face model's).
  const BilinearSubjectModel* bilinear = nullptr;
  TrackerOptions tracker;
};

RigidPose compose(const RigidPose& a, const RigidPose& b);
double rotation_error_deg(const RigidPose& a, const RigidPose& b);
bool tracked(TrackState s);  // tracking or recovered

Result<std::vector<FrameResult>> run_take(const FaceModel& model, const ArkitMapping& mapping,
                                          const RenderedTake& take, const RunOptions& run);

}  // namespace fb::cli
