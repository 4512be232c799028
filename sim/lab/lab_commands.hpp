// The command groups of facebooth-lab (sim/lab/main.cpp): every eval and bench command. They
// score the product's algorithms against the laboratory's ground truth (sim/) and time them.
#pragma once

#include <vector>

#include "host/cli/command_line.hpp"
#include "host/cli/commands.hpp"

namespace fb::cli {

// Options more than one eval offers, spelled once.
inline OptionSpec landmark_noise_option() {
  return {"landmark-noise-px", "PX", "Gaussian noise on the true landmarks (per axis)", "1"};
}

std::vector<Command> bench_camera_commands();           // bench camera
std::vector<Command> fusion_commands();                 // eval fusion, bench fusion
std::vector<Command> fit_commands();                    // eval fit, bench fit
Command eval_track_command();                           // track_eval.cpp
Command bench_track_command();                          // track_bench.cpp
std::vector<Command> storage_eval_commands();           // eval storage
std::vector<Command> daemon_bench_commands();           // bench daemon
std::vector<Command> soak_bench_commands();             // bench soak
std::vector<Command> sync_bench_commands();             // bench sync (bench_sync.cpp)
std::vector<Command> rig_eval_commands();               // eval rig, eval model
Command bench_rig_command();                            // rig_bench.cpp
Command bench_model_command();                          // bench_model.cpp
std::vector<Command> self_calibration_eval_commands();  // eval self-calibration, bench calibration
std::vector<Command> calibration_eval_commands();       // eval calibration
std::vector<Command> texture_eval_commands();           // eval texture
std::vector<Command> transfer_eval_commands();          // eval transfer
Command bench_transfer_command();                       // transfer_bench.cpp
std::vector<Command> wrinkles_eval_commands();          // eval wrinkles, bench wrinkles
std::vector<Command> wrinkle_render_commands();         // render wrinkles (wrinkle_render.cpp)
std::vector<Command> landmark_embed_commands();         // landmarks embed (landmark_embed.cpp)
std::vector<Command> wrinkle_diag_commands();           // diag wrinkles, diag wrinkle-scale
std::vector<Command> wrinkle_visibility_commands();     // diag wrinkle-visibility (in diag's)
std::vector<Command> photo_eval_commands();             // eval photo (photo_eval.cpp)

}  // namespace fb::cli
