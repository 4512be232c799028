// facebooth-lab eval transfer: VTC expression transfer (algo/transfer) beside the project's
// deformation transfer (algo/fitting/expression_transfer, Sumner and Popovic) on synthetic
// subjects of the face model, where every truth is known.
//
// Self-transfer (seed 002, appendix): each of the 53 fitting shapes of a subject mapped back
// onto the subject's own neutral; per vertex the error is | |T_e - T_n| / |S_e - S_n| - 1 | (the
// transferred motion's length against the source motion's), over the vertices the shape moves.
// Cross-subject: subject 1's shapes mapped onto subjects 2..N, whose truth is the same recipe
// (the model's generic expression delta) added to their own neutral, as sim/ builds subjects.
#include <array>
#include <iostream>
#include <optional>

#include <nlohmann/json.hpp>

#include "algo/fitting/expression_transfer.hpp"
#include "algo/transfer/expression_set.hpp"
#include "host/cli/guide_files.hpp"
#include "host/cli/mesh_landmarks.hpp"
#include "host/cli/rig_support.hpp"
#include "host/cli/stats.hpp"
#include "host/cli/tracker_setup.hpp"
#include "sim/lab/lab_commands.hpp"
#include "sim/lab/transfer_image_lab.hpp"
#include "sim/subject/remesh.hpp"
#include "storage/asset_files.hpp"

namespace fb::cli {
namespace {

enum Region { kAll, kEyes, kMouth, kRegions };
constexpr std::array<const char*, kRegions> kRegionNames = {"all", "eye", "mouth"};

// Which regions each vertex is in: within `radius_mm` of an eye-contour landmark (iBUG 36-47)
// or a mouth landmark (48-67) on the model's mean neutral.
std::vector<std::array<bool, kRegions>> regions(const FaceModel& model, double radius_mm) {
  const Points p = points_from_floats(model.neutral);
  std::vector<std::array<bool, kRegions>> out(static_cast<std::size_t>(model.vertex_count));
  for (int v = 0; v < model.vertex_count; ++v) {
    auto& r = out[static_cast<std::size_t>(v)];
    r = {true, false, false};
    for (int l = 36; l < 68; ++l) {
      const auto lv = model.landmark_vertices[static_cast<std::size_t>(l)];
      if ((p.row(v) - p.row(lv)).norm() < radius_mm) r[l < 48 ? kEyes : kMouth] = true;
    }
  }
  return out;
}

struct ErrorSamples {
  std::array<std::vector<double>, kRegions> ratio_pct, vector_pct;
};

// The appendix's per-vertex error (and the stricter vector form) of one transferred shape.
void add_self_errors(const Points& source_neutral, const Points& source_expr,
                     const Points& target_expr, double min_motion_mm,
                     const std::vector<std::array<bool, kRegions>>& region, ErrorSamples& out) {
  for (Eigen::Index v = 0; v < source_neutral.rows(); ++v) {
    const Eigen::RowVector3d motion = source_expr.row(v) - source_neutral.row(v);
    const double m = motion.norm();
    if (m < min_motion_mm) continue;
    const Eigen::RowVector3d moved = target_expr.row(v) - source_neutral.row(v);
    const double ratio = 100.0 * std::abs(moved.norm() / m - 1.0);
    const double vec = 100.0 * (moved - motion).norm() / m;
    for (int r = 0; r < kRegions; ++r) {
      if (!region[static_cast<std::size_t>(v)][static_cast<std::size_t>(r)]) continue;
      out.ratio_pct[static_cast<std::size_t>(r)].push_back(ratio);
      out.vector_pct[static_cast<std::size_t>(r)].push_back(vec);
    }
  }
}

struct Subject {
  Points neutral;
  std::vector<Points> expressions;  // the 53 fitting shapes at weight 1
};

Subject make_subject(const FaceModel& model, std::uint64_t seed) {
  Subject s;
  const auto identity = identity_draw(seed, model.identity_count);
  s.neutral = points_from_floats(face(model, identity, {}));
  for (int j = 0; j < model.fitting_expression_count; ++j)
    s.expressions.push_back(s.neutral + points_from_floats(model.expression_shape(j)));
  return s;
}

// The project's deformation transfer of every shape of `source` onto `target_neutral`.
Result<std::vector<Points>> dt_transfer(const FaceModel& model, const Subject& source,
                                        const Points& target_neutral) {
  const auto target = floats_from_points(target_neutral);
  const auto guide = floats_from_points(source.neutral);
  auto dt = ExpressionTransfer::create(model, target, guide);
  if (!dt) return dt.failure();
  std::vector<Points> out;
  for (const Points& e : source.expressions) {
    auto moved = dt->transfer(floats_from_points(e));
    if (!moved) return moved.failure();
    out.push_back(points_from_floats(*moved));
  }
  return out;
}

nlohmann::json summary(const std::vector<double>& v) {
  const Summary s = stats_of(v);
  return {{"median", s.median}, {"mean", s.mean}, {"p95", s.p95}, {"count", s.count}};
}

nlohmann::json region_json(const ErrorSamples& e) {
  nlohmann::json j;
  for (int r = 0; r < kRegions; ++r) {
    const auto ri = static_cast<std::size_t>(r);
    j[kRegionNames[ri]] = {{"ratio_pct", summary(e.ratio_pct[ri])},
                           {"vector_pct", summary(e.vector_pct[ri])}};
  }
  return j;
}

// Per-vertex distances to the truth over the vertices the truth moves, and over all vertices.
void add_cross_errors(const Points& truth_neutral, const Points& truth, const Points& out,
                      double min_motion_mm, std::vector<double>& moving, std::vector<double>& all) {
  for (Eigen::Index v = 0; v < truth.rows(); ++v) {
    const double d = (out.row(v) - truth.row(v)).norm();
    all.push_back(d);
    if ((truth.row(v) - truth_neutral.row(v)).norm() >= min_motion_mm) moving.push_back(d);
  }
}

Points landmarks(const FaceModel& model, const Points& p) {
  Points out(68, 3);
  for (int l = 0; l < 68; ++l)
    out.row(l) = p.row(model.landmark_vertices[static_cast<std::size_t>(l)]);
  return out;
}

// The target meshes of another topology (sim/subject/remesh.hpp), each with its known truth.
struct Remeshes {
  std::vector<std::pair<std::string, Remesh>> meshes;
  std::vector<TentTopology> topologies;
};

Remeshes make_remeshes(const FaceModel& model) {
  Remeshes r;
  const std::vector<std::uint32_t> keep(model.landmark_vertices.begin(),
                                        model.landmark_vertices.end());
  r.meshes.emplace_back("decimated_50pct",
                        decimate(model.triangles, points_from_floats(model.neutral), 0.5, keep));
  r.meshes.emplace_back("flipped_diagonals",
                        flip_quad_diagonals(model.triangles, model.vertex_count));
  r.meshes.emplace_back(
      "centroid_split_19k",
      split_at_centroids(model.triangles, model.vertex_count, model.face_vertex_count, 19000));
  for (const auto& [name, m] : r.meshes)
    r.topologies.push_back(tent_topology(*faces_of(m.vertex_count(), m.triangles, 3)));
  return r;
}

// Per remeshed target: the errors over moving vertices of both solves between topologies, and
// the correspondence's error (a target vertex's source point against its true place on the
// source, over all target vertices).
struct TopologyErrors {
  std::vector<double> resample, target_tents, correspondence;
  // Feature points found by dlib on frontal renders (host/cli/mesh_landmarks.hpp): the found
  // points' distances to the true landmark vertices, and the transfer with found points on both
  // faces or on the target only (the source's given).
  std::vector<double> found_points, found_both, found_target;
};

// The found-feature-point variants of add_cross_topology for one remeshed target.
Result<void> add_found_features(const FaceModel& model, const TentTopology& topology,
                                const Subject& first, const Points& source_found,
                                const Subject& subject, const Remesh& mesh,
                                const TentTopology& mesh_topology, LandmarkDetector& detector,
                                double min_motion_mm, TopologyErrors& errors) {
  const Points target_neutral = mesh.apply(subject.neutral);
  auto found = cli::landmarks_from_render(detector, target_neutral, mesh.triangles);
  if (!found) return found.failure();
  const Points truth = landmarks(model, subject.neutral);
  for (Eigen::Index l = 0; l < truth.rows(); ++l)
    errors.found_points.push_back((found->row(l) - truth.row(l)).norm());
  for (const bool both : {true, false}) {
    auto out = transfer_expression_set_across(topology, first.neutral, first.expressions,
                                              both ? source_found : landmarks(model, first.neutral),
                                              mesh_topology, target_neutral, *found);
    if (!out) return out.failure();
    std::vector<double> all;
    for (std::size_t j = 0; j < subject.expressions.size(); ++j)
      add_cross_errors(target_neutral, mesh.apply(subject.expressions[j]), out->expressions[j],
                       min_motion_mm, both ? errors.found_both : errors.found_target, all);
  }
  return success();
}

// dlib and subject 1's found feature points, when the shape predictor loads.
struct FoundFeatures {
  std::optional<LandmarkDetector> detector;
  Points source;
  std::string skipped;  // why there are none
};

FoundFeatures found_features(const FaceModel& model, const Subject& first) {
  FoundFeatures f;
  auto detector = cli::load_landmark_detector("");
  if (!detector) return {std::nullopt, {}, detector.error().message};
  auto source = cli::landmarks_from_render(*detector, first.neutral, model.triangles);
  if (!source) return {std::nullopt, {}, source.error().message};
  return {std::move(*detector), std::move(*source), {}};
}

// Subject 1 on the model's mesh -> `subject` remeshed; mean error over moving vertices per mesh.
Result<void> add_cross_topology(const FaceModel& model, const TentTopology& topology,
                                const Subject& first, const Subject& subject, const Remeshes& r,
                                double min_motion_mm, std::vector<TopologyErrors>& errors,
                                Samples& correspondence_ms, FoundFeatures& found) {
  for (std::size_t k = 0; k < r.meshes.size(); ++k) {
    const Remesh& mesh = r.meshes[k].second;
    if (found.detector)
      if (auto ok = add_found_features(model, topology, first, found.source, subject, mesh,
                                       r.topologies[k], *found.detector, min_motion_mm, errors[k]);
          !ok)
        return ok.failure();
    const Points target_neutral = mesh.apply(subject.neutral);
    for (const auto method : {CrossTopologyMethod::kResample, CrossTopologyMethod::kTargetTents}) {
      auto out = transfer_expression_set_across(
          topology, first.neutral, first.expressions, landmarks(model, first.neutral),
          r.topologies[k], target_neutral, landmarks(model, subject.neutral), method);
      if (!out) return out.failure();
      const bool resample = method == CrossTopologyMethod::kResample;
      if (resample) correspondence_ms.add(out->correspondence_ms);
      std::vector<double> all;
      for (std::size_t j = 0; j < subject.expressions.size(); ++j)
        add_cross_errors(target_neutral, mesh.apply(subject.expressions[j]), out->expressions[j],
                         min_motion_mm, resample ? errors[k].resample : errors[k].target_tents,
                         all);
    }
    auto corr = find_correspondence(first.neutral, model.triangles, landmarks(model, first.neutral),
                                    target_neutral, landmarks(model, subject.neutral));
    if (!corr) return corr.failure();
    const Points found = map_points(*corr, first.neutral), truth = mesh.apply(first.neutral);
    for (Eigen::Index v = 0; v < truth.rows(); ++v)
      errors[k].correspondence.push_back((found.row(v) - truth.row(v)).norm());
  }
  return success();
}

// The 2D transfer's figures (sim/lab/transfer_image_lab.hpp) merged into `out`; none for 0.
Result<void> add_image_figures(const FaceModel& model, long long subjects, nlohmann::json& out) {
  if (subjects <= 0) return success();
  auto image = image_transfer_eval(model, static_cast<int>(subjects));
  if (!image) return image.failure();
  out.update(*image);
  return success();
}

// The cross-topology figures. The headline pools every remeshed target (decimated,
// re-triangulated, centroid split).
void add_topology_json(const Remeshes& remeshes, const std::vector<TopologyErrors>& errors,
                       const FoundFeatures& found, nlohmann::json& out) {
  std::vector<double> pooled;
  for (const TopologyErrors& e : errors)
    pooled.insert(pooled.end(), e.resample.begin(), e.resample.end());
  out["cross_topology_vertex_error_mm"] = stats_of(pooled).mean;
  for (std::size_t k = 0; k < remeshes.meshes.size(); ++k)
    out["cross_topology"][remeshes.meshes[k].first] = {
        {"vertices", remeshes.meshes[k].second.vertex_count()},
        {"moving_mm", summary(errors[k].resample)},
        {"target_tents_moving_mm", summary(errors[k].target_tents)},
        {"correspondence_error_mm", summary(errors[k].correspondence)},
        {"found_landmarks",
         {{"point_error_mm", summary(errors[k].found_points)},
          {"found_both_moving_mm", summary(errors[k].found_both)},
          {"found_target_given_source_moving_mm", summary(errors[k].found_target)}}}};
  if (!found.detector) out["found_landmarks_skipped"] = found.skipped;
}

int run_eval_transfer(const ParsedOptions& options) {
  auto subjects = options.get_int("subjects");
  auto min_motion = options.get_double("min-motion");
  auto radius = options.get_double("region-radius");
  auto image_subjects = options.get_int("image-subjects");
  if (!subjects || *subjects < 2 || !min_motion || *min_motion <= 0 || !radius || *radius <= 0 ||
      !image_subjects || *image_subjects < 0 || *image_subjects == 1)
    return report_failure(
        {"--subjects N >= 2, --min-motion MM > 0, --region-radius MM > 0, "
         "--image-subjects 0 or >= 2"});
  auto model = load_face_model();
  if (!model) return report_failure(model.error());
  auto faces = faces_of(model->vertex_count, model->triangles, 3);
  if (!faces) return report_failure(faces.error());
  const TentTopology topology = tent_topology(*faces);
  const auto region = regions(*model, *radius);
  ErrorSamples vtc_self, dt_self;
  std::vector<double> vtc_moving, vtc_all, dt_moving, dt_all;
  Samples factor_ms, per_expression_ms, correspondence_ms;
  const Subject first = make_subject(*model, 1);
  const Remeshes remeshes = make_remeshes(*model);
  std::vector<TopologyErrors> topology_errors(remeshes.meshes.size());
  FoundFeatures found = found_features(*model, first);
  for (long long s = 1; s <= *subjects; ++s) {
    std::cerr << "eval transfer: subject " << s << "/" << *subjects << "\n";
    const Subject subject = s == 1 ? first : make_subject(*model, static_cast<std::uint64_t>(s));
    auto vtc = transfer_expression_set(topology, subject.neutral, subject.expressions,
                                       subject.neutral, false);
    if (!vtc) return report_failure(vtc.error());
    factor_ms.add(vtc->factor_ms);
    per_expression_ms.add(vtc->per_expression_ms);
    auto dt = dt_transfer(*model, subject, subject.neutral);
    if (!dt) return report_failure(dt.error());
    for (std::size_t j = 0; j < subject.expressions.size(); ++j) {
      add_self_errors(subject.neutral, subject.expressions[j], vtc->expressions[j], *min_motion,
                      region, vtc_self);
      add_self_errors(subject.neutral, subject.expressions[j], (*dt)[j], *min_motion, region,
                      dt_self);
    }
    if (s == 1) continue;
    // Cross-subject: subject 1 -> this subject, as `facebooth transfer` runs it (aligned).
    auto cross =
        transfer_expression_set(topology, first.neutral, first.expressions, subject.neutral, true);
    if (!cross) return report_failure(cross.error());
    auto dt_cross = dt_transfer(*model, first, subject.neutral);
    if (!dt_cross) return report_failure(dt_cross.error());
    for (std::size_t j = 0; j < subject.expressions.size(); ++j) {
      add_cross_errors(subject.neutral, subject.expressions[j], cross->expressions[j], *min_motion,
                       vtc_moving, vtc_all);
      add_cross_errors(subject.neutral, subject.expressions[j], (*dt_cross)[j], *min_motion,
                       dt_moving, dt_all);
    }
    if (auto ok = add_cross_topology(*model, topology, first, subject, remeshes, *min_motion,
                                     topology_errors, correspondence_ms, found);
        !ok)
      return report_failure(ok.error());
  }
  nlohmann::json out;
  auto median = [](const std::vector<double>& v) { return stats_of(v).median; };
  out["vtc_self_error_median_pct"] = median(vtc_self.ratio_pct[kAll]);
  out["dt_self_error_median_pct"] = median(dt_self.ratio_pct[kAll]);
  for (int r = kEyes; r < kRegions; ++r) {
    const auto ri = static_cast<std::size_t>(r);
    const std::string name = kRegionNames[ri];
    out["vtc_self_error_" + name + "_median_pct"] = median(vtc_self.ratio_pct[ri]);
    out["dt_self_error_" + name + "_median_pct"] = median(dt_self.ratio_pct[ri]);
  }
  out["cross_subject_vertex_error_mm"] = stats_of(vtc_moving).mean;
  out["dt_cross_subject_vertex_error_mm"] = stats_of(dt_moving).mean;
  add_topology_json(remeshes, topology_errors, found, out);
  out["correspondence_ms"] = correspondence_ms.mean();
  out["self"] = {{"vtc", region_json(vtc_self)}, {"dt", region_json(dt_self)}};
  out["cross_subject"] = {
      {"vtc", {{"moving_mm", summary(vtc_moving)}, {"all_vertices_mm", summary(vtc_all)}}},
      {"dt", {{"moving_mm", summary(dt_moving)}, {"all_vertices_mm", summary(dt_all)}}}};
  out["vtc_factor_ms"] = factor_ms.mean();
  out["vtc_per_expression_ms"] = per_expression_ms.mean();
  out["subjects"] = *subjects;
  out["shapes"] = model->fitting_expression_count;
  out["vertices"] = model->vertex_count;
  if (auto ok = add_image_figures(*model, *image_subjects, out); !ok)
    return report_failure(ok.error());
  out["targets"] = {{"vtc_self_error_median_pct", 0.1},
                    {"cross_subject_vertex_error_mm", 0.5},
                    {"cross_topology_vertex_error_mm", 1.0},
                    {"image_self_psnr_db", 30}};
  out["definition"] =
      "Subjects: face model identities identity_draw(1..N), shapes: the 53 fitting expression "
      "deltas at weight 1. Self: each shape mapped onto its own subject's neutral; per vertex "
      "ratio_pct = 100 |L2(Te - Tn) / L2(Se - Sn) - 1| (seed 002 appendix), vector_pct = 100 "
      "L2((Te - Tn) - (Se - Sn)) / L2(Se - Sn), over vertices the shape moves >= --min-motion "
      "mm, pooled over shapes and subjects; *_median_pct is the ratio's median. Regions: "
      "vertices within --region-radius mm of the eye-contour (iBUG 36-47) or mouth (48-67) "
      "landmark vertices. Cross-subject: subject 1's shapes onto subjects 2..N (VTC with the "
      "similarity alignment `facebooth transfer` uses), truth = that subject's neutral + the "
      "same delta; cross_subject_vertex_error_mm is the mean distance to the truth over the "
      "vertices the truth moves >= --min-motion mm. dt = algo/fitting ExpressionTransfer "
      "(Sumner-Popovic per triangle, the project's deformation transfer) on the same inputs. "
      "Cross-topology: subject 1 (model mesh) onto subjects 2..N remeshed (sim/subject/"
      "remesh.hpp: 50% decimated by half-edge collapses, every quad's other diagonal, face "
      "triangles split at centroids to 19000 vertices), correspondence from the 68 landmark "
      "points (section V), truth = the remeshed truth; cross_topology_vertex_error_mm pools "
      "the three meshes (mean over moving vertices), solved on the target resampled at the "
      "source's vertices (target_tents_moving_mm: solved on the target's own tents); "
      "correspondence_error_mm: each target vertex's source point against its true place; "
      "correspondence_ms: both ways with the resampling (mean over targets); "
      "found_landmarks: dlib's 68 points on frontal renders of subject 1 and the remeshed "
      "target, back-projected (point_error_mm against the true landmark vertices), the "
      "transfer with them on both faces, or on the target only. Images "
      "(2D VTC, "
      "section VI): synthetic photographs 311 x 419 px of --image-subjects textured subjects, "
      "neutral and 4 expression recipes, true landmarks; PSNR (8-bit RGB) over the face "
      "(inside the jaw line, brows raised by 25 % towards the forehead, of the truth's "
      "landmarks); image_self_psnr_db: each expression onto its own neutral photograph against "
      "the expression photograph; image_cross_psnr_db: subject 1's onto subjects 2..N against "
      "their own renders of the recipe, beside the plain landmark warp (image_cross_warp_psnr_db) "
      "and the solve's additive start alone (image.cross_additive_start).";
  std::cout << out.dump(2) << std::endl;
  return kExitOk;
}

}  // namespace

std::vector<Command> transfer_eval_commands() {
  return {{{"eval transfer",
            "score VTC expression transfer against deformation transfer (JSON on stdout)",
            "Self-transfer error as seed 002's appendix defines it and cross-subject error "
            "against known truths, on synthetic subjects of the face model; see the JSON's "
            "definition field.",
            {{"subjects", "N", "synthetic subjects (identity seeds 1..N)", "5"},
             {"min-motion", "MM", "vertices moving less are not scored", "0.1"},
             {"region-radius", "MM", "eye and mouth regions around their landmarks", "15"},
             {"image-subjects", "N", "synthetic photographs' subjects for the 2D figures (0: none)",
              "3"},
             {"json", "", "JSON report on stdout (the only output format)", ""}}},
           run_eval_transfer}};
}

}  // namespace fb::cli
