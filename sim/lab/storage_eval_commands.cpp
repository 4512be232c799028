// facebooth-lab eval storage: crash trials (sim/crash), capture commit latency, export sizes and
// times for one synthetic subject. JSON on stdout, progress on stderr.
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>

#include "algo/core/clock.hpp"
#include "host/cli/export_summary.hpp"
#include "host/cli/scratch_directory.hpp"
#include "host/cli/stats.hpp"
#include "sim/crash/crash_trials.hpp"
#include "sim/lab/lab_commands.hpp"
#include "storage/asset_files.hpp"
#include "storage/durable_file.hpp"
#include "storage/export/export_folder.hpp"
#include "storage/export/export_session.hpp"
#include "storage/export/facewarehouse.hpp"
#include "storage/export/synthetic_subject.hpp"
#include "storage/session_store.hpp"

namespace fb::cli {
namespace {

namespace fs = std::filesystem;

// Capture commit latency at the real frame size: a head-turn capture of `frames` frames of
// 640x480 depth (mm), raw disparity and colour, plus the fused map and landmarks, committed
// `commits` times in a store under `scratch`; the figures go into `result`.
Result<void> time_capture_commits(const fs::path& scratch, long long commits, long long frames,
                                  nlohmann::json& result) {
  std::cerr << "eval storage: " << commits << " capture commits of " << frames
            << " 640x480 frames...\n";
  std::vector<double> commit_ms;
  std::uint64_t capture_bytes = 0;
  {
    auto store = SessionStore::open(scratch / "latency-store");
    if (!store) return store.failure();
    auto subject = store->add_subject("latency");
    if (!subject) return subject.failure();
    std::vector<std::string> guide;
    for (long long i = 0; i < commits; ++i) guide.push_back("pose_" + std::to_string(i));
    auto session = store->create_session(*subject, guide);
    if (!session) return session.failure();
    for (int i = 0; i < static_cast<int>(commits); ++i) {
      const CaptureInput input =
          make_test_capture(*session, i, static_cast<int>(frames), kKinectWidth, kKinectHeight);
      if (auto r = store->begin_capture(*session, i); !r) return r.failure();
      const auto t0 = Clock::now();
      if (auto r = store->commit_capture(*session, i, input); !r) return r.failure();
      commit_ms.push_back(seconds_since(t0) * 1000.0);
    }
    auto bytes = folder_bytes(store->session(*session)->folder);
    if (!bytes) return bytes.failure();
    capture_bytes = *bytes / static_cast<std::uint64_t>(commits);
    const auto t0 = Clock::now();
    auto data = store->read_capture(*session, 0);
    if (!data) return data.failure();
    result["capture_read_ms"] = seconds_since(t0) * 1000.0;
  }
  result["capture_commit_ms"] = percentile(commit_ms, 0.5);
  result["capture_commit_ms_p95"] = percentile(commit_ms, 0.95);
  result["capture_commit_ms_max"] = *std::max_element(commit_ms.begin(), commit_ms.end());
  result["capture_commits"] = commit_ms.size();
  result["capture_frames"] = frames;
  result["capture_bytes"] = capture_bytes;
  result["capture_commit_mb_per_s"] =
      static_cast<double>(capture_bytes) / 1e6 / (percentile(commit_ms, 0.5) / 1000.0);
  result["capture_commit_note"] =
      "frames file + fused depth written and fsynced, renamed, directory fsynced, then one "
      "synchronous=FULL SQLite commit; median over the commits";
  return success();
}

int run_eval_storage(const ParsedOptions& options) {
  auto trials = options.get_int("trials");
  auto commits = options.get_int("commits");
  auto frames = options.get_int("frames-per-capture");
  auto seed = options.get_int("seed");
  for (const auto* r : {&trials, &commits, &frames, &seed}) {
    if (!*r) return report_failure(r->error());
  }
  if (*trials < 0 || *commits < 1 || *frames < 1) {
    return report_failure({"--trials must be >= 0, --commits and --frames-per-capture >= 1"});
  }
  auto scratch = ScratchDirectory::create("facebooth-eval-storage-", options.get("scratch"),
                                          options.flag("keep"));
  if (!scratch) return report_failure(scratch.error());
  nlohmann::json result;
  result["scratch"] = scratch->path().string();

  // 1. SIGKILL crash trials.
  CrashTrialOptions crash;
  crash.root = scratch->path() / "crash-store";
  crash.trials = static_cast<int>(*trials);
  crash.seed = static_cast<std::uint64_t>(*seed);
  std::cerr << "eval storage: " << crash.trials << " SIGKILL crash trials...\n";
  auto start = Clock::now();
  auto report = run_crash_trials(crash);
  if (!report) return report_failure(report.error());
  result["crash_trials"] = report->trials;
  result["crash_trials_survived"] = report->survived;
  result["crash_trials_killed"] = report->killed;
  result["crash_killed_in_phase"] = report->killed_in_phase;
  result["crash_orphans_removed"] = report->orphans_removed;
  result["crash_captures_committed"] = report->captures_committed;
  result["crash_resumes_checked"] = report->resumes_checked;
  result["crash_max_kill_delay_ms"] = report->max_kill_delay_ms;
  result["crash_failures"] = report->failures;
  result["crash_s"] = seconds_since(start);
  for (const auto& f : report->failures) std::cerr << "  " << f << "\n";

  // 2. Capture commit latency at the real frame size.
  if (auto ok = time_capture_commits(scratch->path(), *commits, *frames, result); !ok)
    return report_failure(ok.error());

  // 3. One full subject: the face model with a random identity, 20 captures (640x480 colour),
  // the rig and 20 fitted meshes in a store; then every export format from that session.
  auto made = face_model_subject(options, static_cast<std::uint64_t>(*seed),
                                 "eval storage: building a synthetic subject from ");
  if (!made) return report_failure(made.error());
  const SyntheticSubject* subject = &made->subject;
  const fs::path store_root = scratch->path() / "subject-store";
  SessionId session = 0;
  {
    auto store = SessionStore::open(store_root);
    if (!store) return report_failure(store.error());
    SyntheticCaptureOptions capture;
    capture.width = kKinectWidth;
    capture.height = kKinectHeight;
    capture.frames_per_capture = 2;
    start = Clock::now();
    auto stored = store_synthetic_subject(*store, *subject, "synthetic", capture);
    if (!stored) return report_failure(stored.error());
    session = *stored;
    result["subject_store_s"] = seconds_since(start);
  }
  auto store_bytes = folder_bytes(store_root);
  if (!store_bytes) return report_failure(store_bytes.error());
  result["subject"] = {
      {"vertices", subject->rig.vertex_count()},   {"triangles", subject->rig.triangles.size() / 3},
      {"blendshapes", subject->rig.shape_count()}, {"poses", subject->poses.size()},
      {"captures", subject->poses.size()},         {"store_bytes", *store_bytes}};
  StoreOptions ro;
  ro.read_only = true;
  auto reader = SessionStore::open(store_root, ro);
  if (!reader) return report_failure(reader.error());
  start = Clock::now();
  auto content = load_session_content(*reader, session);
  if (!content) return report_failure(content.error());
  const double load_s = seconds_since(start);
  result["export_load_s"] = load_s;
  nlohmann::json exports;
  double export_total = load_s;
  for (auto format :
       {ExportFormat::kFaceWarehouse, ExportFormat::kGlb, ExportFormat::kObj, ExportFormat::kPly}) {
    std::cerr << "eval storage: export " << to_string(format) << "...\n";
    ExportRequest request;
    request.format = format;
    request.out = scratch->path() / "exports" / to_string(format);
    auto summary = export_content(*content, request);
    if (!summary) return report_failure(summary.error());
    exports[to_string(format)] = summary_json(*summary);
    export_total += summary->seconds;
  }
  result["exports"] = exports;
  result["export_s"] = export_total;
  result["export_s_note"] =
      "reading the session (rig, 20 meshes, 20 captures, checksums verified) plus writing all "
      "four formats (facewarehouse, glb, obj, ply) of one full subject";
  start = Clock::now();
  auto imported = import_facewarehouse(scratch->path() / "exports" / "facewarehouse");
  if (!imported) return report_failure(imported.error());
  result["facewarehouse_import_s"] = seconds_since(start);
  result["facewarehouse_import_exact"] =
      imported->size() == 1 && imported->front().rig.shapes == subject->rig.shapes &&
      imported->front().rig.neutral == subject->rig.neutral &&
      imported->front().poses.size() == subject->poses.size() &&
      imported->front().poses.back().positions == subject->poses.back().positions;

  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  result["peak_rss_mb"] = static_cast<double>(usage.ru_maxrss) / 1024.0;
  result["threads"] = 1;
  std::cout << result.dump(2) << std::endl;
  return report->survived == report->trials ? kExitOk : kExitFailure;
}

}  // namespace

std::vector<Command> storage_eval_commands() {
  return {
      {{"eval storage",
        "crash trials, capture commit latency, export sizes and times for one subject",
        "Prints one JSON object: crash_trials, crash_trials_survived (SIGKILL at random moments "
        "while a child commits captures), capture_commit_ms (median commit of a 640x480 "
        "capture), export_s (one full synthetic subject in all four formats) and details. "
        "Works in a scratch folder on the disk of --scratch, removed afterwards.",
        {{"trials", "N", "SIGKILL crash trials", "30"},
         {"commits", "N", "capture commits timed", "10"},
         {"frames-per-capture", "N", "640x480 frames per timed capture (a 1 s head turn)", "30"},
         {"seed", "N", "seed of the trials and the synthetic subject", "1"},
         {"face-model", "PATH", "face model (default: the installed one)", ""},
         {"scratch", "DIR", "parent folder of the scratch store (default: the temp folder)", ""},
         {"keep", "", "keep the scratch folder", ""},
         {"json", "", "print JSON (the only output format; accepted for symmetry)", ""}}},
       run_eval_storage},
  };
}

}  // namespace fb::cli
