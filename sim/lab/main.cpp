// facebooth-lab: the laboratory's command line. Every eval and bench command: the product's
// algorithms scored on synthetic subjects with ground truth (sim/) and timed; and `track`, which
// here also takes --landmarks truth. Not installed by the .deb; the product's commands are in
// facebooth (host/cli).
#include <iostream>

#include "host/cli/run_cli.hpp"
#include "sim/camera/frame_truth.hpp"
#include "sim/lab/lab_commands.hpp"
#include "sim/lab/transfer_image_lab.hpp"

namespace fb::cli {

int report_failure(const Error& error) {
  std::cerr << "facebooth-lab: " << error.message << "\n";
  return kExitFailure;
}

namespace {

const std::vector<Eigen::Vector2d>* truth_landmarks(const DepthCamera& camera) {
  const FrameTruth* truth = frame_truth(camera);
  return truth != nullptr ? &truth->landmarks_depth_px : nullptr;
}

}  // namespace
}  // namespace fb::cli

int main(int argc, char** argv) {
  using namespace fb::cli;
  std::vector<Command> commands;
  for (auto group :
       {bench_camera_commands(), fusion_commands(), fit_commands(),
        std::vector<Command>{eval_track_command(), bench_track_command()}, storage_eval_commands(),
        daemon_bench_commands(), soak_bench_commands(), sync_bench_commands(), rig_eval_commands(),
        std::vector<Command>{bench_rig_command(), bench_model_command()},
        self_calibration_eval_commands(), calibration_eval_commands(), texture_eval_commands(),
        transfer_eval_commands(), std::vector<Command>{bench_transfer_command()},
        wrinkles_eval_commands(), wrinkle_render_commands(), wrinkle_diag_commands(),
        landmark_embed_commands(),
        std::vector<Command>{render_transfer_image_command(), render_transfer_command(),
                             eval_retarget_command()},
        photo_eval_commands(), tracking_commands(&truth_landmarks)}) {
    for (auto& command : group) commands.push_back(std::move(command));
  }
  return run_cli("facebooth-lab",
                 "facebooth-lab scores and times facebooth's algorithms on synthetic subjects with "
                 "ground truth.",
                 commands, argc, argv);
}
