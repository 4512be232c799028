#include "host/cli/mesh_landmarks.hpp"

#include "algo/transfer/mesh_features.hpp"

namespace fb::cli {

Result<Points> landmarks_from_render(LandmarkDetector& detector, const Points& points,
                                     std::span<const std::uint32_t> triangles) {
  const FrontalRender render = render_frontal(points, triangles);
  detector.reset_tracking();  // unrelated pictures
  auto found = detector.detect(render.image);
  if (!found)
    return fail(
        "dlib found no face on its frontal render (the mesh must look along +z with +y "
        "up, the face model's axes: " +
        found.error().message + ")");
  return back_project(render, points, triangles, found->points);
}

}  // namespace fb::cli
