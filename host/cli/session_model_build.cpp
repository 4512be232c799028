#include "host/cli/session_model_build.hpp"

#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <vector>

#include "algo/bilinear/bootstrap.hpp"
#include "algo/bilinear/streaming_decomposition.hpp"
#include "algo/core/clock.hpp"
#include "host/cli/progress.hpp"
#include "storage/session_store.hpp"

namespace fb::cli {
namespace {

// The rigs a build uses: one per subject, found without reading any rig's data.
struct RigList {
  std::vector<SessionId> used, skipped;
  std::vector<RigId> rigs;
  std::vector<bool> verified;  // SHA-256 checked in this build
  int vertex_count = 0;
  std::vector<std::string> shape_names;
};

Result<std::vector<SessionId>> wanted_sessions(const SessionStore& store, const std::string& list) {
  std::vector<SessionId> wanted;
  if (list.empty() || list == "all") {
    auto all = store.sessions();
    if (!all) return all.failure();
    for (const auto& s : *all) wanted.push_back(s.id);
    return wanted;
  }
  std::stringstream ss(list);
  std::string item;
  while (std::getline(ss, item, ',')) {
    try {
      wanted.push_back(std::stoll(item));
    } catch (...) {
      return fail("--sessions: '" + item + "' is not a session id (give ids like 1,2,5 or all)");
    }
  }
  return wanted;
}

Result<RigList> list_rigs(const SessionStore& store, const std::string& session_list) {
  auto wanted = wanted_sessions(store, session_list);
  if (!wanted) return wanted.failure();
  RigList out;
  for (SessionId sid : *wanted) {
    auto serving = store.rig_for(sid);
    if (!serving) return serving.failure();
    // The rig serving the session, unless another session of the subject built it (that
    // session counts it; a subject is one identity of the tensor, not one per session).
    if (!*serving || ((*serving)->session && *(*serving)->session != sid)) {
      out.skipped.push_back(sid);
      continue;
    }
    const RigInfo& r = **serving;
    if (!out.rigs.empty() &&
        (r.vertex_count != out.vertex_count || r.shape_names != out.shape_names))
      return fail("session " + std::to_string(sid) +
                  ": its rig has another vertex count or other blendshapes than the first rig; "
                  "a tensor needs the same topology and shapes for every subject");
    out.vertex_count = r.vertex_count;
    out.shape_names = r.shape_names;
    out.rigs.push_back(r.id);
    out.verified.push_back(false);
    out.used.push_back(sid);
  }
  if (out.rigs.size() < 2)
    return fail("model build: " + std::to_string(out.rigs.size()) +
                " rigged session(s) found; a tensor needs at least 2 (rig sessions with "
                "`facebooth rig --store DIR --session ID --save`)");
  return out;
}

// Identity i's expressions as the accumulators take them: the neutral, then every shape. Each
// rig's SHA-256 is checked at its first read of the build (a software hash of 7.3 MB is ~35 ms
// here, and the streamed build reads each rig 2-4 times); later reads check the size.
Result<void> read_identity(const SessionStore& store, RigList& list, int i,
                           std::vector<float>& slices, std::vector<std::uint32_t>* triangles) {
  const auto k = static_cast<std::size_t>(i);
  auto rig = store.read_rig(list.rigs[k], !list.verified[k]);
  if (rig) list.verified[k] = true;
  if (!rig) return rig.failure();
  if (rig->vertex_count() != list.vertex_count || rig->shapes.size() != list.shape_names.size())
    return fail("session " + std::to_string(list.used[static_cast<std::size_t>(i)]) +
                ": its rig file does not match its database row (vertex or shape count); check "
                "the store with `facebooth store info --verify`");
  const std::size_t rows = rig->neutral.size();
  slices.resize(rows * (1 + rig->shapes.size()));
  std::copy(rig->neutral.begin(), rig->neutral.end(), slices.begin());
  for (std::size_t e = 0; e < rig->shapes.size(); ++e)
    std::copy(rig->shapes[e].begin(), rig->shapes[e].end(),
              slices.begin() + static_cast<std::ptrdiff_t>((e + 1) * rows));
  if (triangles) *triangles = std::move(rig->triangles);
  return success();
}

struct Built {
  TruncatedTensor truncated;
  std::vector<std::uint32_t> triangles;
  long long rig_reads = 0;
  double read_s = 0;  // reading, checking and decoding rigs (the rest is arithmetic)
  int passes = 0;
  int panel = 0;
};

Result<Built> build_in_memory(const SessionStore& store, RigList& list,
                              const SessionModelOptions& o) {
  DataTensor t;
  t.rows = 3 * list.vertex_count;
  t.identities = static_cast<int>(list.rigs.size());
  t.expressions = 1 + static_cast<int>(list.shape_names.size());
  t.data.resize(static_cast<std::size_t>(t.rows) * t.identities * t.expressions);
  Built b;
  std::vector<float> slices;
  std::optional<Progress> bar;
  if (o.progress) bar.emplace("model build: reading rigs", t.identities);
  for (int i = 0; i < t.identities; ++i) {
    const auto tr = Clock::now();
    if (auto ok = read_identity(store, list, i, slices, i == 0 ? &b.triangles : nullptr); !ok)
      return ok.failure();
    b.read_s += seconds_since(tr);
    for (int e = 0; e < t.expressions; ++e)
      std::copy_n(slices.begin() + static_cast<std::ptrdiff_t>(e) * t.rows, t.rows,
                  t.data.begin() + (static_cast<std::ptrdiff_t>(e) * t.identities + i) * t.rows);
    if (bar) bar->update(i + 1);
  }
  bar.reset();
  b.rig_reads = t.identities;
  auto factors = mode_factors(t);
  if (!factors) return factors.failure();
  auto truncated = truncate(t, *factors, o.id_knobs, std::min(o.exp_knobs, t.expressions));
  if (!truncated) return fail("model build: " + truncated.error().message);
  b.truncated = std::move(*truncated);
  return b;
}

Result<Built> build_streaming(const SessionStore& store, RigList& list,
                              const SessionModelOptions& o) {
  const StreamShape shape{3 * list.vertex_count, static_cast<int>(list.rigs.size()),
                          1 + static_cast<int>(list.shape_names.size())};
  Built b;
  b.panel = panel_for_memory(shape, o.memory_mb << 20);
  auto gram = GramAccumulator::create(shape, b.panel);
  if (!gram) return gram.failure();
  b.passes = gram->passes();
  // Reads: each pass its panel and the identities before it, then one pass for the core.
  long long total = shape.identities;
  for (int p = 0; p < b.passes; ++p) total += std::min(shape.identities, (p + 1) * b.panel);
  std::optional<Progress> bar;
  if (o.progress)
    bar.emplace("model build: " + std::to_string(b.passes) + " Gram pass(es) + core, rigs read",
                total);
  std::vector<float> slices;
  for (int i; (i = gram->next_identity()) >= 0;) {
    const auto tr = Clock::now();
    if (auto ok = read_identity(store, list, i, slices, nullptr); !ok) return ok.failure();
    b.read_s += seconds_since(tr);
    if (auto ok = gram->add(i, slices); !ok) return fail("model build: " + ok.error().message);
    if (bar) bar->update(++b.rig_reads);
  }
  auto factors = gram->factors();
  if (!factors) return fail("model build: " + factors.error().message);
  auto core = CoreAccumulator::create(shape, *factors, o.id_knobs,
                                      std::min(o.exp_knobs, shape.expressions));
  if (!core) return fail("model build: " + core.error().message);
  for (int i = 0; i < shape.identities; ++i) {
    const auto tr = Clock::now();
    if (auto ok = read_identity(store, list, i, slices, i == 0 ? &b.triangles : nullptr); !ok)
      return ok.failure();
    b.read_s += seconds_since(tr);
    if (auto ok = core->add(i, slices); !ok) return fail("model build: " + ok.error().message);
    if (bar) bar->update(++b.rig_reads);
  }
  auto truncated = core->finish();
  if (!truncated) return fail("model build: " + truncated.error().message);
  b.truncated = std::move(*truncated);
  return b;
}

}  // namespace

Result<BuiltModel> build_from_sessions(const FaceModel& face_model, const SessionModelOptions& o) {
  if (o.memory_mb < 16) return fail("--memory-mb must be at least 16");
  StoreOptions so;
  so.read_only = true;
  so.create = false;
  auto store = SessionStore::open(o.store, so);
  if (!store) return store.failure();
  const auto t0 = Clock::now();
  auto list = list_rigs(*store, o.sessions);
  if (!list) return list.failure();
  const int identities = static_cast<int>(list->rigs.size());
  if (o.id_knobs > identities)
    return fail("model build: only " + std::to_string(identities) +
                " rigged subjects; pass --id-knobs " + std::to_string(identities) + " or fewer");
  auto built = o.in_memory ? build_in_memory(*store, *list, o) : build_streaming(*store, *list, o);
  if (!built) return built.failure();
  std::vector<std::string> names{"neutral"};
  for (const auto& n : list->shape_names) names.push_back(n);
  BuiltModel b;
  b.info = {
      {"source", "session store rigs"}, {"store", std::filesystem::absolute(o.store).string()},
      {"sessions", list->used},         {"sessions_without_rig", list->skipped},
      {"identities", identities},       {"expressions", static_cast<int>(names.size())},
      {"id_knobs", o.id_knobs},         {"exp_knobs", built->truncated.exp_knobs},
      {"rig_reads", built->rig_reads},  {"rig_read_s", built->read_s}};
  if (o.in_memory) {
    b.info["tensor"] = "dense, in memory";
  } else {
    b.info["tensor"] = "streamed: Gram matrices accumulated one subject at a time, then the core";
    b.info["gram_passes"] = built->passes;
    b.info["panel_identities"] = built->panel;
    b.info["memory_mb"] = o.memory_mb;
  }
  FaceModel topology = face_model;
  if (!built->triangles.empty()) topology.triangles = built->triangles;
  b.model = make_bilinear_model(built->truncated, topology, names, b.info.dump());
  b.build_s = seconds_since(t0);
  return b;
}

}  // namespace fb::cli
