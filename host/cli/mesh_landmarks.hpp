// A mesh's 68 feature points without a landmark file (issue 39 item 2, seed 002 section V):
// the mesh drawn frontally (algo/transfer/mesh_features.hpp), dlib's 68 points found on the
// picture (algo/landmarks) and carried back onto the surface.
#pragma once

#include <cstdint>
#include <span>

#include "algo/landmarks/landmark_detector.hpp"
#include "algo/transfer/tent_mesh.hpp"

namespace fb::cli {

// Fails with what to do when dlib finds no face on the render (the mesh must face +z, +y up).
Result<Points> landmarks_from_render(LandmarkDetector& detector, const Points& points,
                                     std::span<const std::uint32_t> triangles);

}  // namespace fb::cli
