// facebooth-lab bench transfer: VTC's factorization and per-expression solve on a ~19K-vertex
// target (the paper's size), beside the project's deformation transfer (algo/fitting
// ExpressionTransfer) on the same meshes in the same run.
#include <algorithm>
#include <array>
#include <iostream>

#include <nlohmann/json.hpp>

#include "algo/core/clock.hpp"
#include "algo/fitting/expression_transfer.hpp"
#include "algo/transfer/correspondence.hpp"
#include "algo/transfer/expression_set.hpp"
#include "algo/transfer/vtc_transfer.hpp"
#include "host/cli/guide_files.hpp"
#include "host/cli/rig_support.hpp"
#include "host/cli/stats.hpp"
#include "sim/lab/lab_commands.hpp"
#include "sim/lab/transfer_image_lab.hpp"
#include "sim/subject/remesh.hpp"
#include "storage/asset_files.hpp"

namespace fb::cli {
namespace {

struct Inputs {
  FaceModel dt_model;  // the face model re-topologised, for ExpressionTransfer
  Points source_neutral, target_neutral;
  std::vector<Points> expressions;
};

Inputs make_inputs(const FaceModel& model, const Remesh& r, int expressions) {
  Inputs in;
  const Points s0 = points_from_floats(face(model, identity_draw(1, model.identity_count), {}));
  in.source_neutral = r.apply(s0);
  in.target_neutral =
      r.apply(points_from_floats(face(model, identity_draw(2, model.identity_count), {})));
  for (int j = 0; j < expressions; ++j)
    in.expressions.push_back(r.apply(s0 + points_from_floats(model.expression_shape(j))));
  // Metadata, fitting and rigid vertex lists keep their (old, still valid) indices.
  in.dt_model = model;
  in.dt_model.vertex_count = r.vertex_count();
  in.dt_model.triangles = r.triangles;
  in.dt_model.neutral = floats_from_points(r.apply(points_from_floats(model.neutral)));
  in.dt_model.identity_basis.clear();
  in.dt_model.expression_basis.clear();
  in.dt_model.uvs.clear();
  in.dt_model.triangle_uvs.clear();
  return in;
}

struct Timing {
  Samples factor_ms, per_expression_ms;
  long long factor_nonzeros = 0;
};

Result<void> time_vtc(const Inputs& in, const TentTopology& topology, Timing& t) {
  auto source = VtcSource::create(topology, in.source_neutral);
  if (!source) return source.failure();
  auto target = VtcTarget::create(topology, in.target_neutral);
  if (!target) return target.failure();
  t.factor_ms.add(target->factor_ms());
  t.factor_nonzeros = target->factor_nonzeros();
  const auto t0 = Clock::now();
  for (const Points& e : in.expressions)
    if (auto out = vtc_transfer(*source, *target, e); !out) return out.failure();
  t.per_expression_ms.add(ms_since(t0) / static_cast<double>(in.expressions.size()));
  return success();
}

Result<void> time_dt(const Inputs& in, Timing& t) {
  const auto t0 = Clock::now();
  auto dt = ExpressionTransfer::create(in.dt_model, floats_from_points(in.target_neutral),
                                       floats_from_points(in.source_neutral));
  if (!dt) return dt.failure();
  t.factor_ms.add(ms_since(t0));
  std::vector<std::vector<float>> floats;
  for (const Points& e : in.expressions) floats.push_back(floats_from_points(e));
  const auto t1 = Clock::now();
  for (const auto& e : floats)
    if (auto out = dt->transfer(e); !out) return out.failure();
  t.per_expression_ms.add(ms_since(t1) / static_cast<double>(floats.size()));
  return success();
}

// Section V's correspondence from the model's topology onto the split target.
Result<double> time_correspondence(const FaceModel& model, const Inputs& in, const Remesh& r) {
  const Points source = in.source_neutral.topRows(model.vertex_count);
  Points source_features(68, 3), target_features(68, 3);
  for (int l = 0; l < 68; ++l) {
    const auto v = model.landmark_vertices[static_cast<std::size_t>(l)];
    source_features.row(l) = source.row(v);
    target_features.row(l) = in.target_neutral.row(v);  // split keeps the original vertices
  }
  const auto t0 = Clock::now();
  auto c = find_correspondence(source, model.triangles, source_features, in.target_neutral,
                               target_features);
  if (!c) return c.failure();
  return ms_since(t0);
}

// The whole transfer between topologies as `facebooth transfer` runs it: the model's mesh onto
// the split target (both correspondences, the factorisation on the resampled target, the solve
// and the displacement carried back per expression).
Result<void> time_across(const FaceModel& model, const Inputs& in, const TentTopology& split,
                         Samples& correspondence_ms, Timing& t) {
  const auto n = static_cast<Eigen::Index>(model.vertex_count);
  std::vector<Points> expressions;
  for (const Points& e : in.expressions) expressions.push_back(e.topRows(n));
  Points source_features(68, 3), target_features(68, 3);
  for (int l = 0; l < 68; ++l) {
    const auto v = model.landmark_vertices[static_cast<std::size_t>(l)];
    source_features.row(l) = in.source_neutral.row(v);
    target_features.row(l) = in.target_neutral.row(v);
  }
  auto faces = faces_of(model.vertex_count, model.triangles, 3);
  if (!faces) return faces.failure();
  auto out = transfer_expression_set_across(tent_topology(*faces), in.source_neutral.topRows(n),
                                            expressions, source_features, split, in.target_neutral,
                                            target_features);
  if (!out) return out.failure();
  correspondence_ms.add(out->correspondence_ms);
  t.factor_ms.add(out->factor_ms);
  t.per_expression_ms.add(out->per_expression_ms);
  return success();
}

int run_bench_transfer(const ParsedOptions& options) {
  auto repeats = options.get_int("repeats");
  auto vertices = options.get_int("vertices");
  if (!repeats || *repeats < 1 || !vertices || *vertices < 1)
    return report_failure({"--repeats >= 1, --vertices >= 1"});
  auto model = load_face_model();
  if (!model) return report_failure(model.error());
  const Remesh refined = split_at_centroids(model->triangles, model->vertex_count,
                                            model->face_vertex_count, static_cast<int>(*vertices));
  const Inputs in = make_inputs(*model, refined, model->fitting_expression_count);
  auto faces = faces_of(refined.vertex_count(), refined.triangles, 3);
  if (!faces) return report_failure(faces.error());
  const TentTopology topology = tent_topology(*faces);
  Timing vtc, dt, across;
  Samples correspondence_ms, across_correspondence_ms;
  for (long long r = 0; r < *repeats; ++r) {
    std::cerr << "bench transfer: repeat " << r + 1 << "/" << *repeats << "\n";
    if (auto ok = time_vtc(in, topology, vtc); !ok) return report_failure(ok.error());
    if (auto ok = time_dt(in, dt); !ok) return report_failure(ok.error());
    auto ms = time_correspondence(*model, in, refined);
    if (!ms) return report_failure(ms.error());
    correspondence_ms.add(*ms);
    if (auto ok = time_across(*model, in, topology, across_correspondence_ms, across); !ok)
      return report_failure(ok.error());
  }
  nlohmann::json out;
  out["factor_ms"] = vtc.factor_ms.min();
  out["per_expression_ms"] = vtc.per_expression_ms.min();
  out["dt_factor_ms"] = dt.factor_ms.min();
  out["dt_per_expression_ms"] = dt.per_expression_ms.min();
  out["per_expression_vs_dt"] = vtc.per_expression_ms.min() / dt.per_expression_ms.min();
  out["factor_vs_dt"] = vtc.factor_ms.min() / dt.factor_ms.min();
  out["correspondence_ms"] = correspondence_ms.min();
  out["cross_topology"] = {{"correspondence_ms", across_correspondence_ms.min()},
                           {"factor_ms", across.factor_ms.min()},
                           {"per_expression_ms", across.per_expression_ms.min()}};
  out["vertices"] = refined.vertex_count();
  out["triangles"] = refined.triangles.size() / 3;
  out["unknowns"] = 2 * refined.vertex_count();
  out["factor_nonzeros"] = vtc.factor_nonzeros;
  out["expressions"] = in.expressions.size();
  out["peer"] = "algo/fitting ExpressionTransfer (Sumner-Popovic deformation transfer)";
  auto image = image_transfer_bench(*model, static_cast<int>(*repeats));
  if (!image) return report_failure(image.error());
  out.update(*image);
  out["targets"] = {
      {"per_expression_ms", 20}, {"correspondence_ms", 200}, {"image_transfer_ms", 100}};
  out["definition"] =
      "best of --repeats, wall clock, one thread. Meshes: the face model with face-region "
      "triangles split at their centroid until --vertices; source subject 1 and its 53 fitting "
      "shapes, target subject 2's neutral. factor_ms: VtcTarget::create (tents, A^T A, "
      "SimplicialLDLT). per_expression_ms: mean over the 53 of the source's Q per vertex, the "
      "back-substitution and the translation fix. dt_factor_ms: ExpressionTransfer::create, "
      "which also factors its Laplacian refinement system (used by expression fits, not by "
      "transfer); dt_per_expression_ms: ExpressionTransfer::transfer. image_transfer_ms: "
      "transfer_image_expression (2D VTC, seed 002 section VI) of subject 1's jaw-open/brows-up "
      "synthetic photograph pair onto subject 2's neutral photograph, 311 x 419 px, landmarks "
      "given (the truth; dlib not timed), whole call; image_warp_peer_ms: the plain "
      "piecewise-affine landmark warp of the target on the same input (warp_expression). "
      "cross_topology: transfer_expression_set_across from the model's mesh onto the split "
      "target as facebooth transfer runs it (the target resampled at the source's vertices): "
      "correspondence_ms both ways plus the resampling, factor_ms on the resampled target, "
      "per_expression_ms the solve and the displacement carried back.";
  std::cout << out.dump(2) << std::endl;
  return kExitOk;
}

}  // namespace

Command bench_transfer_command() {
  return {{"bench transfer",
           "time VTC expression transfer beside deformation transfer (JSON on stdout)",
           "",
           {{"repeats", "N", "best of N", "3"},
            {"vertices", "N", "target size: face triangles split until N vertices", "19000"},
            {"json", "", "JSON report on stdout (the only output format)", ""}}},
          run_bench_transfer};
}

}  // namespace fb::cli
