// facebooth-lab bench model (issue 38, item 4): `facebooth model build --from-sessions` on a
// real store of --subjects synthetic subjects' rigs, run as the product runs it (a child
// process: its own model_build_s, its peak RSS from wait4), beside the in-memory build
// (`--in-memory`, the build before streaming) on the first --peer-subjects of the same store,
// streamed and in memory, so the ratio is on the same input in the same run.
#include <fcntl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <iostream>
#include <random>

#include <nlohmann/json.hpp>

#include "algo/bilinear/bilinear_model.hpp"
#include "algo/core/clock.hpp"
#include "host/cli/command_line.hpp"
#include "host/cli/scratch_directory.hpp"
#include "sim/lab/lab_commands.hpp"
#include "sim/subject/synthetic_rigs.hpp"
#include "storage/asset_files.hpp"
#include "storage/session_store.hpp"

namespace fb::cli {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

fs::path facebooth_binary(const std::string& given) {
  if (!given.empty()) return given;
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  for (const fs::path& p : {self.parent_path() / "../host/cli/facebooth",
                            self.parent_path() / "facebooth", fs::path("/usr/bin/facebooth")})
    if (fs::exists(p, ec)) return fs::weakly_canonical(p, ec);
  return {};
}

Result<double> make_store(const FaceModel& m, const fs::path& dir, int subjects) {
  const auto t0 = Clock::now();
  auto store = SessionStore::open(dir);
  if (!store) return store.failure();
  for (int i = 0; i < subjects; ++i) {
    if (auto r = add_synthetic_rig_subject(*store, m, "synthetic " + std::to_string(i + 1),
                                           1000 + static_cast<std::uint64_t>(i));
        !r)
      return r.failure();
    if ((i + 1) % 50 == 0 || i + 1 == subjects)
      std::cerr << "bench model: store " << i + 1 << "/" << subjects << " rigs\n";
  }
  return seconds_since(t0);
}

struct Measured {
  json result;
  double peak_rss_mb = 0;
  double wall_s = 0;
};

// Runs the facebooth binary with `args`; stdout parsed as JSON, stderr left on ours.
Result<Measured> run_measured(const fs::path& exe, const std::vector<std::string>& args) {
  int out[2];
  if (::pipe(out) != 0) return fail("pipe failed");
  const auto t0 = Clock::now();
  const pid_t pid = ::fork();
  if (pid < 0) return fail("fork failed");
  if (pid == 0) {
    ::dup2(out[1], STDOUT_FILENO);
    ::close(out[0]);
    ::close(out[1]);
    std::vector<char*> argv{const_cast<char*>(exe.c_str())};
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    ::execv(exe.c_str(), argv.data());
    std::_Exit(127);
  }
  ::close(out[1]);
  std::string text;
  char buf[4096];
  for (ssize_t n; (n = ::read(out[0], buf, sizeof buf)) > 0;)
    text.append(buf, static_cast<std::size_t>(n));
  ::close(out[0]);
  int status = 0;
  rusage usage{};
  ::wait4(pid, &status, 0, &usage);
  Measured m;
  m.wall_s = seconds_since(t0);
  m.peak_rss_mb = static_cast<double>(usage.ru_maxrss) / 1024.0;
  m.result = json::parse(text, nullptr, false);
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0 || m.result.is_discarded())
    return fail("facebooth " + args.front() + " " + args[1] + " failed (its stderr says why)");
  return m;
}

// Max |reconstruction difference| of the training slices of two models, relative to max |slice|.
Result<double> model_difference(const fs::path& a, const fs::path& b) {
  auto ra = read_file_bytes(a);
  auto rb = read_file_bytes(b);
  if (!ra || !rb) return fail("cannot read the built models");
  auto ma = parse_bilinear_model(std::as_bytes(std::span(*ra)));
  auto mb = parse_bilinear_model(std::as_bytes(std::span(*rb)));
  if (!ma || !mb) return fail("a built model does not parse");
  std::vector<float> va(static_cast<std::size_t>(ma->coordinate_count())), vb(va.size());
  double worst = 0, scale = 0;
  for (int i = 0; i < ma->identity_count; i += 7)
    for (int e = 0; e < ma->expression_count; e += 5) {
      ma->evaluate(ma->identity_row(i), ma->expression_row(e), va);
      mb->evaluate(mb->identity_row(i), mb->expression_row(e), vb);
      for (std::size_t k = 0; k < va.size(); ++k) {
        worst = std::max(worst, static_cast<double>(std::abs(va[k] - vb[k])));
        scale = std::max(scale, static_cast<double>(std::abs(va[k])));
      }
    }
  return worst / scale;
}

std::string id_list(int n) {
  std::string s;
  for (int i = 1; i <= n; ++i) s += (i > 1 ? "," : "") + std::to_string(i);
  return s;
}

int bench_model(const ParsedOptions& o) {
  const fs::path exe = facebooth_binary(o.get("facebooth"));
  if (exe.empty())
    return report_failure(
        {"facebooth not found next to facebooth-lab, in the build tree or in "
         "/usr/bin; pass --facebooth"});
  auto subjects = o.get_int("subjects");
  auto peer_subjects = o.get_int("peer-subjects");
  auto memory_mb = o.get_int("memory-mb");
  if (!subjects || !peer_subjects || !memory_mb || *subjects < 50 || *peer_subjects < 50 ||
      *peer_subjects > *subjects)
    return report_failure(
        {"--subjects >= 50, --peer-subjects 50..subjects (the build keeps 50 identity knobs)"});
  auto model = load_face_model();
  if (!model) return report_failure(model.error());
  auto scratch = ScratchDirectory::create("facebooth-bench-model-", o.get("scratch"));
  if (!scratch) return report_failure(scratch.error());
  const fs::path store = scratch->path() / "store";
  auto made = make_store(*model, store, static_cast<int>(*subjects));
  if (!made) return report_failure(made.error());
  auto build = [&](const std::string& name, int n, bool in_memory) -> Result<Measured> {
    std::cerr << "bench model: " << name << "\n";
    std::vector<std::string> args{"model",
                                  "build",
                                  "--from-sessions",
                                  "--store",
                                  store.string(),
                                  "--memory-mb",
                                  std::to_string(*memory_mb),
                                  "--out",
                                  (scratch->path() / (name + ".fbbm")).string()};
    if (n < *subjects) args.insert(args.end(), {"--sessions", id_list(n)});
    if (in_memory) args.push_back("--in-memory");
    return run_measured(exe, args);
  };
  auto full = build("streamed-all", static_cast<int>(*subjects), false);
  if (!full) return report_failure(full.error());
  auto streamed = build("streamed-peer", static_cast<int>(*peer_subjects), false);
  if (!streamed) return report_failure(streamed.error());
  auto dense = build("in-memory-peer", static_cast<int>(*peer_subjects), true);
  if (!dense) return report_failure(dense.error());
  auto diff = model_difference(scratch->path() / "streamed-peer.fbbm",
                               scratch->path() / "in-memory-peer.fbbm");
  if (!diff) return report_failure(diff.error());
  const double build_s = full->result["model_build_s"].get<double>();
  const double s_peer = streamed->result["model_build_s"].get<double>();
  const double d_peer = dense->result["model_build_s"].get<double>();
  json out = {
      {"subjects", *subjects},
      {"store_rigs_gb", static_cast<double>(*subjects) * 54 * model->vertex_count * 3 * 4 / 1e9},
      {"store_build_s", *made},
      {"model_build_s", build_s},
      {"model_build_budget_s", 120},
      {"peak_rss_mb", full->peak_rss_mb},
      {"peak_rss_budget_mb", 2048},
      {"gram_passes", full->result["gram_passes"]},
      {"rig_reads", full->result["rig_reads"]},
      {"rig_read_s", full->result["rig_read_s"]},
      {"memory_mb", *memory_mb},
      {"peer",
       "the in-memory build (facebooth model build --from-sessions --in-memory: every "
       "rig stacked in one dense tensor), on the first peer_subjects of the same store"},
      {"peer_subjects", *peer_subjects},
      {"streamed_at_peer_subjects_s", s_peer},
      {"streamed_at_peer_subjects_rss_mb", streamed->peak_rss_mb},
      {"in_memory_at_peer_subjects_s", d_peer},
      {"in_memory_at_peer_subjects_rss_mb", dense->peak_rss_mb},
      {"streamed_vs_in_memory_time", d_peer > 0 ? s_peer / d_peer : 0.0},
      {"streamed_vs_in_memory_rss", streamed->peak_rss_mb / dense->peak_rss_mb},
      {"streamed_vs_in_memory_max_relative_difference", *diff},
      {"note",
       "model_build_s is the command's own figure (store opened to model built, 50 x 25 knobs; "
       "without the face model load and the model file write); peak_rss_mb is the whole "
       "process's (wait4 ru_maxrss), writing the model file included. The store is written "
       "first (store_build_s, not counted); the rigs are in the page cache."}};
  std::cout << out.dump(2) << "\n";
  return kExitOk;
}

}  // namespace

Command bench_model_command() {
  return {{"bench model",
           "model build --from-sessions over a store of synthetic subjects: time, peak memory, "
           "beside the in-memory build",
           "Writes --subjects synthetic subjects' rigs (face-model identities, each fitting shape "
           "at its own amplitude) into a real session store, then runs `facebooth model build "
           "--from-sessions` on all of them (model_build_s, peak_rss_mb), and on the first "
           "--peer-subjects both streamed and --in-memory (the peer), and compares the two "
           "models.",
           {{"json", "", "print the JSON result (always on)", ""},
            {"facebooth", "PATH", "the facebooth binary", ""},
            {"subjects", "N", "synthetic subjects in the store", "300"},
            {"peer-subjects", "N", "subjects of the side-by-side run", "60"},
            {"memory-mb", "MB", "the streaming build's --memory-mb", "1024"},
            {"scratch", "DIR", "where the store is written (default: the temp folder)", ""}}},
          &bench_model};
}

}  // namespace fb::cli
