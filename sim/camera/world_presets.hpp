// Scenario presets and URI keys of the realistic synthetic world (synthetic_world.hpp).
//
// URI keys (all default off): world=PART, world_seed=N (the subject's world; default: seed),
// displace=MM, asym=MM, id_scale=S, id_extreme=N, texture=on|off, tone=T, light=fixed|vary,
// hair=on|off, beard=on|off, torso=on|off, desk=on|off, hand=on|off, hand_pass=on|off|START,
// offset_x=PX, offset_y=PX, block_noise=RAW, block_px=N, speckle=RATE. A preset is applied
// first; explicit keys then override it.
//
// Parts (each seeded by the subject seed, so one subject keeps its face over its takes):
//  identity:  identities scaled 1.6x with the first 3 modes past +-3.5 sigma, a displacement
//             field of 2-5 mm peak, the chin 1-3 mm off to one side;
//  texture:   textured skin of a drawn tone (pale to dark), per-take light drifting over it;
//  hair:      a hair cap; a beard on odd subject seeds;
//  clutter:   torso, desk, a hand beside the face, a hand passing in front of it, the face
//             placed up to 80 px off-centre and 20-100 px high;
//  noise:     block-correlated disparity noise (0.9 raw over 6 px) and 0.5 % speckle holes;
//  unit:      a decalibrated Kinect unit (random_unit_correction(subject seed + 1)) reporting
//             the default calibration, as `unit=SEED` does;
//  realistic: all of the above.
#pragma once

#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "algo/core/result.hpp"
#include "sim/camera/synthetic_camera.hpp"

namespace fb {

// The parts, in the order the evals report them (not "realistic", which is all of them).
const std::vector<std::string>& world_parts();

// The runs of an eval's --scenario: for realistic a plain "baseline", every part alone, then
// realistic itself; for one part, that part. Unknown names are errors listing the accepted ones.
Result<std::vector<std::string>> scenario_parts(const std::string& scenario);

// Sets the options of scenario `part` (a world_parts() name, "realistic", or "none") for the
// subject `subject_seed`. Unknown names are errors that list the accepted ones.
Result<void> apply_world_preset(std::string_view part, std::uint64_t subject_seed,
                                SyntheticOptions& options);

bool is_world_key(std::string_view key);

// Applies the world keys among `values` (a preset first, then the explicit keys).
Result<void> apply_world_keys(const std::map<std::string, std::string>& values,
                              SyntheticOptions& options);

}  // namespace fb
