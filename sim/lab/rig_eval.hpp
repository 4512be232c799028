// facebooth-lab eval model (model_eval.cpp); its command is listed with eval rig's
// (rig_eval_commands.cpp).
#pragma once

#include "host/cli/commands.hpp"

namespace fb::cli {

int run_eval_model(const ParsedOptions& options);

}  // namespace fb::cli
