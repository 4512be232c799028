// Private: tracking mode, the daemon's room for live tracking. It owns the face tracker (with
// dlib re-acquisition on the colour image), the VMC sender, the take buffered for the store,
// the per-frame latency rings and the live weights the page reads. The worker starts, feeds and
// stops it (its frame loop is the one thread that touches the tracker); the HTTP threads read
// only the live weights, under their own lock (LiveWeights). What the status shows is copied
// out of it by the worker (Tick, figures()): the status stays a snapshot.
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "algo/core/clock.hpp"
#include "algo/tracking/arkit.hpp"
#include "algo/tracking/detected_landmarks.hpp"
#include "algo/tracking/face_tracker.hpp"
#include "algo/tracking/occlusion_report.hpp"
#include "algo/wrinkles/map_weights.hpp"
#include "drivers/camera/depth_camera.hpp"
#include "firmware/daemon/guide_steps.hpp"
#include "firmware/daemon/session_records.hpp"
#include "firmware/streaming/live_json.hpp"
#include "firmware/streaming/vmc_sender.hpp"
#include "storage/take_writer.hpp"

namespace fb {

// The latest tracked frame as JSON for the page (/api/tracking/live and its event stream):
// written by the worker, read by any thread.
class LiveWeights {
 public:
  // `detail`: the frame's wrinkle map weights (none when the rig has no detail captures).
  void publish(const ArkitFrame& frame, const LiveDetailWeights& detail = {});
  // The latest frame's JSON ("" before the first).
  std::string latest() const;
  // Waits up to `timeout` for a frame newer than `seen` (or for `stopping`): its JSON, with
  // `seen` moved to it; "" when none came.
  std::string wait_newer(std::uint64_t& seen, std::chrono::milliseconds timeout,
                         const std::atomic<bool>& stopping) const;
  // Wakes the waiters (at stop).
  void wake_all() const;
  // Forgets the latest frame (at stop): a page must not read the last run's weights as live.
  void clear();

 private:
  mutable std::mutex mutex_;
  mutable std::condition_variable cv_;
  std::string json_;  // guarded by mutex_
  std::uint64_t version_ = 0;
};

// Whose face is tracked: the subject's stored rig (from the host) wins over the quick neutral
// fit's identity; neither = the mean face, calibrated on the first frames.
struct TrackingIdentity {
  std::optional<StoredRig> rig;
  // The booth's guide: the recipes of the rig's detail captures (their map weights). Must
  // outlive start(); null = no map weights.
  const std::vector<GuideStep>* guide = nullptr;
  std::vector<float> neutral;  // identity coefficients of the neutral fit
  std::int64_t neutral_session = 0;
};

// The recipes (one weight per fitting shape of `model`) of a rig's detail captures, in order,
// from the booth's guide: what the map weights c = P^T a invert. Fails naming the capture whose
// expression the guide has no recipe for (or the neutral, which is no weighted capture).
Result<std::vector<std::vector<float>>> detail_capture_recipes(
    std::span<const RigDetailCapture> captures, const std::vector<GuideStep>& guide,
    const FaceModel& model);

class TrackingMode {
 public:
  // What one frame changed, for the status.
  struct Tick {
    bool detected = false;  // the face detector found the face (re-acquisition)
    bool occlusion_changed = false;
    std::string send_error;  // the VMC datagram was not sent: why
  };
  // Over this run, for the status.
  struct Figures {
    const char* state = "";   // the tracker's state of the last frame
    const char* reason = "";  // why it has no face then, or ""
    bool occluded = false;
    double hidden_fraction = 0;
    long long occluded_frames = 0;
    long long vmc_datagrams = 0;
    // Over the last kLatencyWindow frames: frame out of the driver to VMC sent, and the
    // tracker's own share.
    double latency_median_ms = 0, latency_p95_ms = 0, track_ms_median = 0;
  };

  // Builds the tracker for `model` and the camera under `identity`, the take's buffer
  // (`max_take_frames` of room, reserved now) and the VMC sender (`vmc_target`, "" = off).
  // Returns where the identity came from. On failure the mode may still hold a tracker (as it
  // always did: a VMC target that does not resolve leaves tracking on without streaming).
  Result<std::string> start(const FaceModel& model, const CameraInfo& camera,
                            LandmarkDetector detector, TrackingIdentity identity,
                            const std::string& vmc_target, int max_take_frames,
                            std::int64_t take_session);
  bool active() const { return tracker_ != nullptr; }
  // Tracks one frame (`arrival`: when it left the camera driver): sends VMC, buffers the take,
  // publishes the live weights.
  Tick track(const RgbdFrame& frame, Clock::time_point arrival);
  Figures figures() const;
  const char* state() const;

  // The buffered take (null when not tracking) and the session it belongs to, for storing.
  TakeWriter* take() { return take_ ? &*take_ : nullptr; }
  std::int64_t take_session() const { return take_session_; }
  long long occluded_frames() const { return occlusion_log_.occluded_frames(); }
  // Frees the tracker, the detector, the sender and the take.
  void stop();

  const LiveWeights& live() const { return live_; }

 private:
  std::unique_ptr<FaceTracker> tracker_;
  std::unique_ptr<VmcSender> vmc_;
  std::optional<ArkitMapping> arkit_;
  std::optional<TakeWriter> take_;  // the tracked take, stored when tracking stops
  int max_take_frames_ = 0;
  std::int64_t take_session_ = 0;
  // Re-acquisition by detection: dlib on the colour image while the tracker has no face or
  // calibrates the identity (the fitter's shape predictor, shared); its pose seeds the ICP,
  // its points guide the calibration.
  std::optional<TrackLandmarkSource> reacquire_source_;
  bool face_before_ = false;    // the last tracked frame had the face
  OcclusionLog occlusion_log_;  // this run's occluded frames
  // track()'s per-frame times, a ring of the last kLatencyWindow (no allocation).
  static constexpr int kLatencyWindow = 300;
  std::array<float, kLatencyWindow> latency_ring_{}, track_ms_ring_{};
  long long latency_count_ = 0;
  TrackReport report_;
  ArkitFrame frame_;
  // The rig's wrinkle map weights (issue 40 item 5): c = P^T a per frame, one per detail
  // capture, keyed "EXPRESSION@CAPTURE" in the live JSON. Sized at start: no allocation per
  // frame. Empty when the rig has no detail captures.
  std::optional<MapWeights> map_weights_;
  std::vector<float> detail_values_;
  std::vector<std::string> detail_keys_;
  LiveWeights live_;
};

}  // namespace fb
