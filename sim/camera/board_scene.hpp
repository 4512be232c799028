// The synthetic checkerboard target: a flat plate with a printed checkerboard (BoardSpec, a
// white margin of one square) in front of a wall, at a seeded sequence of poses, rendered
// through a Kinect v1 unit's TRUE calibration while the camera reports the defaults, so
// `camera calibrate` and `eval calibration` are scored against known truth.
//
// URI: synthetic:target=checkerboard,board=9x6:25mm,seed=N,frames=N,noise=on|off,wall=MM,
//      unit=SEED|reg_dx=PX,reg_dy=PX,reg_rot=DEG,depth_scale=S,calibrated=0|1
// Defaults: board 9x6:25mm, seed 0, 20 frames, noise on, wall at 2200 mm, unit 0 (calibrated).
//
// Rendering:
//  - Depth: KinectSensorModel (noise, quantisation, projector shadow, dropouts at the plate's
//    edges) through the unit's true calibration; depth_mm is the raw disparity through the
//    reported (default) law, as a Kinect without a device.json delivers it.
//  - Colour: analytic. Each colour pixel is traced back through the true registration (the
//    continuous RegistrationModel: bilinear table, parallax at the plate's depth) to the depth
//    pixel and so to the plate; pixels an edge of the print crosses are supersampled 8x8, so
//    corners are placed to a few hundredths of a pixel. Small Gaussian noise (sigma 2 levels).
//  - Poses: board centre spread over a 3x3 grid of the image, distance 600-1500 mm
//    (stratified), tilt up to 35 deg about a random axis in the image plane, in-plane rotation
//    up to 15 deg; every pose keeps the whole plate inside the depth image.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "algo/calibration/board.hpp"
#include "algo/core/frame.hpp"
#include "algo/render/kinect_sensor.hpp"
#include "drivers/camera/depth_camera.hpp"

namespace fb {

struct BoardSceneOptions {
  BoardSpec board;
  std::uint64_t seed = 0;  // poses and noise
  int frame_count = 20;
  double wall_mm = 2200.0;
  KinectSensorOptions sensor;
  KinectCalibration calibration = KinectCalibration::defaults();  // the unit's truth
  std::optional<KinectCalibration> reported_calibration;          // unset = calibration
  std::string uri;
};

// Seeded board poses (camera_from_board, depth camera frame, mm); see the header comment.
std::vector<RigidPose> board_scene_poses(const BoardSpec& board, std::uint64_t seed, int count);

// Truth of one rendered view.
struct BoardViewTruth {
  RigidPose camera_from_board;
  std::vector<Eigen::Vector2d> corners_color;  // inner corners in the colour image (true reg.)
  std::vector<Eigen::Vector2d> corners_depth;  // inner corners projected into the depth image
};

class BoardScene {
 public:
  static Result<std::unique_ptr<BoardScene>> create(const BoardSceneOptions& options);
  ~BoardScene();

  const BoardSceneOptions& options() const;
  const KinectCalibration& reported_calibration() const;
  int frame_count() const;
  // Renders view `index` into `frame` (depth, raw disparity, colour) and its truth.
  Result<void> render(int index, RgbdFrame& frame, BoardViewTruth* truth = nullptr);

  struct State;

 private:
  explicit BoardScene(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

// Parses the URI arguments above (after `synthetic:`).
Result<BoardSceneOptions> parse_board_scene_options(std::string_view arguments);
// True when the synthetic URI asks for this scene (`target=checkerboard`).
bool is_board_target(std::string_view arguments);
// The scene as a DepthCamera (FrameTruth stays null: it describes faces).
Result<std::unique_ptr<DepthCamera>> open_board_camera(std::string_view arguments);

}  // namespace fb
