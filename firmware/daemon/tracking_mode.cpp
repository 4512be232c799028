#include "firmware/daemon/tracking_mode.hpp"

#include <algorithm>
#include <cstdio>

#include "algo/guide/guide_expressions.hpp"
#include "algo/tracking/rig_view.hpp"

namespace fb {
namespace {

// Tracks with the subject's rig from the host (their own neutral and blendshapes, FaceWarehouse
// 4.2), as `facebooth track --rig-from-store` does. Returns the status note, or why the rig
// cannot be used.
Result<std::string> track_with_rig(FaceTracker& tracker, const StoredRig& rig,
                                   const FaceModel& model, const ArkitMapping& arkit) {
  const TrackerRig view =
      tracker_rig_view(rig.data.neutral, rig.data.shape_names, rig.data.shapes, model, arkit);
  if (view.shapes.empty()) return fail("none of its shape names is a tracked blendshape");
  if (auto set = tracker.set_rig(view); !set) return set.failure();
  return "stored rig " + std::to_string(rig.id) + " of subject " + std::to_string(rig.subject) +
         " (" + std::to_string(view.shapes.size()) + " of its " +
         std::to_string(rig.data.shape_count()) + " shapes tracked)";
}

// The map weights of the rig's detail captures: their recipes from the guide, the live JSON's
// keys. Returns the status note's part ("" when the rig has none), or why there are none.
Result<std::string> build_map_weights(const StoredRig& rig, const std::vector<GuideStep>* guide,
                                      const FaceModel& model, std::optional<MapWeights>& weights,
                                      std::vector<std::string>& keys) {
  const auto& captures = rig.data.detail_captures;
  if (captures.empty()) return std::string();
  if (guide == nullptr) return fail("the booth's guide is not loaded");
  auto recipes = detail_capture_recipes(captures, *guide, model);
  if (!recipes) return recipes.failure();
  auto built = MapWeights::build(*recipes, model.fitting_expression_count);
  if (!built) return built.failure();
  weights = std::move(*built);
  std::string list;
  for (const auto& c : captures) {
    keys.push_back(c.expression + "@" + std::to_string(c.capture_index));
    list += (list.empty() ? "" : ", ") + keys.back();
  }
  return "; wrinkle map weights of " + std::to_string(captures.size()) + " captures (" + list + ")";
}

// The q-quantile of the first n values (a copy: the ring keeps its order).
template <std::size_t N>
double percentile_of(std::array<float, N> values, int n, double q) {
  if (n <= 0) return 0.0;
  const auto k = static_cast<std::ptrdiff_t>(q * (n - 1) + 0.5);
  std::nth_element(values.begin(), values.begin() + k, values.begin() + n);
  return values[static_cast<std::size_t>(k)];
}

}  // namespace

Result<std::vector<std::vector<float>>> detail_capture_recipes(
    std::span<const RigDetailCapture> captures, const std::vector<GuideStep>& guide,
    const FaceModel& model) {
  std::vector<std::vector<float>> out;
  for (const auto& c : captures) {
    const auto step = std::find_if(guide.begin(), guide.end(),
                                   [&](const GuideStep& g) { return g.name == c.expression; });
    const std::string which =
        "capture " + std::to_string(c.capture_index) + " ('" + c.expression + "')";
    if (step == guide.end())
      return fail(which +
                  " is not an expression of this booth's guide, so its recipe (the "
                  "weights its map weight inverts) is unknown; list only the guide's "
                  "expressions");
    if (step == guide.begin() || c.capture_index == 0)
      return fail(which +
                  " is the neutral: its maps are the base every frame adds to, not a "
                  "weighted capture; list only the expressions beside the neutral");
    GuideExpression g;
    g.name = step->name;
    g.weights = step->weights;
    auto w = guide_weights(g, model);
    if (!w) return w.failure();
    w->resize(static_cast<std::size_t>(model.fitting_expression_count));
    out.push_back(std::move(*w));
  }
  return out;
}

void LiveWeights::publish(const ArkitFrame& frame, const LiveDetailWeights& detail) {
  {
    std::lock_guard lock(mutex_);
    format_frame_json(frame, json_, detail);  // into the same string: no allocation per frame
    ++version_;
  }
  cv_.notify_all();
}

std::string LiveWeights::latest() const {
  std::lock_guard lock(mutex_);
  return json_;
}

std::string LiveWeights::wait_newer(std::uint64_t& seen, std::chrono::milliseconds timeout,
                                    const std::atomic<bool>& stopping) const {
  std::unique_lock lock(mutex_);
  cv_.wait_for(lock, timeout, [&] { return version_ != seen || stopping.load(); });
  if (version_ == seen || stopping) return {};
  seen = version_;
  return json_;
}

void LiveWeights::clear() {
  std::lock_guard lock(mutex_);
  json_.clear();  // keeps its capacity: the next run's frames still do not allocate
}

void LiveWeights::wake_all() const {
  { std::lock_guard lock(mutex_); }
  cv_.notify_all();
}

Result<std::string> TrackingMode::start(const FaceModel& model, const CameraInfo& camera,
                                        LandmarkDetector detector, TrackingIdentity identity,
                                        const std::string& vmc_target, int max_take_frames,
                                        std::int64_t take_session) {
  auto t = FaceTracker::create(model, camera.depth_intrinsics);
  if (!t) return t.failure();
  tracker_ = std::move(*t);
  auto mapping = make_arkit_mapping(model);
  if (!mapping) return mapping.failure();
  arkit_ = *mapping;
  std::vector<std::string> shape_names(kArkitNames.begin(), kArkitNames.end());
  take_.emplace(std::move(shape_names), camera.fps);
  // The whole take's room up front, so the frame loop does not grow it (the pages count only
  // once written).
  max_take_frames_ = max_take_frames;
  take_->reserve(max_take_frames);
  latency_count_ = 0;
  face_before_ = false;
  occlusion_log_ = OcclusionLog();
  reacquire_source_.emplace(std::move(detector), camera.calibration);
  take_session_ = take_session;
  std::string note;
  if (identity.rig) {
    // The subject's own rig wins over the quick neutral fit.
    auto rig_note = track_with_rig(*tracker_, *identity.rig, model, *arkit_);
    if (rig_note) {
      note = std::move(*rig_note);
    } else {
      std::fprintf(stderr, "faceboothd: stored rig %lld not used: %s\n",
                   static_cast<long long>(identity.rig->id), rig_note.error().message.c_str());
      identity.rig.reset();
    }
  }
  map_weights_.reset();
  detail_keys_.clear();
  if (identity.rig) {
    auto detail =
        build_map_weights(*identity.rig, identity.guide, model, map_weights_, detail_keys_);
    if (detail) {
      note += *detail;
    } else {
      // The rig still tracks; only the wrinkle weights are off.
      std::fprintf(stderr, "faceboothd: stored rig %lld: no wrinkle map weights: %s\n",
                   static_cast<long long>(identity.rig->id), detail.error().message.c_str());
      note += "; no wrinkle map weights (" + detail.error().message + ")";
      map_weights_.reset();
      detail_keys_.clear();
    }
  }
  detail_values_.assign(detail_keys_.size(), 0.0f);
  if (!identity.rig) {
    if (!identity.neutral.empty()) {
      note = "neutral fit of session " + std::to_string(identity.neutral_session);
      if (auto ok = tracker_->set_identity(identity.neutral); !ok) return ok.failure();
    } else {
      // No neutral fit yet: the tracker starts from the mean face and calibrates the identity
      // on its first frames.
      note = "mean face, calibrated on the first frames (no neutral fit yet)";
    }
  }
  vmc_.reset();
  if (!vmc_target.empty()) {
    auto dest = parse_osc_destination(vmc_target);
    if (!dest) return fail("[streaming] target '" + vmc_target + "': " + dest.error().message);
    auto sender = VmcSender::open(*dest);
    if (!sender) return sender.failure();
    vmc_ = std::move(*sender);
  }
  return note;
}

TrackingMode::Tick TrackingMode::track(const RgbdFrame& frame, Clock::time_point arrival) {
  Tick tick;
  // While the face is not found (start, after loss) the detector looks for it: its landmarks
  // give the tracker a pose to start from, not the nearest surface (a hand, the desk). While
  // the identity calibrates they guide it (depth alone lets hair and noise pull it off).
  // Tracked frames use depth alone.
  const TrackLandmarks* landmarks = nullptr;
  if (reacquire_source_ && (!face_before_ || !tracker_->calibrated()) &&
      reacquire_source_->detect(frame.color, frame.depth_mm).found) {
    landmarks = reacquire_source_->landmarks();
    tick.detected = true;
  }
  tracker_->track(frame.depth_mm, frame.depth_host_time_s, landmarks, report_);
  // Lost: the next detection searches the whole image, not around the last face.
  if (face_before_ && !report_.face_found && reacquire_source_) reacquire_source_->reset();
  face_before_ = report_.face_found;
  frame_.index = frame.index;
  frame_.time_s = frame.depth_host_time_s;
  frame_.face_found = report_.face_found;
  frame_.occluded = report_.occluded;
  frame_.occluded_fraction = report_.occluded_fraction;
  tick.occlusion_changed = occlusion_log_.add(report_.occluded) != OcclusionLog::Change::kNone;
  frame_.camera_from_model = report_.camera_from_model;
  arkit_->to_arkit(
      std::span<const float>(report_.weights.data(), static_cast<std::size_t>(report_.shape_count)),
      frame_.weights);
  if (vmc_) {
    if (auto sent = vmc_->send(frame_); !sent) tick.send_error = sent.error().message;
  }
  const auto slot = static_cast<std::size_t>(latency_count_++ % kLatencyWindow);
  latency_ring_[slot] = static_cast<float>(ms_since(arrival));
  track_ms_ring_[slot] = static_cast<float>(report_.times.total_ms());
  if (take_ && take_->frame_count() < max_take_frames_) {
    // 52 weights for 52 names: cannot fail.
    (void)take_->add_frame(frame_.time_s, frame_.camera_from_model, frame_.weights);
  }
  if (map_weights_) {
    map_weights_->apply(std::span<const float>(report_.weights.data(),
                                               static_cast<std::size_t>(report_.shape_count)),
                        detail_values_);
  }
  live_.publish(frame_, {detail_keys_, detail_values_});
  return tick;
}

const char* TrackingMode::state() const {
  return tracker_ ? to_string(report_.state) : "";
}

TrackingMode::Figures TrackingMode::figures() const {
  Figures f;
  f.state = state();
  f.reason = tracker_ ? report_.loss_reason : "";
  f.occluded = tracker_ && report_.occluded;
  f.hidden_fraction = tracker_ ? report_.occluded_fraction : 0.0;
  f.occluded_frames = occlusion_log_.occluded_frames();
  f.vmc_datagrams = vmc_ ? vmc_->datagrams_sent() : 0;
  const int n = static_cast<int>(std::min<long long>(latency_count_, kLatencyWindow));
  f.latency_median_ms = percentile_of(latency_ring_, n, 0.5);
  f.latency_p95_ms = percentile_of(latency_ring_, n, 0.95);
  f.track_ms_median = percentile_of(track_ms_ring_, n, 0.5);
  return f;
}

void TrackingMode::stop() {
  live_.clear();
  tracker_.reset();
  reacquire_source_.reset();
  vmc_.reset();
  take_.reset();
  map_weights_.reset();
}

}  // namespace fb
