// Synthetic wrinkle cases for `facebooth-lab eval wrinkles` and `bench wrinkles`: a textured
// synthetic subject with raised brows (the synthetic camera's face, skin texture and light),
// given wrinkle relief of known height on the forehead and at the eye corners, and rendered as
// the booth's colour frame: each pixel integrates 3 x 3 samples of the skin shaded with the
// relief's normals (Lambert + ambient under the booth's key light, as the synthetic camera
// shades), then the colour sensor's noise (3 levels per channel) and 8-bit quantisation.
// The mesh (2-3 mm between vertices) cannot carry sub-millimetre relief, so the relief is a
// height field over the model's frontal (x, y) plane applied to the shading normals: the image
// sees it exactly as it would see displaced geometry of that height (to first order).
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "algo/core/camera_model.hpp"
#include "algo/core/frame.hpp"
#include "algo/core/image.hpp"
#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"
#include "algo/sensor/kinect_calibration.hpp"
#include "algo/wrinkles/wrinkle_detail.hpp"

namespace fb::cli {

enum class WrinkleRelief {
  kGrooves,  // synthetic grooves of known depth 0.2-1.0 mm (forehead lines, crow's feet)
  kScan,     // the scan's own forehead and crow's-feet relief (exemplar crops at angle 0)
  kNone,     // no relief (a neutral capture's frame)
};

struct WrinkleCaseOptions {
  WrinkleRelief relief = WrinkleRelief::kGrooves;
  std::uint64_t seed = 1;      // subject (identity, skin texture and tone) and noise
  bool light_vary = false;     // the synthetic world's per-take light instead of the booth's
  double distance_mm = 700.0;  // the face's distance (the synthetic camera's default)
  // kScan: the crops placed as truth (forehead_0, crows_feet_left_0, crows_feet_right_0) and
  // their pixel size.
  std::vector<WrinkleExemplar> scan_crops;
  double scan_mm_per_px = 0.25;
  bool raised_brows = true;  // false: the neutral face
};

struct WrinkleCase {
  ColorImage color;                           // 640 x 480, the booth's frame
  FloatImage luminance;                       // Rec. 601 luma of `color`, 0..1
  FloatImage true_height_mm;                  // the relief each pixel sees (mean of its samples)
  std::vector<PixelRect> true_regions;        // each relief window's pixels (bounding box)
  std::array<Eigen::Vector2d, 68> landmarks;  // the true 68 points in this image
  PinholeIntrinsics intrinsics;
  double face_depth_mm = 0.0;  // depth of the landmarks' centroid
  // The subject's skin mesh (model frame, 3 floats per vertex; the model's triangles), where it is
  // in the depth camera, and the 68 landmarks' 3D points there.
  std::vector<float> vertices;
  RigidPose camera_from_model;
  std::array<Eigen::Vector3d, 68> landmarks_3d;
};

Result<WrinkleCase> make_wrinkle_case(const FaceModel& model, const WrinkleCaseOptions& options);

// The subject's neutral capture beside a case made with `options`: the same subject, camera and
// light, brows down, no relief, its own sensor noise (another exposure).
Result<WrinkleCase> make_neutral_case(const FaceModel& model, WrinkleCaseOptions options);

// The case's mesh in its camera (mm), as wrinkle_detail's WrinkleFace wants it.
std::vector<Eigen::Vector3f> camera_vertices(const WrinkleCase& c);

// What the product gives wrinkle_detail for a case: its mesh, and (optional) the neutral's frame
// and mesh. Holds the vertices the face's spans point into; not copyable or movable.
struct CaseFace {
  CaseFace(const WrinkleCase& c, const FaceModel& model, const WrinkleCase* neutral);
  CaseFace(const CaseFace&) = delete;
  CaseFace& operator=(const CaseFace&) = delete;
  std::vector<Eigen::Vector3f> expression, neutral;
  WrinkleFace face;
};

// The case as the Kinect delivers it (what a stored capture holds): depth in mm in the depth
// camera's image, and `color` moved into the colour camera's image through the unit's
// registration at the surface's depth (each depth pixel's 3 x 3 sub-samples splatted, holes
// filled from the row's neighbours), as the synthetic camera renders colour.
Result<RgbdFrame> wrinkle_case_frame(const WrinkleCase& c, const FaceModel& model,
                                     const KinectRegistration& registration);

struct WrinkleScore {
  double height_mae_mm = 0, zero_field_mae_mm = 0, wrinkle_pixel_mae_mm = 0, height_correlation = 0;
  double region_recall = 0, region_precision = 0, max_displacement_outside_mm = 0;
  int max_outside_x = -1, max_outside_y = -1;  // where the largest outside height is
};

// Scores against the truth. T: the true relief windows; T+m: grown by the margin; D: the
// detected regions; W: pixels in T whose true relief is at least 0.1 mm deep or high.
// height_mae_mm and height_correlation (Pearson, synthesised vs true) over T, zero_field_mae_mm
// the MAE of an all-zero field over T, wrinkle_pixel_mae_mm over W; region_recall = |W in D| /
// |W|; region_precision = |D in T+m| / |D|; max_displacement_outside_mm over the image minus T+m.
WrinkleScore score_wrinkles(const WrinkleCase& c, const WrinkleDetail& d, int margin);

}  // namespace fb::cli
