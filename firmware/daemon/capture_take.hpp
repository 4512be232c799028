// Private: the capture take, the daemon's room for recording one guide expression. It owns
// fusion and the take's depth confidence (reused between takes), the take's face detector, the
// frame loop's pacing (missed frames, a stalled camera), the spool of stored frames and the
// take's result until the fit worker gets it. The worker starts it, lets it record from a camera
// and takes the result; everything here runs on the worker thread (the face box search runs
// beside it, in TakeStart, synchronised by its future), so the room needs no lock: what other
// threads see of a take goes through the hooks into the status and the preview.
#pragma once

#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <utility>

#include "algo/fusion/face_fusion.hpp"
#include "algo/fusion/view_consistency.hpp"
#include "algo/landmarks/face_region_box.hpp"
#include "drivers/camera/depth_camera.hpp"
#include "firmware/daemon/quick_fit.hpp"
#include "firmware/daemon/session_records.hpp"
#include "firmware/daemon/take_fusion.hpp"

namespace fb {

struct QaReport {
  double coverage = 0;        // fused face-box pixels / face-box pixels
  double residual_mm = 0;     // mean ICP RMS over fused frames
  double fused_fraction = 0;  // fused frames / recorded frames
  // Landmarks and the quick fit ("off" when disabled, "failed" with a reason, else "ok").
  std::string landmarks = "off";
  std::string fit = "off";
  double landmark_score = 0;     // dlib detection margin
  int landmarks_3d = 0;          // interior points lifted with the fused depth
  double landmark_error_mm = 0;  // landmark_disagreement_mm() of the fit
  double fit_rms_mm = 0;         // RMS of the fitted mesh to the fused depth
  double fit_rms_initial_mm = 0;
  double fit_ms = 0;
  int corrections = 0;  // operator-corrected landmarks
  bool passed = false;
  std::string reason;  // why it failed
};

// A recorded take as the fit worker gets it.
struct RecordedTake {
  QaReport qa;           // the take's own quality (coverage, residual, fused share)
  CaptureCommit commit;  // spooled frames, fused depth, scores, calibration
  CaptureView view;      // frontal colour + fused surface
};

// What one take needs to know.
struct TakeSettings {
  int frames = 90;  // the take's length
  int stored_frame_stride = 3;
  std::filesystem::path spool_folder;
  std::string no_detector_note;  // why there is no face detector (when there is none)
  // The take's own quality check ([session]).
  double min_coverage = 0.25, min_fused_fraction = 0.6, max_residual_mm = 2.5;
};

// What the take's frame loop asks of the daemon, on the worker thread.
struct TakeHooks {
  std::function<bool()> cancelled;  // before each frame: true = cancelled or stopping
  std::function<void(const RgbdFrame&, const FaceBox&)> show;  // every 5th frame and the last
  std::function<void(int recorded)> recorded;                  // after each frame
  std::function<void(long long missed)> ended;  // the loop ended (not on a camera failure)
};

class CaptureTake {
 public:
  CaptureTake() = default;
  CaptureTake(const CaptureTake&) = delete;
  CaptureTake& operator=(const CaptureTake&) = delete;

  // Once, with the fitter: the face detector takes use (dlib's, shared) and the face model's
  // proportions that grow its box to the face.
  void set_detector(LandmarkDetector detector, FaceProportions proportions);
  // Once, at start-up: makes fusion's and the detector's buffers for `info`'s geometry.
  void warm_up(const CameraInfo& info);

  // Begins a take: hands freed heap back and creates its spool. Drops the last take's result.
  Result<void> start(const TakeSettings& settings);
  // Records and fuses the take from `camera` (started). False when cancelled or stopping.
  Result<bool> record(DepthCamera& camera, const TakeHooks& hooks);
  // The recorded take (moved out).
  RecordedTake take_result() { return std::exchange(result_, {}); }

 private:
  void assess(const TakeTally& tally, const CameraInfo& info);

  TakeSettings settings_;
  FaceFusion fusion_;
  ViewConsistency consistency_;  // the take's depth confidence
  // The take's face box: dlib (the fitter's shape predictor, shared) on the take's first frames,
  // grown by the face model's proportions. Made with the fitter (dlib's HOG detector takes
  // 0.5-1 s to build); used by one take's start thread at a time.
  std::optional<LandmarkDetector> detector_;
  std::optional<FaceProportions> proportions_;
  RecordedTake result_;
};

}  // namespace fb
