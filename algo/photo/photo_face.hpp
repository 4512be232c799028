// A face in a photograph as the bilinear model sees it (FaceWarehouse 4.1, 4.3): the model fitted
// to the photo's 68 landmarks under weak perspective (image_fit.hpp, eq. 13-14), the photo's
// image blendshapes B_i = C_r x_2 w_id x_3 U_exp[i] (eq. 17), new expressions as
// V = B_0 + sum_i beta_i (B_i - B_0), and what the mesh warp (mesh_warp.hpp) needs: meshes
// projected with the photo's pose, the face region's triangles, the inner-lip polygon.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "algo/bilinear/bilinear_model.hpp"
#include "algo/bilinear/image_fit.hpp"
#include "algo/core/result.hpp"
#include "algo/photo/mesh_warp.hpp"

namespace fb {

struct PhotoFace {
  LandmarkFit fit;                              // pose, w_id, w_exp, landmark error (px)
  std::vector<float> mesh;                      // C_r x_2 w_id x_3 w_exp: the photo's face, 3V
  std::vector<std::vector<float>> blendshapes;  // eq. 17, one per model expression, 3V each
};

// Fits the model and builds the image blendshapes.
Result<PhotoFace> fit_photo_face(const BilinearModel& model, const ImageLandmarks& landmarks,
                                 const LandmarkFitOptions& options = {});

// V = B_0 + sum_i beta[i-1] (B_i - B_0), i = 1..E-1 (beta has one value per model expression
// after the neutral; missing values are 0). With `base` non-empty it replaces B_0 as the
// starting mesh (the photo's own expression kept under the take's).
void blend_image_blendshapes(const std::vector<std::vector<float>>& blendshapes,
                             std::span<const float> beta, std::span<const float> base,
                             std::span<float> out);

// x, y in photo px and the depth along the view, per vertex (weak perspective, eq. 13).
std::vector<Eigen::Vector3f> project_mesh(const WeakPerspectivePose& pose,
                                          std::span<const float> mesh);

// The model's triangles whose three corners are face-region vertices (0..face_vertex_count-1).
std::vector<std::uint32_t> face_region_triangles(const BilinearModel& model);

// The inner-lip landmarks (iBUG 60-67) of a projected mesh: the mouth opening's outline.
std::vector<Eigen::Vector2f> mouth_polygon(const BilinearModel& model,
                                           std::span<const Eigen::Vector3f> projected);

// The photo re-rendered after its face mesh changed from `from` to `to` (both 3V, same pose).
Result<ColorImage> warp_face(const ColorImage& photo, const BilinearModel& model,
                             const WeakPerspectivePose& pose, std::span<const float> from,
                             std::span<const float> to, std::span<const std::uint32_t> triangles,
                             const MeshWarpOptions& options = {}, MeshWarpStats* stats = nullptr);

}  // namespace fb
