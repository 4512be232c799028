// facebooth: the companion host tool and the device's command-line front end. The laboratory's
// eval and bench commands are a separate binary, facebooth-lab (sim/lab).
#include <iostream>

#include "host/cli/retarget.hpp"
#include "host/cli/run_cli.hpp"

namespace fb::cli {

int report_failure(const Error& error) {
  std::cerr << "facebooth: " << error.message << "\n";
  return kExitFailure;
}

}  // namespace fb::cli

int main(int argc, char** argv) {
  using namespace fb::cli;
  std::vector<Command> commands;
  for (auto group :
       {camera_commands(), guide_commands(), tracking_commands(), storage_commands(),
        rig_commands(), self_calibration_commands(), camera_calibrate_commands(),
        texture_commands(), transfer_commands(), transfer_image_commands(), retarget_commands(),
        sync_commands(), wrinkle_commands(), photo_commands()}) {
    for (auto& command : group) commands.push_back(std::move(command));
  }
  return run_cli("facebooth",
                 "facebooth drives a Kinect v1 face-capture appliance and does the host-side work.",
                 commands, argc, argv);
}
