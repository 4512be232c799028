// Plain data that the session store keeps and the exporters read: meshes, blendshape rigs,
// landmark sets. No I/O here; see session_store.hpp and export/.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace fb {

// A triangle mesh in millimetres (the face model's frame and units).
struct MeshData {
  std::vector<float> positions;          // 3 * vertex_count, xyz interleaved
  std::vector<std::uint32_t> triangles;  // 3 * triangle_count, 0-based

  int vertex_count() const { return static_cast<int>(positions.size() / 3); }
  int triangle_count() const { return static_cast<int>(triangles.size() / 3); }
};

// A personal blendshape rig: the neutral face and one full shape (not a delta) per blendshape,
// all with the same topology. This is what FaceWarehouse's shape.bs holds.
// A capture of the rig's session that has wrinkle detail maps (issue 40 item 5): a tracked
// frame's map weights have one weight per such capture, from its guide expression's recipe.
struct RigDetailCapture {
  int capture_index = 0;
  std::string expression;  // the capture's guide expression
  bool operator==(const RigDetailCapture&) const = default;
};

struct RigData {
  std::vector<float> neutral;              // 3 * vertex_count
  std::vector<std::vector<float>> shapes;  // one 3 * vertex_count block per blendshape
  std::vector<std::string> shape_names;    // one per shape, e.g. "jawOpen"
  std::vector<std::uint32_t> triangles;    // shared topology
  // Captures with wrinkle detail, for the map weights (schema v7; empty: none).
  std::vector<RigDetailCapture> detail_captures;

  int vertex_count() const { return static_cast<int>(neutral.size() / 3); }
  int shape_count() const { return static_cast<int>(shapes.size()); }
  MeshData neutral_mesh() const { return {neutral, triangles}; }
  MeshData shape_mesh(int j) const { return {shapes[static_cast<std::size_t>(j)], triangles}; }
};

// One landmark: pixel position in the colour image, and a depth-camera 3D point when it has one
// (interior points lifted with depth; contour points stay 2D).
struct Landmark {
  float u = 0.0f;
  float v = 0.0f;
  bool has_3d = false;
  float x = 0.0f;  // mm, depth camera frame
  float y = 0.0f;
  float z = 0.0f;
};

enum class LandmarkSource {
  kAutomatic,  // the detector's output
  kOperator,   // corrected by the operator in the UI; wins over kAutomatic when present
};

}  // namespace fb
