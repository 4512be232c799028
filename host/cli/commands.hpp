// The command table of the facebooth and facebooth-lab binaries. Each group lives in its own
// file and contributes its commands here; main.cpp only dispatches (run_cli.hpp).
#pragma once

#include <functional>
#include <vector>

#include <Eigen/Core>

#include "drivers/camera/depth_camera.hpp"
#include "host/cli/command_line.hpp"

namespace fb::cli {

// Exit codes shared by every command.
inline constexpr int kExitOk = 0;
inline constexpr int kExitFailure = 1;  // the work could not be done (message on stderr)
inline constexpr int kExitUsage = 2;    // the command line was wrong

struct Command {
  CommandSpec spec;
  std::function<int(const ParsedOptions&)> run;
};

// The product's command groups (facebooth); the laboratory's are in sim/lab/lab_commands.hpp.
std::vector<Command> camera_commands();
std::vector<Command> guide_commands();  // guide_commands.cpp
// The true landmarks (68, depth image px) of a camera's last frame, or null; only the lab has
// them (sim/camera/frame_truth.hpp). Without it `track --landmarks truth` is refused.
using TruthLandmarks = const std::vector<Eigen::Vector2d>* (*)(const DepthCamera& camera);
std::vector<Command> tracking_commands(TruthLandmarks truth_landmarks = nullptr);  // track
std::vector<Command> storage_commands();           // export, import, store info
std::vector<Command> rig_commands();               // rig, model build
std::vector<Command> self_calibration_commands();  // camera self-calibrate
std::vector<Command> camera_calibrate_commands();  // camera_calibrate.cpp
std::vector<Command> texture_commands();           // texture_commands.cpp
std::vector<Command> transfer_commands();          // transfer_commands.cpp
std::vector<Command> transfer_image_commands();    // transfer_image_commands.cpp
std::vector<Command> sync_commands();              // sync_commands.cpp: sync with booths
std::vector<Command> wrinkle_commands();           // wrinkle_commands.cpp
std::vector<Command> photo_commands();             // photo_commands.cpp: photo animate, edit

// Prints "<program>: <message>" to stderr and returns kExitFailure (each binary's main.cpp).
int report_failure(const Error& error);

}  // namespace fb::cli
