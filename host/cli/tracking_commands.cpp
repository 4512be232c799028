// facebooth track: the real-time tracker run live on any camera (freenect, OpenNI2, replay,
// synthetic): identity calibration on the first frames or the subject's stored rig, VMC over
// OSC/UDP, Live Link Face CSV, the kiosk's SSE events, and the take recorded in a session store.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <numeric>
#include <optional>
#include <random>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "algo/core/clock.hpp"
#include "algo/tracking/arkit.hpp"
#include "algo/tracking/detected_landmarks.hpp"
#include "algo/tracking/face_tracker.hpp"
#include "algo/tracking/occlusion_report.hpp"
#include "algo/tracking/rig_view.hpp"
#include "firmware/streaming/live_json.hpp"
#include "firmware/streaming/vmc_sender.hpp"
#include "host/cli/commands.hpp"
#include "host/cli/detail_weights.hpp"
#include "host/cli/frame_open.hpp"
#include "host/cli/progress.hpp"
#include "host/cli/stats.hpp"
#include "host/cli/track_drive.hpp"
#include "host/cli/tracker_setup.hpp"
#include "storage/asset_files.hpp"
#include "storage/export/livelink_csv.hpp"
#include "storage/session_store.hpp"
#include "storage/take_writer.hpp"

namespace fb::cli {
namespace {

// Noise on --landmarks truth, as on the lab's takes (sim/subject/synthetic_take.hpp).
constexpr double kTruthLandmarkNoisePx = 1.5;

// The stored rig serving the take (SessionStore::rig_for with --session, else the subject's
// newest) as a TrackerRig over the model's fitting shapes (matched by the model's expression
// names or the ARKit names of one-to-one curves). nullopt: no rig.
struct LoadedRig {
  RigId id = 0;
  std::optional<SessionId> session;  // the session that built the rig, if any
  RigData data;
  int matched = 0;
  TrackerRig view;
};
Result<std::optional<LoadedRig>> load_stored_rig(const SessionStore& store, SubjectId subject,
                                                 std::optional<SessionId> session,
                                                 const FaceModel& model,
                                                 const ArkitMapping& mapping) {
  auto serving = session ? store.rig_for(*session) : store.newest_rig(subject);
  if (!serving) return serving.failure();
  if (!*serving) return std::optional<LoadedRig>{};
  LoadedRig out;
  out.id = (*serving)->id;
  out.session = (*serving)->session;
  auto data = store.read_rig(out.id);
  if (!data) return data.failure();
  out.data = std::move(*data);
  if (out.data.vertex_count() != model.vertex_count) {
    return fail("rig " + std::to_string(out.id) + " of subject " + std::to_string(subject) +
                " has " + std::to_string(out.data.vertex_count()) + " vertices, the face model " +
                std::to_string(model.vertex_count) +
                "; the tracker needs a rig in the face model's topology (drop --rig-from-store "
                "to calibrate the identity instead)");
  }
  out.view =
      tracker_rig_view(out.data.neutral, out.data.shape_names, out.data.shapes, model, mapping);
  out.matched = static_cast<int>(out.view.shapes.size());
  return std::optional<LoadedRig>(std::move(out));
}

// Why `track` ended without a calibrated subject, and what to do.
std::string never_calibrated_message(int needed, long long frames, long long with_face, int most,
                                     int rejected_sets, const std::string& rejection,
                                     const std::string& last_reason) {
  std::string why;
  if (rejected_sets > 0) {
    why = "a full set of " + std::to_string(needed) + " calibration frames was rejected " +
          (rejected_sets == 1 ? std::string("once") : std::to_string(rejected_sets) + " times") +
          " (" + rejection + ")";
  } else {
    why = "only " + std::to_string(most) + " of the " + std::to_string(needed) +
          " calibration frames came in (the face was found on " + std::to_string(with_face) +
          " of " + std::to_string(frames) + " frames" +
          (last_reason.empty() ? "" : "; last: " + last_reason) + ")";
  }
  return "track: the subject never calibrated, so no weights of this face were tracked: " + why +
         ". Give a take with the face in view for at least " + std::to_string(needed) +
         " frames in a row (face the camera, neutral, still), or lower --calibration-frames";
}

// The calibrated subject as a rig in the face model's topology: the fitted neutral and, per
// fitting shape, the neutral plus the subject's delta (`source`'s, e.g. the bilinear model's
// C x2 w x3 (u_e - u_0), else the model's generic one). Tracking with it needs no calibration.
RigData calibrated_rig(const FaceModel& face, std::span<const float> identity,
                       const SubjectBlendshapes* source) {
  const auto size = static_cast<std::size_t>(3 * face.vertex_count);
  const int k = face.fitting_expression_count;
  RigData rig;
  rig.neutral.resize(size);
  face.evaluate(identity, {}, rig.neutral);
  // The model's deltas of the fitting shapes (expression_basis is column-major, 3V per shape).
  std::vector<float> deltas(face.expression_basis.begin(),
                            face.expression_basis.begin() +
                                static_cast<std::ptrdiff_t>(size * static_cast<std::size_t>(k)));
  if (source != nullptr) {
    std::vector<std::uint32_t> every(static_cast<std::size_t>(face.vertex_count));
    std::iota(every.begin(), every.end(), 0u);
    source->subject_deltas(identity, every, deltas);
  }
  for (int j = 0; j < k; ++j) {
    std::vector<float> shape(rig.neutral);
    for (std::size_t c = 0; c < size; ++c)
      shape[c] += deltas[static_cast<std::size_t>(j) * size + c];
    rig.shapes.push_back(std::move(shape));
    rig.shape_names.push_back(face.expression_names[static_cast<std::size_t>(j)]);
  }
  rig.triangles = face.triangles;
  return rig;
}

// Where the take goes (--store, --subject, --session) and whether a stored rig is used or kept.
struct TrackStore {
  std::string path;
  bool rig_from_store = false;
  bool save_rig = false;
  std::optional<SessionStore> store;
  std::optional<SubjectId> subject;
  std::optional<SessionId> session;
};

// Storage: takes go to --store (a new subject unless --subject names one); --rig-from-store
// tracks with the subject's newest stored rig instead of calibrating an identity.
Result<TrackStore> open_track_store(const ParsedOptions& options) {
  TrackStore t;
  t.path = options.get("store");
  t.rig_from_store = options.flag("rig-from-store");
  if (!options.get("session").empty()) {
    auto id = options.get_int("session");
    if (!id || *id <= 0) return fail("--session must be a session id (see `facebooth store info`)");
    if (!options.get("subject").empty())
      return fail("give --session or --subject, not both (a session names its subject)");
    t.session = *id;
  }
  if (!options.get("subject").empty()) {
    auto id = options.get_int("subject");
    if (!id || *id <= 0) return fail("--subject must be a subject id (see `facebooth store info`)");
    t.subject = *id;
  }
  if ((t.subject || t.session || t.rig_from_store) && t.path.empty()) {
    return fail("--subject, --session and --rig-from-store need --store DIR");
  }
  if (t.rig_from_store && !t.subject && !t.session) {
    return fail("--rig-from-store needs --session ID or --subject ID (whose rig to load)");
  }
  t.save_rig = options.flag("save-rig");
  if (t.save_rig && t.path.empty()) {
    return fail("--save-rig needs --store DIR (where to keep the subject's rig)");
  }
  if (t.save_rig && t.rig_from_store) {
    return fail(
        "--save-rig stores a calibrated subject; with --rig-from-store "
        "nothing is calibrated (drop one of them)");
  }
  if (t.path.empty()) return t;
  auto opened = SessionStore::open(t.path);
  if (!opened) return opened.failure();
  t.store.emplace(std::move(*opened));
  if (t.session) {
    auto known = t.store->session(*t.session);
    if (!known) {
      return fail("there is no session " + std::to_string(*t.session) + " in " + t.path +
                  " (see `facebooth store info --store " + t.path + "`)");
    }
    t.subject = known->subject;
  } else if (t.subject) {
    if (auto known = t.store->subject(*t.subject); !known) {
      return fail("there is no subject " + std::to_string(*t.subject) + " in " + t.path +
                  " (see `facebooth store info --store " + t.path +
                  "`), or omit --subject to record under a new subject");
    }
  }
  return t;
}

// One run of track: what it sends and records, and what it counts for the summary.
struct TrackRun {
  std::string landmark_source, reacquire;
  TruthLandmarks truth_landmarks_of = nullptr;
  const ArkitMapping* mapping = nullptr;
  FaceTracker* tracker = nullptr;
  int calibration_frames = 0;
  bool recording = false;  // a store takes the take
  std::optional<TakeWriter> take;
  std::optional<TrackLandmarkSource> detector;
  std::string reacquire_note = "depth only (nearest surface, last pose)";
  std::unique_ptr<VmcSender> sender;
  std::optional<LiveLinkCsvWriter> csv;
  bool csv_started = false;
  bool print_sse = false;
  // --detail-weights: the session's wrinkle maps blended per frame (issue 40 item 5); the file
  // gets each frame's map weights, one per captured expression with detail.
  std::optional<SessionDetailBlend> detail;
  std::optional<DetailWeightsCsv> detail_csv;
  std::vector<float> map_weights;
  std::optional<RigDrive> drive;  // --drive: another subject's rig, a mesh per frame

  std::mt19937_64 rng{1};
  std::normal_distribution<float> noise{0.0f, static_cast<float>(kTruthLandmarkNoisePx)};
  std::vector<Eigen::Vector2f> landmark_points = std::vector<Eigen::Vector2f>(68);
  TrackReport report;
  ArkitFrame out;
  std::string sse;

  std::vector<double> landmark_ms, latency, cost;
  long long detections = 0, detection_misses = 0;
  bool face_before = false;
  long long read = 0, found = 0, lost_reports = 0;
  std::string last_reason;  // the tracker's loss reason on the previous frame
  // Why a take never calibrated: the most calibration frames that came in, and the full sets
  // the tracker rejected (it starts over with a loss reason saying why).
  int most_calibration_frames = 0, rejected_sets = 0;
  std::string rejection;
  OcclusionLog occlusion;
  std::map<std::string, long long> states;
  std::string stop_reason = "end of stream";
  bool camera_failed = false;

  std::string never_calibrated() const {
    return never_calibrated_message(calibration_frames, read, found, most_calibration_frames,
                                    rejected_sets, rejection, last_reason);
  }
};

// dlib on the colour image: every frame (--landmarks dlib) and/or while the face is searched
// for (--reacquire dlib: detection gives the tracker a starting pose after loss, not the
// nearest surface, which a hand, a desk or the chest can be) and while the identity
// calibrates (depth alone lets hair and noise pull the calibration off). Then the VMC sender
// (--osc) and the Live Link CSV (--csv).
Result<void> open_outputs(const ParsedOptions& options, const CameraInfo& info, TrackRun& t) {
  if (t.landmark_source == "dlib" || t.reacquire == "dlib") {
    auto loaded = load_landmark_detector(options.get("shape-predictor"));
    if (loaded) {
      t.detector.emplace(std::move(*loaded), info.calibration);
      t.reacquire_note = t.reacquire == "dlib" ? "dlib detection on the colour image, then depth"
                                               : t.reacquire_note;
    } else if (t.landmark_source == "dlib") {
      return loaded.failure();
    } else {
      std::cerr << "track: " << loaded.error().message << "; re-acquiring from depth only\n";
    }
  }
  if (!options.get("osc").empty()) {
    auto destination = parse_osc_destination(options.get("osc"));
    if (!destination) return destination.failure();
    auto opened = VmcSender::open(*destination);
    if (!opened) return opened.failure();
    t.sender = std::move(*opened);
  }
  if (!options.get("csv").empty()) {
    auto opened = LiveLinkCsvWriter::open(options.get("csv"), info.fps > 0 ? info.fps : 30.0);
    if (!opened) return opened.failure();
    t.csv.emplace(std::move(*opened));
  }
  t.print_sse = options.flag("sse");
  return success();
}

// --detail-weights FILE: the session's wrinkle detail maps (from `facebooth wrinkles`) and the
// CSV their per-frame weights go to.
Result<void> open_detail_weights(const ParsedOptions& options, const TrackStore& where,
                                 const FaceModel& model, TrackRun& t) {
  const std::string file = options.get("detail-weights");
  if (file.empty()) return success();
  if (!where.store || !where.session)
    return fail(
        "--detail-weights needs --store DIR and --session ID (the session whose wrinkle "
        "detail, from `facebooth wrinkles`, the weights blend)");
  auto guide = load_guide_expressions(model);
  if (!guide) return guide.failure();
  auto loaded = load_session_detail_blend(*where.store, *where.session, model, *guide);
  if (!loaded) return loaded.failure();
  for (const auto& why : loaded->skipped) std::cerr << "track: detail weights: " << why << "\n";
  auto opened = DetailWeightsCsv::open(file, *loaded);
  if (!opened) return opened.failure();
  t.detail.emplace(std::move(*loaded));
  t.detail_csv.emplace(std::move(*opened));
  t.map_weights.resize(t.detail->captures.size());
  return success();
}

// What the track's JSON says of the detail weights it wrote.
nlohmann::json detail_weights_json(const TrackRun& t, const std::string& file) {
  nlohmann::json layers = nlohmann::json::array();
  for (std::size_t e = 0; e < t.detail->captures.size(); ++e)
    layers.push_back(
        {{"capture", t.detail->captures[e]}, {"expression", t.detail->expressions[e]}});
  return {{"file", file},
          {"neutral_capture", t.detail->neutral_capture},
          {"layers", layers},
          {"skipped", t.detail->skipped},
          {"meaning", detail_weights_description()}};
}

// The frame's 2D landmarks: the truth plus noise (--landmarks truth) and/or dlib's; null when
// there are none. `truth` holds the truth's.
const TrackLandmarks* frame_landmarks(TrackRun& t, const DepthCamera& camera,
                                      const RgbdFrame& frame, TrackLandmarks& truth) {
  const TrackLandmarks* landmarks = nullptr;
  if (t.landmark_source == "truth") {
    if (const auto* truth_px = t.truth_landmarks_of(camera)) {
      for (int l = 0; l < 68; ++l) {
        t.landmark_points[static_cast<std::size_t>(l)] =
            (*truth_px)[static_cast<std::size_t>(l)].cast<float>() +
            Eigen::Vector2f(t.noise(t.rng), t.noise(t.rng));
      }
      truth.points = t.landmark_points;
      landmarks = &truth;
    }
  }
  const bool reacquiring = t.reacquire == "dlib" && (!t.face_before || !t.tracker->calibrated());
  if (t.detector && (t.landmark_source == "dlib" || reacquiring)) {
    const LandmarkFrameResult found = t.detector->detect(frame.color, frame.depth_mm);
    t.landmark_ms.push_back(found.ms);
    if (found.found) {
      ++t.detections;
      landmarks = t.detector->landmarks();
    } else {
      ++t.detection_misses;
    }
  }
  return landmarks;
}

// The tracked frame out: VMC, the CSV row, the take's frame, the SSE event.
Result<void> emit_frame(TrackRun& t, Clock::time_point arrival) {
  if (t.sender) {
    if (auto sent = t.sender->send(t.out); !sent) {
      std::cerr << "facebooth: " << sent.error().message << "\n";
    }
  }
  t.latency.push_back(ms_since(arrival));
  t.cost.push_back(t.report.times.total_ms());
  if (t.csv) {
    // The Timecode is the time of day (as the app writes it): the first row's is now.
    if (!t.csv_started) {
      t.csv->set_start_of_day_s(local_time_of_day_s(std::chrono::system_clock::now()) -
                                t.out.time_s);
      t.csv_started = true;
    }
    if (auto r = t.csv->append(to_livelink_row(t.out)); !r) return r.failure();
  }
  if (t.recording) {
    if (auto r = t.take->add_frame(t.out.time_s, t.out.camera_from_model, t.out.weights); !r)
      return r.failure();
  }
  if (t.detail_csv) {
    t.detail->blend.map_weights(
        std::span<const float>(t.report.weights.data(),
                               static_cast<std::size_t>(t.report.shape_count)),
        t.map_weights);
    if (auto r = t.detail_csv->append(static_cast<long long>(t.out.index), t.out.time_s,
                                      t.out.face_found, t.map_weights);
        !r)
      return r.failure();
  }
  if (t.drive) {
    if (auto r = drive_frame(*t.drive, t.out); !r) return r.failure();
  }
  if (t.print_sse) {
    format_sse_event(t.out, t.sse);
    std::cerr << t.sse;
  }
  return success();
}

// Counts the frame's report and says on stderr what changed (loss, search, occlusion).
void log_report(TrackRun& t, const RgbdFrame& frame) {
  const TrackReport& report = t.report;
  ++t.read;
  if (report.face_found) ++t.found;
  if (report.state == TrackState::kLost) {
    ++t.lost_reports;
    std::cerr << "track: frame " << frame.index << ": face lost (" << report.loss_reason << ")\n";
  } else if (report.state == TrackState::kSearching && *report.loss_reason &&
             t.last_reason != report.loss_reason) {
    // Once per reason: "no face found" every frame of an empty room says nothing new.
    std::cerr << "track: frame " << frame.index << ": searching (" << report.loss_reason << ")\n";
  }
  if (report.state == TrackState::kCalibrating)
    t.most_calibration_frames =
        std::max(t.most_calibration_frames, t.calibration_frames - report.calibration_frames_left);
  if (!report.face_found && std::string_view(report.loss_reason).starts_with("calibration")) {
    ++t.rejected_sets;
    t.rejection = report.loss_reason;
  }
  t.last_reason = report.loss_reason;
  switch (t.occlusion.add(report.occluded)) {
    case OcclusionLog::Change::kOccluded:
      std::cerr << "track: frame " << frame.index << ": face occluded ("
                << std::lround(100.0 * report.occluded_fraction) << " % of it hidden)\n";
      break;
    case OcclusionLog::Change::kClear:
      std::cerr << "track: frame " << frame.index << ": face clear again\n";
      break;
    case OcclusionLog::Change::kNone:
      break;
  }
  ++t.states[to_string(report.state)];
}

// Tracks the camera's frames until the stream ends, `max_frames` are read (0: no limit) or
// the camera fails (stop_reason says which).
Result<void> track_frames(TrackRun& t, DepthCamera& camera, long long max_frames,
                          Progress& progress) {
  RgbdFrame frame;
  long long timeouts_in_row = 0;
  while (max_frames <= 0 || t.read < max_frames) {
    auto status = camera.next_frame(frame, std::chrono::milliseconds(1000));
    if (!status) {
      t.stop_reason = "camera error: " + status.error().message;
      t.camera_failed = true;
      break;
    }
    if (*status == FrameStatus::kEndOfStream) break;
    if (*status == FrameStatus::kTimeout) {
      if (++timeouts_in_row >= 5) {
        t.stop_reason = "the camera stopped delivering frames (5 s without a frame)";
        t.camera_failed = true;
        break;
      }
      continue;
    }
    timeouts_in_row = 0;
    const auto arrival = Clock::now();
    TrackLandmarks truth_landmarks;
    const TrackLandmarks* landmarks = frame_landmarks(t, camera, frame, truth_landmarks);
    t.tracker->track(frame.depth_mm, frame.depth_host_time_s, landmarks, t.report);
    t.face_before = t.report.face_found;
    t.out.index = frame.index;
    t.out.time_s = frame.depth_host_time_s;
    t.out.face_found = t.report.face_found;
    t.out.occluded = t.report.occluded;
    t.out.occluded_fraction = t.report.occluded_fraction;
    t.out.camera_from_model = t.report.camera_from_model;
    t.mapping->to_arkit(std::span<const float>(t.report.weights.data(),
                                               static_cast<std::size_t>(t.report.shape_count)),
                        t.out.weights);
    if (auto r = emit_frame(t, arrival); !r) return r.failure();
    log_report(t, frame);
    progress.update(t.read);
  }
  return success();
}

// The summary's figures of the run (what was tracked, how fast, what went where).
void summary_json(const TrackRun& t, const std::string& uri, double seconds,
                  nlohmann::json& result) {
  result["camera"] = uri;
  result["frames"] = t.read;
  result["frames_with_face"] = t.found;
  result["loss_reports"] = t.lost_reports;
  result["occluded_frames"] = t.occlusion.occluded_frames();
  result["states"] = t.states;
  result["calibrated"] = t.tracker->calibrated();
  result["stopped"] = t.stop_reason;
  result["fps"] = seconds > 0 ? static_cast<double>(t.read) / seconds : 0.0;
  result["ms_per_frame"] = stats_of(t.cost).mean;
  result["latency_ms"] = to_json(stats_of(t.latency));
  result["landmarks"] =
      t.landmark_source == "truth"  ? "ground truth + N(0, 1.5 px) (synthetic camera only)"
      : t.landmark_source == "dlib" ? "dlib HOG + shape_predictor_68 on the colour image"
                                    : "none (depth only)";
  result["reacquire"] = t.reacquire_note;
  if (t.detector) {
    result["detections"] = t.detections;
    result["detection_misses"] = t.detection_misses;
    result["landmark_ms"] = to_json(stats_of(t.landmark_ms));
  }
  if (t.sender) {
    result["osc"] = t.sender->options().host + ":" + std::to_string(t.sender->options().port);
    result["osc_datagrams"] = t.sender->datagrams_sent();
    result["osc_messages"] = t.sender->messages_sent();
  }
}

// After the take: stores it (a new subject unless one was named) and, with --save-rig, the
// calibrated subject as a rig; their ids go into `result`.
Result<void> store_results(TrackStore& where, TrackRun& t, const FaceModel& tracker_model,
                           const BilinearSubjectModel* bilinear, nlohmann::json& result) {
  if (where.store && t.take->frame_count() > 0) {
    if (!where.subject) {
      auto added = where.store->add_subject("tracking take");
      if (!added) return added.failure();
      where.subject = *added;
    }
    auto id = t.take->store(*where.store, *where.subject, where.session);
    if (!id) return id.failure();
    result["take"] = *id;
    result["subject"] = *where.subject;
    result["session"] = where.session ? nlohmann::json(*where.session) : nlohmann::json(nullptr);
    std::cerr << "track: stored take " << *id << " (" << t.take->frame_count()
              << " frames; the face was "
              << "occluded on " << t.occlusion.occluded_frames() << ")\n";
    result["store"] = where.path;
  } else if (where.store) {
    result["take"] = nullptr;  // no frame: nothing to store
  }
  if (!where.save_rig) return success();
  // Only a subject the tracker calibrated itself (a stored rig loaded instead was refused
  // above, and one that fell back to calibration for want of a rig is calibrated here).
  if (!t.tracker->calibrated() || !where.subject) {
    std::cout << result.dump(2) << std::endl;
    return fail(t.never_calibrated() + "; --save-rig stored no rig");
  }
  const RigData saved = calibrated_rig(tracker_model, t.tracker->identity(),
                                       bilinear ? &*bilinear->blendshapes : nullptr);
  auto id = where.store->add_rig(*where.subject, std::nullopt, saved);
  if (!id) return id.failure();
  result["rig"] = *id;
  result["subject"] = *where.subject;
  std::cerr << "track: stored the calibrated subject as rig " << *id << " of subject "
            << *where.subject << " (" << saved.shape_count() << " shapes); track with it: "
            << "--store " << where.path << " --subject " << *where.subject << " --rig-from-store\n";
  return success();
}

int run_track(const ParsedOptions& options, TruthLandmarks truth_landmarks_of) {
  const std::string uri = options.get("camera");
  if (uri.empty())
    return report_failure({"--camera URI is required (see `facebooth camera list`)"});
  auto max_frames = options.get_int("frames");
  if (!max_frames) return report_failure(max_frames.error());
  auto calibration = options.get_int("calibration-frames");
  if (!calibration || *calibration < 1)
    return report_failure({"--calibration-frames must be >= 1"});
  TrackRun t;
  t.landmark_source = options.get("landmarks");
  if (t.landmark_source != "truth" && t.landmark_source != "none" && t.landmark_source != "dlib") {
    return report_failure({"--landmarks must be dlib, truth or none"});
  }
  if (t.landmark_source == "truth" && truth_landmarks_of == nullptr) {
    return report_failure(
        {"--landmarks truth needs the laboratory's ground truth: run it as "
         "`facebooth-lab track` (synthetic camera), or use dlib or none"});
  }
  t.truth_landmarks_of = truth_landmarks_of;
  t.reacquire = options.get("reacquire");
  if (t.reacquire != "dlib" && t.reacquire != "depth") {
    return report_failure({"--reacquire must be dlib or depth"});
  }
  auto model_result = load_face_model();
  if (!model_result) return report_failure(model_result.error());
  const FaceModel& model = *model_result;
  auto mapping = make_arkit_mapping(model);
  if (!mapping) return report_failure(mapping.error());
  t.mapping = &*mapping;

  auto where = open_track_store(options);
  if (!where) return report_failure(where.error());
  std::optional<LoadedRig> rig;
  if (where->rig_from_store) {
    auto loaded = load_stored_rig(*where->store, *where->subject, where->session, model, *mapping);
    if (!loaded) return report_failure(loaded.error());
    rig = std::move(*loaded);
    // A take tracked with a session's rig belongs to that session (issue 37).
    if (rig && !where->session) where->session = rig->session;
  }

  auto camera = open_started_camera(uri);
  if (!camera) return report_failure(camera.error());
  const CameraInfo info = (*camera)->info();
  TrackerOptions tracker_options;
  tracker_options.calibration.calibration_frames = static_cast<int>(*calibration);
  t.calibration_frames = tracker_options.calibration.calibration_frames;
  // --model: calibrate in a bilinear model's identity space and track with the subject's own
  // blendshapes from it (a stored rig, when loaded, still takes precedence).
  std::unique_ptr<BilinearSubjectModel> bilinear;
  if (const std::string file = options.get("model"); !file.empty()) {
    auto loaded = load_bilinear_subject_model(file, model, "track");
    if (!loaded) return report_failure(loaded.error());
    bilinear = std::move(*loaded);
  }
  const FaceModel& tracker_model = bilinear ? bilinear->tracking.face : model;
  auto tracker = FaceTracker::create(tracker_model, info.depth_intrinsics, tracker_options);
  if (!tracker) return report_failure(tracker.error());
  t.tracker = tracker->get();
  if (bilinear) t.tracker->set_subject_blendshapes(&*bilinear->blendshapes);
  std::string subject_model = bilinear ? "identity calibrated on the first frames with the " +
                                             bilinear->describe() +
                                             ", the subject's own blendshapes from it"
                                       : "identity calibrated on the first frames";
  if (rig) {
    if (auto r = t.tracker->set_rig(rig->view); !r) return report_failure(r.error());
    subject_model =
        "stored rig " + std::to_string(rig->id) + " (" + std::to_string(rig->matched) + " shapes)";
  } else if (where->rig_from_store) {
    subject_model =
        "subject " + std::to_string(*where->subject) + " has no stored rig: " + subject_model;
  }
  // The take as the store keeps it (storage/take_writer.hpp): the streamed pose, the 52 ARKit
  // curves under their camelCase names, each frame's camera time.
  t.take.emplace(std::vector<std::string>(kArkitNames.begin(), kArkitNames.end()),
                 info.fps > 0 ? info.fps : 30.0);
  t.recording = where->store.has_value();
  if (auto ok = open_outputs(options, info, t); !ok) return report_failure(ok.error());
  if (auto ok = open_detail_weights(options, *where, model, t); !ok)
    return report_failure(ok.error());
  if (const std::string to = options.get("drive"); !to.empty()) {
    if (!where->store) return report_failure({"--drive needs --store (where the rig is)"});
    auto drive =
        open_rig_drive(*where->store, to, options.get("drive-out"), options.get("drive-format"));
    if (!drive) return report_failure(drive.error());
    t.drive = std::move(*drive);
  }

  const long long total = *max_frames > 0 ? *max_frames : info.frame_count;
  Progress progress("track", total > 0 ? total : 0);
  const auto t0 = Clock::now();
  if (auto ok = track_frames(t, **camera, *max_frames, progress); !ok)
    return report_failure(ok.error());
  (*camera)->stop();
  if (t.csv) {
    if (auto r = t.csv->close(); !r) return report_failure(r.error());
  }
  if (t.detail_csv) {
    if (auto r = t.detail_csv->close(); !r) return report_failure(r.error());
  }
  const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  nlohmann::json result;
  if (auto ok = store_results(*where, t, tracker_model, bilinear.get(), result); !ok)
    return report_failure(ok.error());
  result["subject_model"] = subject_model;
  summary_json(t, uri, seconds, result);
  if (t.csv) result["csv"] = options.get("csv");
  if (t.detail) result["detail_weights"] = detail_weights_json(t, options.get("detail-weights"));
  if (t.drive)
    result["drive"] = {
        {"rig", t.drive->rig_id}, {"frames", t.drive->written}, {"out", t.drive->dir.string()}};
  std::cout << result.dump(2) << std::endl;
  if (!t.camera_failed && !t.tracker->calibrated()) {
    // Weights from an uncalibrated mean face are not this subject's: a failure, said plainly.
    return report_failure({t.never_calibrated()});
  }
  return t.camera_failed ? kExitFailure : kExitOk;
}

}  // namespace

std::vector<Command> tracking_commands(TruthLandmarks truth_landmarks) {
  return {
      {{"track",
        "run the tracker live on a camera; stream VMC over OSC and/or record Live Link CSV",
        "Calibrates the identity on the first frames (hold a neutral face) with the face "
        "model, or with a bilinear model (--model; for tracking build it with --exp-knobs 54), "
        "or loads the subject's stored rig (--rig-from-store), then tracks. Prints a JSON "
        "summary at the end (with --store: the stored take's id; with --save-rig: the rig's); "
        "loss of the face is reported on stderr and tracking resumes when the face is found "
        "again.",
        {{"camera", "URI", "camera URI, e.g. synthetic:frames=300 or freenect:0", ""},
         {"osc", "HOST:PORT", "send VMC (OSC/UDP) here; port 39539 if omitted", ""},
         {"csv", "FILE", "record a Live Link Face CSV take", ""},
         {"store", "DIR",
          "record the take in this session store (export it with `facebooth "
          "export --take ID --store DIR --out OUT`)",
          ""},
         {"subject", "ID", "store the take under this subject (default: a new subject)", ""},
         {"session", "ID",
          "store the take under this session (and its subject); with --rig-from-store, track "
          "with the rig serving the session (the newest built from it, else the subject's)",
          ""},
         {"rig-from-store", "",
          "track with the stored rig serving --session (or --subject's newest rig; face model "
          "topology) instead of calibrating, and record the rig's session with the take; falls "
          "back to calibration when the subject has no rig",
          ""},
         {"save-rig", "",
          "after the take, store the calibrated subject in --store as their rig (fitted neutral "
          "and blendshapes: the bilinear model's with --model, else the generic ones), which "
          "--rig-from-store and the device's tracking mode then use without calibrating",
          ""},
         {"frames", "N", "stop after N frames (0 = until the stream ends)", "0"},
         {"calibration-frames", "N", "frames for the identity fit", "10"},
         {"model", "FILE",
          "calibrate with this bilinear model (`facebooth model build`; FaceWarehouse 4.3) and "
          "track with the subject's own blendshapes from it, instead of the face model's "
          "identity PCA and generic blendshapes",
          ""},
         {"landmarks", "dlib|truth|none",
          "2D landmarks in the weight solve: dlib on the colour image every frame, ground truth "
          "+ noise (synthetic camera only), or none",
          "none"},
         {"reacquire", "dlib|depth",
          "finding the face at the start and after loss: dlib detection on the colour image, "
          "whose points also guide the identity calibration (falls back to depth when the "
          "model is missing), or depth only",
          "dlib"},
         {"shape-predictor", "PATH", "dlib 68-point model", kShapePredictor},
         {"drive", "subject:ID",
          "drive another subject's stored rig (subject:ID, session:ID) with the tracked weights",
          ""},
         {"drive-out", "DIR", "--drive writes DIR/frame_INDEX.obj (or .ply) per frame", ""},
         {"drive-format", "F", "obj or ply", "obj"},
         {"sse", "", "also print the kiosk's SSE events to stderr", ""},
         {"detail-weights", "FILE",
          "write each frame's wrinkle map weights (CSV: one column per captured expression "
          "with detail) for --session's maps from `facebooth wrinkles`; the frame's detail is "
          "N + sum c_e (D_e - N) (docs/wrinkles.md)",
          ""}}},
       [truth_landmarks](const ParsedOptions& o) { return run_track(o, truth_landmarks); }}};
}

}  // namespace fb::cli
