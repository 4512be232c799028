// The 2D expression transfer's figures (algo/transfer/image_transfer.hpp) for eval transfer and
// bench transfer, on synthetic photographs with known truth (sim/subject/synthetic_photo.hpp).
#pragma once

#include <nlohmann/json.hpp>

#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"
#include "host/cli/commands.hpp"

namespace fb::cli {

// Self: each expression mapped back onto its own subject's neutral photograph, against the
// expression photograph; cross: subject 1's expressions onto subjects 2..subjects, against
// their own renders of the same recipe, beside the plain landmark warp.
Result<nlohmann::json> image_transfer_eval(const FaceModel& model, int subjects);

// `facebooth-lab render transfer-image --out DIR`: the synthetic photographs `facebooth
// transfer-image` is documented with (subject 1 neutral and expression, subject 2 neutral and
// its true expression) as PNG files with their 68 landmarks as 'x y' text files.
Command render_transfer_image_command();

// `facebooth-lab render transfer` (transfer_render.cpp): the README's picture of the 3D
// transfer from the OBJ folders `facebooth export` and `facebooth transfer` write.
Command render_transfer_command();

// `facebooth-lab eval retarget` (retarget_eval.cpp).
Command eval_retarget_command();

// VTC transfer on a 311 x 419 photograph beside the plain piecewise-affine warp, best of `runs`.
Result<nlohmann::json> image_transfer_bench(const FaceModel& model, int runs);

}  // namespace fb::cli
