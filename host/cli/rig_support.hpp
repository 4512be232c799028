// What `rig` / `model build` share with the lab's eval rig, eval model and bench rig
// (sim/lab/rig_eval_commands.cpp): mesh distances, the rig options, the bootstrap model build.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string_view>
#include <vector>

#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include "algo/bilinear/bilinear_model.hpp"
#include "algo/core/camera_model.hpp"
#include "algo/facemodel/face_model.hpp"
#include "algo/guide/guide_expressions.hpp"
#include "algo/rigging/example_rigging.hpp"
#include "host/cli/command_line.hpp"
#include "host/cli/progress.hpp"

namespace fb::cli {

// Mean distance over `subset` between mesh a (mapped by `a_to_b`) and mesh b.
double mean_distance(std::span<const float> a, std::span<const float> b,
                     std::span<const std::uint32_t> subset, const RigidPose& a_to_b = RigidPose{});
// Mean |R (a - a0) - (b - b0)| over `subset`: the expression part of two faces alone.
double mean_delta_distance(std::span<const float> a, std::span<const float> a0,
                           std::span<const float> b, std::span<const float> b0,
                           std::span<const std::uint32_t> subset, const Eigen::Quaterniond& r);
std::vector<float> face(const FaceModel& model, std::span<const float> identity,
                        std::span<const float> weights);
// A rig progress bar over the whole job (0..1000).
std::function<void(std::string_view, double)> rig_progress(std::shared_ptr<Progress> bar);
Result<RigOptions> rig_options(const ParsedOptions& options, const FaceModel& model);
std::vector<OptionSpec> rig_option_specs();
// What `rig` and `sync` rig with: the face model, the guide (--guide) and the rig options.
struct RigInputs {
  FaceModel model;
  GuideSet guide;
  RigOptions rig;
};
Result<RigInputs> load_rig_inputs(const ParsedOptions& options);
// Random held-out expression mixes: every fitting shape is on with probability 0.2, U(0, 1).
std::vector<std::vector<float>> random_mixes(int count, int shapes, std::uint64_t seed);

struct BuiltModel {
  BilinearModel model;
  double build_s = 0;
  nlohmann::json info;
};
Result<BuiltModel> build_from_face_model(const FaceModel& face_model, int identities,
                                         std::uint64_t seed, int id_knobs, int exp_knobs);

}  // namespace fb::cli
