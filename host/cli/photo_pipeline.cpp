#include "host/cli/photo_pipeline.hpp"

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include <Eigen/QR>
#include <opencv2/imgcodecs.hpp>

#include "algo/tracking/arkit.hpp"
#include "host/cli/take_columns.hpp"

namespace fb::cli {

Result<ColorImage> read_photo(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    return fail("cannot read the photo " + path.string() + ": no such file");
  const cv::Mat bgr = cv::imread(path.string(), cv::IMREAD_COLOR);
  if (bgr.empty())
    return fail("cannot read the photo " + path.string() +
                ": not an image OpenCV can decode (give a PNG or JPEG)");
  ColorImage out;
  out.resize(bgr.cols, bgr.rows);
  for (int y = 0; y < bgr.rows; ++y)
    for (int x = 0; x < bgr.cols; ++x) {
      const cv::Vec3b p = bgr.at<cv::Vec3b>(y, x);
      out.at(x, y) = {p[2], p[1], p[0]};
    }
  return out;
}

Result<void> write_photo(const ColorImage& image, const std::filesystem::path& path) {
  cv::Mat bgr(image.height, image.width, CV_8UC3);
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x) {
      const Rgb8 p = image.at(x, y);
      bgr.at<cv::Vec3b>(y, x) = {p.b, p.g, p.r};
    }
  if (!cv::imwrite(path.string(), bgr)) return fail("could not write " + path.string());
  return success();
}

Result<ImageLandmarks> read_landmarks_file(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) return fail("cannot read the landmarks file " + path.string());
  ImageLandmarks out;
  std::string line;
  int k = 0, line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (const auto hash = line.find('#'); hash != std::string::npos) line.resize(hash);
    std::istringstream fields(line);
    std::string xs, ys;
    if (!(fields >> xs)) continue;
    if (!(fields >> ys))
      return fail(path.string() + " line " + std::to_string(line_number) +
                  ": expected two numbers 'x y'");
    if (k >= 68) return fail(path.string() + ": more than 68 points");
    char* end_x = nullptr;
    char* end_y = nullptr;
    const double x = std::strtod(xs.c_str(), &end_x);
    const double y = std::strtod(ys.c_str(), &end_y);
    if (*end_x != '\0' || *end_y != '\0')
      return fail(path.string() + " line " + std::to_string(line_number) + ": '" + xs + " " + ys +
                  "' is not two numbers");
    out.points[static_cast<std::size_t>(k)] = {x, y};
    out.valid[static_cast<std::size_t>(k)] = std::isfinite(x) && std::isfinite(y);
    ++k;
  }
  if (k != 68)
    return fail(path.string() + ": " + std::to_string(k) +
                " points, expected 68 in iBUG order (one 'x y' line each)");
  return out;
}

Result<void> write_landmarks_file(const ImageLandmarks& l, const std::filesystem::path& path) {
  std::ofstream out(path);
  out << "# 68 landmarks, iBUG order, photo px: x y\n";
  for (int k = 0; k < 68; ++k) {
    const auto& p = l.points[static_cast<std::size_t>(k)];
    if (l.valid[static_cast<std::size_t>(k)]) {
      out << p.x() << " " << p.y() << "\n";
    } else {
      out << "nan nan\n";
    }
  }
  if (!out) return fail("could not write " + path.string());
  return success();
}

Result<ImageLandmarks> detect_photo_landmarks(LandmarkDetector& detector, const ColorImage& photo,
                                              const std::string& what) {
  detector.reset_tracking();
  auto found = detector.detect(photo);
  if (!found)
    return fail("no face found in " + what + " (" + found.error().message +
                "): use a frontal photo with the face at least 80 px wide, or give the 68 "
                "points with --landmarks FILE");
  ImageLandmarks out;
  out.points = found->points;
  out.valid.fill(true);
  return out;
}

Result<TakeCoefficients> take_coefficients(const TakeData& take, const BilinearModel& model) {
  // Column of each ARKit curve in the take (camelCase or Live Link's capitalised names).
  const std::array<int, kArkitShapeCount> column = arkit_columns(take.info.shape_names);
  const auto& names = take.info.shape_names;
  // Model expression e (1..E-1) reads the take column of its ARKit curve, or of its own name
  // when the take is in the model's names (a take of a rig in model names).
  TakeCoefficients out;
  const int shapes = model.expression_count - 1;
  std::vector<int> source(static_cast<std::size_t>(std::max(0, shapes)), -1);
  for (int e = 1; e < model.expression_count; ++e) {
    const std::string& name = model.expression_names[static_cast<std::size_t>(e)];
    int col = -1;
    for (std::size_t i = 0; i < names.size(); ++i)
      if (names[i] == name) col = static_cast<int>(i);
    if (col < 0) {
      const std::string arkit = arkit_name_of(name);
      for (int k = 0; k < kArkitShapeCount && col < 0; ++k)
        if (!arkit.empty() && kArkitNames[k] == arkit) col = column[k];
    }
    source[static_cast<std::size_t>(e - 1)] = col;
    if (col >= 0) {
      ++out.mapped_shapes;
    } else {
      out.unmapped.push_back(name);
    }
  }
  if (out.mapped_shapes == 0)
    return fail("take " + std::to_string(take.info.id) +
                " has no curve for any of the model's expressions (the take has ARKit names, "
                "the model should have the face model's, e.g. jawOpen, eyeBlink_L)");
  out.beta.resize(static_cast<std::size_t>(take.info.frame_count));
  for (int f = 0; f < take.info.frame_count; ++f) {
    const auto v = take.frame(f);
    auto& beta = out.beta[static_cast<std::size_t>(f)];
    beta.assign(static_cast<std::size_t>(shapes), 0.0f);
    for (int e = 0; e < shapes; ++e) {
      const int col = source[static_cast<std::size_t>(e)];
      if (col >= 0) beta[static_cast<std::size_t>(e)] = v[kTakePoseValues + col];
    }
  }
  return out;
}

Result<VideoCoefficients> video_coefficients(const BilinearModel& model,
                                             const std::vector<ImageLandmarks>& frames,
                                             const std::vector<bool>& found, int rounds) {
  std::vector<ImageLandmarks> used;
  for (std::size_t f = 0; f < frames.size(); ++f)
    if (found[f]) used.push_back(frames[f]);
  if (used.empty()) return fail("no face found in any frame of the video");
  auto joint = fit_landmarks_joint(model, used, {}, rounds);
  if (!joint) return joint.failure();
  // Columns: U_exp[0], then U_exp[i] - U_exp[0].
  const int e = model.expression_count, k = model.exp_knobs;
  Eigen::MatrixXd basis(k, e);
  for (int i = 0; i < e; ++i)
    for (int j = 0; j < k; ++j)
      basis(j, i) = model.expression_row(i)[j] - (i > 0 ? model.expression_row(0)[j] : 0.0f);
  const auto solver = basis.colPivHouseholderQr();
  VideoCoefficients out;
  out.mean_fit_error_px = joint->mean_error_px;
  std::vector<float> last(static_cast<std::size_t>(e - 1), 0.0f);
  std::size_t next = 0;
  Eigen::VectorXd neutral;
  for (std::size_t f = 0; f < frames.size(); ++f) {
    if (found[f]) {
      const auto& w = joint->images[next++].w_exp;
      Eigen::VectorXd target(k);
      for (int j = 0; j < k; ++j) target[j] = w[static_cast<std::size_t>(j)];
      const Eigen::VectorXd x = solver.solve(target);
      Eigen::VectorXd beta = x.tail(e - 1) / (std::abs(x[0]) > 1e-9 ? x[0] : 1.0);
      // The first frame with a face is the performer's neutral: what the fit puts there (their
      // shape outside the identity space, the fit's bias) is not expression.
      if (neutral.size() == 0) neutral = beta;
      for (int i = 0; i < e - 1; ++i)
        last[static_cast<std::size_t>(i)] =
            std::clamp(static_cast<float>(beta[i] - neutral[i]), 0.0f, 1.0f);
    } else {
      ++out.frames_without_face;
    }
    out.coefficients.beta.push_back(last);
  }
  out.coefficients.mapped_shapes = e - 1;
  return out;
}

Result<ColorImage> animate_photo_frame(const ColorImage& photo, const BilinearModel& model,
                                       const PhotoFace& face,
                                       const std::vector<std::uint32_t>& triangles,
                                       std::span<const float> beta, bool keep_expression,
                                       std::vector<float>& scratch, MeshWarpStats* stats) {
  scratch.resize(face.mesh.size());
  blend_image_blendshapes(
      face.blendshapes, beta,
      keep_expression ? std::span<const float>(face.mesh) : std::span<const float>(), scratch);
  return warp_face(photo, model, face.fit.pose, face.mesh, scratch, triangles, {}, stats);
}

namespace {

// The first executable `name` on PATH, or empty.
std::filesystem::path find_on_path(const std::string& name) {
  const char* path = std::getenv("PATH");
  std::istringstream dirs(path ? path : "/usr/bin:/bin");
  std::string dir;
  while (std::getline(dirs, dir, ':')) {
    if (dir.empty()) continue;
    const std::filesystem::path p = std::filesystem::path(dir) / name;
    if (::access(p.c_str(), X_OK) == 0) return p;
  }
  return {};
}

// Runs argv without a shell, output to `log`; returns the exit status.
int run_tool(const std::vector<std::string>& argv, const std::filesystem::path& log) {
  const pid_t pid = ::fork();
  if (pid < 0) return -1;
  if (pid == 0) {
    std::vector<char*> args;
    for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    if (std::FILE* f = std::fopen(log.c_str(), "w")) {
      ::dup2(::fileno(f), 1);
      ::dup2(::fileno(f), 2);
    }
    ::execv(args[0], args.data());
    ::_exit(127);
  }
  int status = 0;
  if (::waitpid(pid, &status, 0) < 0) return -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

}  // namespace

Result<std::filesystem::path> encode_frames(const std::filesystem::path& dir, int frame_count,
                                            double fps, std::string& why) {
  const std::filesystem::path log = dir / "encoder.log";
  char rate[32];
  std::snprintf(rate, sizeof rate, "%.3f", fps);
  if (const auto ffmpeg = find_on_path("ffmpeg"); !ffmpeg.empty()) {
    const auto out = dir / "animation.mp4";
    // Even sizes for yuv420p; -y: a re-run replaces the file.
    const int status =
        run_tool({ffmpeg.string(), "-y", "-loglevel", "error", "-framerate", rate, "-i",
                  (dir / "frame_%04d.png").string(), "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2", "-c:v",
                  "libx264", "-pix_fmt", "yuv420p", out.string()},
                 log);
    if (status != 0)
      return fail("ffmpeg failed (exit " + std::to_string(status) + "); see " + log.string());
    return out;
  }
  if (const auto img2webp = find_on_path("img2webp"); !img2webp.empty()) {
    const auto out = dir / "animation.webp";
    const int ms = static_cast<int>(std::lround(1000.0 / fps));
    std::vector<std::string> argv = {img2webp.string(), "-loop", "0", "-lossy", "-q", "80", "-d",
                                     std::to_string(ms)};
    char name[32];
    for (int f = 0; f < frame_count; ++f) {
      std::snprintf(name, sizeof name, "frame_%04d.png", f);
      argv.push_back((dir / name).string());
    }
    argv.insert(argv.end(), {"-o", out.string()});
    const int status = run_tool(argv, log);
    if (status != 0)
      return fail("img2webp failed (exit " + std::to_string(status) + "); see " + log.string());
    return out;
  }
  why =
      "no video encoder installed: `apt-get install ffmpeg` (MP4) or `apt-get install webp` "
      "(animated WebP, img2webp); the PNG frames are written";
  return std::filesystem::path{};
}

}  // namespace fb::cli
