#include "sim/crash/crash_trials.hpp"

#include <signal.h>
#include <sys/mman.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <functional>
#include <memory>
#include <optional>
#include <random>
#include <thread>

#include "algo/core/clock.hpp"

namespace fb {

namespace fs = std::filesystem;

namespace {

std::uint32_t mix(std::uint64_t x) {
  x ^= x >> 33;
  x *= 0xff51afd7ed558ccdULL;
  x ^= x >> 33;
  x *= 0xc4ceb9fe1a85ec53ULL;
  x ^= x >> 33;
  return static_cast<std::uint32_t>(x);
}

// What the child tells the parent, in memory shared across fork().
struct Shared {
  std::atomic<int> phase{0};
  std::atomic<std::int64_t> first_session{-1};  // first capture the child started in this run
  std::atomic<int> first_index{-1};
  std::atomic<std::int64_t> committed_session{-1};  // last capture whose commit returned
  std::atomic<int> committed_index{-1};
  std::atomic<int> child_error{0};
  char error_text[512] = {};
};

const char* phase_name(int phase) {
  switch (static_cast<StorePhase>(phase)) {
    case StorePhase::kIdle:
      return "idle_or_preparing";
    case StorePhase::kWritingFile:
      return "writing_file";
    case StorePhase::kSyncingFile:
      return "fsync_file";
    case StorePhase::kRenaming:
      return "rename_and_fsync_dir";
    case StorePhase::kCommitting:
      return "sqlite_commit";
  }
  return "opening";
}
constexpr int kPhaseOpening = 100;

std::vector<std::string> guide_names(int n) {
  std::vector<std::string> names;
  for (int i = 0; i < n; ++i) names.push_back("pose_" + std::to_string(i));
  return names;
}

// The newest session that is not complete, or a new one.
Result<SessionId> open_session(SessionStore& store, int guide_count) {
  auto sessions = store.sessions();
  if (!sessions) return sessions.failure();
  for (auto it = sessions->rbegin(); it != sessions->rend(); ++it) {
    if (!it->complete) return it->id;
  }
  auto subject = store.add_subject("crash-trial");
  if (!subject) return subject.failure();
  return store.create_session(*subject, guide_names(guide_count));
}

[[noreturn]] void child_main(const CrashTrialOptions& options, Shared* shared) {
  shared->phase = kPhaseOpening;
  StoreOptions store_options;
  store_options.on_phase = [shared](StorePhase p) { shared->phase = static_cast<int>(p); };
  auto store = SessionStore::open(options.root, store_options);
  auto die = [&](const Error& e) {
    std::snprintf(shared->error_text, sizeof shared->error_text, "%s", e.message.c_str());
    shared->child_error = 1;
    _exit(2);
  };
  if (!store) die(store.error());
  shared->phase = static_cast<int>(StorePhase::kIdle);
  bool first = true;
  for (;;) {
    auto session = open_session(*store, options.guide_count);
    if (!session) die(session.error());
    auto next = store->next_capture(*session);
    if (!next) die(next.error());
    if (!*next) continue;  // open_session creates a new one next time round
    const int index = (*next)->index;
    if (first) {
      shared->first_session = *session;
      shared->first_index = index;
      first = false;
    }
    if (auto r = store->begin_capture(*session, index); !r) die(r.error());
    const CaptureInput input = make_test_capture(*session, index, options.frames_per_capture,
                                                 options.width, options.height);
    if (auto r = store->commit_capture(*session, index, input); !r) die(r.error());
    shared->committed_session = *session;
    shared->committed_index = index;
  }
}

int count_files(const fs::path& dir, bool temporaries_only) {
  int n = 0;
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return 0;
  for (auto it = fs::recursive_directory_iterator(dir, ec);
       !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
    if (!it->is_regular_file(ec)) continue;
    const bool temp = it->path().filename().string().rfind(".tmp-", 0) == 0;
    if (!temporaries_only || temp) ++n;
  }
  return n;
}

// Mean time of one capture commit of the trial size, in a scratch store.
Result<double> calibrate(const CrashTrialOptions& options) {
  const fs::path scratch = options.root.string() + "-calibration";
  std::error_code ec;
  fs::remove_all(scratch, ec);
  double mean_ms = 0.0;
  {
    auto store = SessionStore::open(scratch);
    if (!store) return store.failure();
    auto subject = store->add_subject("calibration");
    if (!subject) return subject.failure();
    auto session = store->create_session(*subject, guide_names(3));
    if (!session) return session.failure();
    const auto start = Clock::now();
    for (int i = 0; i < 3; ++i) {
      if (auto r = store->begin_capture(*session, i); !r) return r.failure();
      auto input =
          make_test_capture(*session, i, options.frames_per_capture, options.width, options.height);
      if (auto r = store->commit_capture(*session, i, input); !r) return r.failure();
    }
    mean_ms = ms_since(start) / 3.0;
  }
  fs::remove_all(scratch, ec);
  return mean_ms;
}

// Where the next child must resume: the newest incomplete session's next capture.
struct ResumePoint {
  SessionId session = -1;
  int index = -1;
};

// Every session's done captures byte for byte, and its folder and completeness flag; returns
// the done captures counted (and sets `complete` to the completed sessions).
int check_sessions(const CrashTrialOptions& options, SessionStore& store,
                   const std::vector<SessionInfo>& sessions, int& complete,
                   std::vector<std::string>& problems) {
  int done_total = 0;
  for (const auto& s : sessions) {
    complete += s.complete ? 1 : 0;
    auto captures = store.captures(s.id);
    if (!captures) {
      problems.push_back(captures.error().message);
      continue;
    }
    int done = 0;
    for (const auto& c : *captures) {
      if (c.state != CaptureState::kDone) continue;
      ++done;
      auto data = store.read_capture(s.id, c.index);
      if (!data) {
        problems.push_back("committed capture unreadable: " + data.error().message);
        continue;
      }
      const std::string diff = compare_test_capture(
          *data, s.id, c.index, options.frames_per_capture, options.width, options.height);
      if (!diff.empty()) problems.push_back("capture " + std::to_string(c.index) + ": " + diff);
    }
    done_total += done;
    // Nothing half-written: exactly two data files (frames + fused depth) per done capture.
    const int files = count_files(s.folder, false);
    if (files != 2 * done) {
      problems.push_back("session " + std::to_string(s.id) + " folder holds " +
                         std::to_string(files) + " files for " + std::to_string(done) +
                         " done captures");
    }
    if (s.complete != (done == s.capture_count)) {
      problems.push_back("session completeness flag disagrees with its captures");
    }
  }
  return done_total;
}

// After a kill: reopens the store as the writer (migrations, orphan cleanup) and checks it,
// its sessions and the last commit that returned; sets where the next child must resume.
void check_reopened_store(const CrashTrialOptions& options, const Shared& shared,
                          CrashTrialReport& report, ResumePoint& expected,
                          std::vector<std::string>& problems) {
  auto store = SessionStore::open(options.root);
  if (!store) {
    problems.push_back("reopen failed: " + store.error().message);
    return;
  }
  report.orphans_removed += store->orphans_removed();
  auto verified = store->verify();
  if (!verified) {
    problems.push_back("verify failed: " + verified.error().message);
  } else if (!verified->ok()) {
    problems.push_back("verify: integrity " + verified->integrity +
                       (verified->problems.empty() ? "" : ", " + verified->problems[0]));
  }
  if (const int temps = count_files(options.root, true); temps > 0) {
    problems.push_back(std::to_string(temps) + " temporary files survived the cleanup");
  }
  auto sessions = store->sessions();
  int done_total = 0, complete = 0;
  if (!sessions) {
    problems.push_back(sessions.error().message);
  } else {
    done_total = check_sessions(options, *store, *sessions, complete, problems);
  }
  // A commit that returned must have survived the kill.
  if (shared.committed_session >= 0) {
    auto c = store->capture(shared.committed_session, shared.committed_index);
    if (!c || c->state != CaptureState::kDone) {
      problems.push_back("a capture whose commit returned is not done after the kill");
    }
  }
  expected = ResumePoint{};
  if (sessions) {
    for (auto it = sessions->rbegin(); it != sessions->rend(); ++it) {
      if (it->complete) continue;
      auto next = store->next_capture(it->id);
      if (next && *next) expected = {it->id, (*next)->index};
      break;
    }
  }
  report.captures_committed = done_total;
  report.sessions_completed = complete;
}

}  // namespace

CaptureInput make_test_capture(SessionId session, int index, int frames, int width, int height) {
  CaptureInput input;
  const std::uint64_t base =
      (static_cast<std::uint64_t>(session) << 32) ^ (static_cast<std::uint64_t>(index) << 16);
  for (int f = 0; f < frames; ++f) {
    RgbdFrame frame;
    frame.index = static_cast<std::uint64_t>(f);
    frame.depth_host_time_s = 100.0 + f / 30.0;
    frame.color_host_time_s = 100.0 + f / 30.0 + 0.001;
    frame.depth_device_timestamp = mix(base + f);
    frame.color_device_timestamp = mix(base + f + 7);
    frame.depth_mm.resize(width, height);
    frame.raw_disparity.resize(width, height);
    frame.color.resize(width, height);
    const std::uint64_t seed = base ^ (static_cast<std::uint64_t>(f) << 8);
    for (std::size_t i = 0; i < frame.depth_mm.pixels.size(); ++i) {
      const std::uint32_t h = mix(seed + i);
      frame.depth_mm.pixels[i] = static_cast<std::uint16_t>(500 + (h & 0x3ff));
      frame.raw_disparity.pixels[i] = static_cast<std::uint16_t>((h >> 10) & 0x7ff);
      frame.color.pixels[i] = {static_cast<std::uint8_t>(h >> 21),
                               static_cast<std::uint8_t>(h >> 8), static_cast<std::uint8_t>(h)};
    }
    input.frames.push_back(std::move(frame));
  }
  input.fused_depth.resize(width, height);
  for (std::size_t i = 0; i < input.fused_depth.pixels.size(); ++i) {
    input.fused_depth.pixels[i] = static_cast<std::uint16_t>(600 + (mix(base + 99 + i) & 0xff));
  }
  for (int k = 0; k < 68; ++k) {
    Landmark p;
    p.u = static_cast<float>(100 + k);
    p.v = static_cast<float>(200 + (mix(base + k) & 0x3f));
    p.has_3d = k >= 17;
    if (p.has_3d) p.x = 1.5f * k, p.y = -2.0f * k, p.z = 600.0f + k;
    input.landmarks.push_back(p);
  }
  input.qa_scores = {{"coverage", 0.5 + 0.01 * index}, {"session", static_cast<double>(session)}};
  return input;
}

std::string compare_test_capture(const CaptureData& data, SessionId session, int index, int frames,
                                 int width, int height) {
  const CaptureInput want = make_test_capture(session, index, frames, width, height);
  if (data.frames.size() != want.frames.size()) return "frame count differs";
  for (std::size_t f = 0; f < want.frames.size(); ++f) {
    const auto& a = data.frames[f];
    const auto& b = want.frames[f];
    if (a.index != b.index || a.depth_host_time_s != b.depth_host_time_s ||
        a.color_device_timestamp != b.color_device_timestamp) {
      return "frame " + std::to_string(f) + " metadata differs";
    }
    if (a.depth_mm.pixels != b.depth_mm.pixels || a.raw_disparity.pixels != b.raw_disparity.pixels)
      return "frame " + std::to_string(f) + " depth differs";
    if (a.color.width != b.color.width || std::memcmp(a.color.pixels.data(), b.color.pixels.data(),
                                                      b.color.pixels.size() * sizeof(Rgb8)) != 0) {
      return "frame " + std::to_string(f) + " colour differs";
    }
  }
  if (data.fused_depth.pixels != want.fused_depth.pixels) return "fused depth differs";
  if (data.landmarks.size() != want.landmarks.size()) return "landmark count differs";
  for (std::size_t k = 0; k < want.landmarks.size(); ++k) {
    if (data.landmarks[k].v != want.landmarks[k].v ||
        data.landmarks[k].has_3d != want.landmarks[k].has_3d) {
      return "landmark " + std::to_string(k) + " differs";
    }
  }
  if (data.info.qa_scores != want.qa_scores) return "QA scores differ";
  return {};
}

Result<CrashTrialReport> run_crash_trials(const CrashTrialOptions& options) {
  CrashTrialReport report;
  auto capture_ms = calibrate(options);
  if (!capture_ms) return capture_ms.failure();
  report.capture_commit_ms = *capture_ms;
  report.max_kill_delay_ms =
      options.max_kill_delay_ms > 0 ? options.max_kill_delay_ms : 10.0 + 3.0 * *capture_ms;

  // Shared with the children; unmapped when this scope ends.
  void* mapping =
      ::mmap(nullptr, sizeof(Shared), PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0);
  if (mapping == MAP_FAILED) return fail("cannot map memory for the crash trials");
  const std::unique_ptr<void, std::function<void(void*)>> unmap(
      mapping, [](void* p) { ::munmap(p, sizeof(Shared)); });

  std::mt19937_64 rng(options.seed);
  std::uniform_real_distribution<double> delay(0.0, report.max_kill_delay_ms);
  // Where the next child must start (session -1: no open session, the child creates one).
  ResumePoint expected;

  for (int trial = 0; trial < options.trials; ++trial) {
    auto* shared = new (mapping) Shared();
    const pid_t pid = ::fork();
    if (pid < 0) return fail("fork failed for crash trial " + std::to_string(trial));
    if (pid == 0) {
      try {
        child_main(options, shared);
      } catch (...) {
        _exit(3);
      }
    }
    std::this_thread::sleep_for(std::chrono::duration<double, std::milli>(delay(rng)));
    const int phase_at_kill = shared->phase.load();
    ::kill(pid, SIGKILL);
    int status = 0;
    ::waitpid(pid, &status, 0);
    ++report.trials;
    std::vector<std::string> problems;
    const std::string prefix = "trial " + std::to_string(trial) + ": ";
    if (WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) {
      ++report.killed;
      ++report.killed_in_phase[phase_at_kill == kPhaseOpening ? "opening"
                                                              : phase_name(phase_at_kill)];
    } else {
      problems.push_back("child exited on its own: " + std::string(shared->error_text));
    }
    // Resume: the child's first capture must be the one the store said was next.
    if (expected.session >= 0 && shared->first_session >= 0) {
      if (shared->first_session != expected.session || shared->first_index != expected.index) {
        problems.push_back("resumed at session " + std::to_string(shared->first_session) +
                           " capture " + std::to_string(shared->first_index) + ", expected " +
                           std::to_string(expected.session) + "/" + std::to_string(expected.index));
      } else {
        ++report.resumes_checked;
      }
    }

    // Reopen as the writer: migrations, orphan cleanup; then every check of the store.
    check_reopened_store(options, *shared, report, expected, problems);
    if (problems.empty()) {
      ++report.survived;
    } else {
      for (const auto& p : problems) report.failures.push_back(prefix + p);
    }
    shared->~Shared();
  }
  return report;
}

}  // namespace fb
