// facebooth-lab eval track, in parts (track_eval.cpp runs them): the scoring of a tracked take
// against its truth, the realistic-world scenarios and the occluder takes.
#pragma once

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "host/cli/commands.hpp"
#include "sim/scoring/take_runner.hpp"

namespace fb::cli::track_eval {

// track_eval_scoring.cpp

// The rigid motion between two identities' neutral faces (model frame), least squares over the
// front-facing face vertices: how far the calibrated face's frame sits from the true one
// (degrees, mm at `centre`). `estimate` is in `estimate_model`'s identity modes.
std::pair<double, double> identity_rigid_offset(const FaceModel& model,
                                                std::span<const float> truth,
                                                const FaceModel& estimate_model,
                                                std::span<const float> estimate,
                                                const Eigen::Vector3d& centre);

// The constant rigid motion between the calibrated and the true model frame (track_eval_scoring.cpp
// says why): Q = mean over tracked frames of T_true^-1 T_est.
RigidPose calibration_gauge(const std::vector<FrameResult>& results);

// Scores the frames after calibration (the subject's identity is known from then on).
struct Score {
  std::vector<double> weight_error;  // per frame: mean over all shapes
  std::vector<double> active_error;  // per frame: mean over the take's active shapes
  std::vector<double> rot, centre, origin, raw_rot, raw_centre, abs_rot, abs_centre;
  std::vector<double> per_shape_sum;
  int frames = 0, lost = 0;
};

void score(const RenderedTake& take, const std::vector<FrameResult>& results, Score& s, int k);
nlohmann::json score_json(const Score& s, const FaceModel& model);
// The n shapes of a per-shape figure with the largest values, largest first.
nlohmann::json top_shapes(const nlohmann::json& per_shape, std::size_t n);

// track_eval_world.cpp: --scenario NAME, every part of the realistic world (and for realistic a
// plain baseline) over seeds 1..N; prints the JSON and returns the exit code.
int run_world_scenarios(const ParsedOptions& options, const FaceModel& model,
                        const ArkitMapping& mapping, const TakeSpec& design,
                        const std::string& scenario, long long seeds, long long frames,
                        const TrackerOptions& overrides, BilinearSubjectModel* bilinear,
                        const std::string& landmark_source);

// track_eval_occluder.cpp
constexpr int kOccluderTakeFrames = 130;

// One occluder take (track_eval_occluder.cpp): a flat plate passes in front of the face.
// Appends the per-frame mean abs error of the shapes the plate does not cover to `unaffected`;
// returns the take's figures.
Result<nlohmann::json> evaluate_occluder_take(const FaceModel& model, const ArkitMapping& mapping,
                                              const RunOptions& run, const TakeSpec& spec,
                                              std::vector<double>& unaffected);

// The `occluder` object of the report over all occluder takes.
nlohmann::json occluder_json(const nlohmann::json& occluder_takes,
                             const std::vector<double>& unaffected);

}  // namespace fb::cli::track_eval
