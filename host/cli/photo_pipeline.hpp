// The file and tool side of `facebooth photo` (animate, edit), shared with the lab's `eval
// photo`: photos as PNG, their 68 landmarks (dlib or a file), a take's ARKit weights as the
// bilinear model's expression coefficients, one animated frame, and the frames encoded as a
// video by a Debian encoder when one is installed.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "algo/bilinear/bilinear_model.hpp"
#include "algo/bilinear/image_fit.hpp"
#include "algo/core/image.hpp"
#include "algo/core/result.hpp"
#include "algo/landmarks/landmark_detector.hpp"
#include "algo/photo/photo_face.hpp"
#include "storage/session_store.hpp"

namespace fb::cli {

Result<ColorImage> read_photo(const std::filesystem::path& path);
Result<void> write_photo(const ColorImage& image, const std::filesystem::path& path);

// 68 lines "x y" (photo px, iBUG order); '#' starts a comment; "nan nan" marks a missing point.
Result<ImageLandmarks> read_landmarks_file(const std::filesystem::path& path);
Result<void> write_landmarks_file(const ImageLandmarks& landmarks,
                                  const std::filesystem::path& path);
// dlib's face detector and 68-point predictor on the photo (full-image pass); "no face found"
// says what to do.
Result<ImageLandmarks> detect_photo_landmarks(LandmarkDetector& detector, const ColorImage& photo,
                                              const std::string& what);

// Per take frame, one coefficient per model expression after the neutral (beta of eq. 17's
// blend): the take's ARKit curves (camelCase or Live Link names) back onto the model's shapes
// by the project's one mapping (algo/tracking/arkit.hpp); a combined ARKit curve feeds both
// halves. Fails when the take and the model share no shape.
struct TakeCoefficients {
  std::vector<std::vector<float>> beta;  // frames x (model expressions - 1)
  int mapped_shapes = 0;                 // model expressions the take drives
  std::vector<std::string> unmapped;     // model expressions no take curve drives
};
Result<TakeCoefficients> take_coefficients(const TakeData& take, const BilinearModel& model);

// FaceWarehouse 4.4: a video's per-frame coefficients. One identity fitted jointly over all
// frames' landmarks (eq. 15 extended to every frame, `rounds` rounds), then each frame's w_exp
// written in the model's expressions: w_exp = a U_exp[0] + sum_i b_i (U_exp[i] - U_exp[0])
// solved by least squares, beta_i = b_i / a (a absorbs the scale weak perspective leaves
// between w_id and w_exp), less the first face frame's (the video starts neutral, as a take's
// calibration does), clamped to [0, 1] as a rig's weights are. Frames without landmarks get the previous frame's coefficients.
struct VideoCoefficients {
  TakeCoefficients coefficients;
  double mean_fit_error_px = 0;
  int frames_without_face = 0;
};
Result<VideoCoefficients> video_coefficients(const BilinearModel& model,
                                             const std::vector<ImageLandmarks>& frames,
                                             const std::vector<bool>& found, int rounds = 3);

// One animated frame: the photo warped from its fitted face to B_0 + sum beta (B_i - B_0)
// (or, `keep_expression`, the fitted face + sum beta (B_i - B_0)).
Result<ColorImage> animate_photo_frame(const ColorImage& photo, const BilinearModel& model,
                                       const PhotoFace& face,
                                       const std::vector<std::uint32_t>& triangles,
                                       std::span<const float> beta, bool keep_expression,
                                       std::vector<float>& scratch, MeshWarpStats* stats = nullptr);

// Encodes DIR/frame_%04d.png with the first encoder found on PATH: ffmpeg (H.264 MP4, yuv420p)
// or img2webp (animated WebP, lossy). Returns the file written, or an empty path and `why`
// when no encoder is installed.
Result<std::filesystem::path> encode_frames(const std::filesystem::path& dir, int frame_count,
                                            double fps, std::string& why);

}  // namespace fb::cli
