// `facebooth photo animate` and `facebooth photo edit`: the bilinear model on a photograph
// (FaceWarehouse 4.3 and 4.1). The photo's 68 landmarks (dlib, or a file), the model fitted
// under weak perspective, then either the image blendshapes driven by a stored take's
// coefficients, frame by frame, or the identity moved by the attribute regression; each result
// is the photo re-rendered by the mesh warp (algo/photo).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <numeric>

#include <nlohmann/json.hpp>

#include "algo/photo/photo_face.hpp"
#include "host/cli/commands.hpp"
#include "host/cli/photo_pipeline.hpp"
#include "host/cli/progress.hpp"
#include "host/cli/tracker_setup.hpp"
#include "storage/durable_file.hpp"

namespace fb::cli {

namespace {

struct LoadedPhoto {
  ColorImage image;
  ImageLandmarks landmarks;
  std::string landmark_source;
  BilinearModel model;
  PhotoFace face;
};

Result<BilinearModel> read_model(const std::string& path) {
  if (path.empty())
    return fail(
        "give --model FILE (a bilinear model: `facebooth model build --from-face-model "
        "--exp-knobs 54 --out FILE`)");
  auto bytes = read_file_bytes(path);
  if (!bytes)
    return fail(bytes.error().message +
                " (a bilinear model is written by `facebooth model build --out FILE`)");
  auto parsed = parse_bilinear_model(std::as_bytes(std::span(*bytes)));
  if (!parsed) return fail(path + ": " + parsed.error().message);
  return parsed;
}

// Photo, landmarks, model and the fit: what both commands start from.
Result<LoadedPhoto> load_and_fit(const ParsedOptions& options, const std::string& command) {
  LoadedPhoto out;
  const std::string in = options.get("in");
  if (in.empty()) return fail("give --in PHOTO.png");
  auto image = read_photo(in);
  if (!image) return image.failure();
  out.image = std::move(*image);
  if (const std::string file = options.get("landmarks"); !file.empty()) {
    auto l = read_landmarks_file(file);
    if (!l) return l.failure();
    out.landmarks = *l;
    out.landmark_source = file;
  } else {
    auto detector = load_landmark_detector(options.get("shape-predictor"));
    if (!detector) return detector.failure();
    auto l = detect_photo_landmarks(*detector, out.image, in);
    if (!l) return l.failure();
    out.landmarks = *l;
    out.landmark_source = "dlib";
  }
  std::cerr << command << ": loading the bilinear model " << options.get("model") << "...\n";
  auto model = read_model(options.get("model"));
  if (!model) return model.failure();
  out.model = std::move(*model);
  if (out.model.expression_names.empty() || out.model.expression_names.front() != "neutral")
    return fail(options.get("model") + ": the model has no neutral expression first");
  auto face = fit_photo_face(out.model, out.landmarks);
  if (!face) return face.failure();
  out.face = std::move(*face);
  return out;
}

nlohmann::json fit_json(const LoadedPhoto& p) {
  const auto& pose = p.face.fit.pose;
  // The head's turn from frontal: the model frame (+Y up, +Z out of the face) seen from the
  // front is diag(1, -1, -1) in image axes (y down, z into the picture).
  const Eigen::Matrix3d head = Eigen::Vector3d(1, -1, -1).asDiagonal() * pose.rotation;
  // Yaw about y, pitch about x, roll about z (Eigen's eulerAngles folds small negative
  // angles to near 180 deg).
  const double deg = 180.0 / M_PI;
  const Eigen::Vector3d ypr(std::atan2(head(0, 2), head(2, 2)) * deg,
                            std::asin(std::clamp(-head(1, 2), -1.0, 1.0)) * deg,
                            std::atan2(head(1, 0), head(1, 1)) * deg);
  return {{"landmarks", p.landmark_source},
          {"landmark_fit_error_px", p.face.fit.mean_error_px},
          {"scale_px_per_mm", pose.scale},
          {"model_knobs", {p.model.id_knobs, p.model.exp_knobs}},
          {"model_identities", p.model.identity_count},
          {"head_yaw_pitch_roll_deg", {ypr.x(), ypr.y(), ypr.z()}}};
}

// Strip frames: the K frames whose face moved most (largest shift of a pixel), at least
// frames/(K+1) apart.
std::vector<int> strip_frames(const std::vector<double>& shift, int k) {
  std::vector<int> order(shift.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    return shift[static_cast<std::size_t>(a)] > shift[static_cast<std::size_t>(b)];
  });
  const int gap = static_cast<int>(shift.size()) / (k + 1);
  std::vector<int> out;
  for (int f : order) {
    if (static_cast<int>(out.size()) == k) break;
    if (std::all_of(out.begin(), out.end(), [&](int g) { return std::abs(g - f) >= gap; }))
      out.push_back(f);
  }
  std::sort(out.begin(), out.end());
  return out;
}

// The photo and the strip frames side by side, cropped around the face.
ColorImage make_strip(const ColorImage& photo, const std::vector<ColorImage>& frames,
                      const ImageLandmarks& l) {
  double x0 = 1e9, x1 = -1e9, y0 = 1e9, y1 = -1e9;
  for (int k = 0; k < 68; ++k) {
    if (!l.valid[static_cast<std::size_t>(k)]) continue;
    const auto& p = l.points[static_cast<std::size_t>(k)];
    x0 = std::min(x0, p.x());
    x1 = std::max(x1, p.x());
    y0 = std::min(y0, p.y());
    y1 = std::max(y1, p.y());
  }
  const double cx = (x0 + x1) / 2, cy = (y0 + y1) / 2 - 0.1 * (y1 - y0);
  const double half = 0.8 * std::max(x1 - x0, y1 - y0);
  const int size = std::max(8, static_cast<int>(2 * half));
  const int left = static_cast<int>(cx - half), top = static_cast<int>(cy - half);
  ColorImage strip;
  strip.resize(size * static_cast<int>(frames.size() + 1) + 4 * static_cast<int>(frames.size()),
               size);
  std::fill(strip.pixels.begin(), strip.pixels.end(), Rgb8{255, 255, 255});
  for (std::size_t i = 0; i <= frames.size(); ++i) {
    const ColorImage& src = i == 0 ? photo : frames[i - 1];
    const int ox = static_cast<int>(i) * (size + 4);
    for (int y = 0; y < size; ++y)
      for (int x = 0; x < size; ++x) {
        const int sx = std::clamp(left + x, 0, src.width - 1);
        const int sy = std::clamp(top + y, 0, src.height - 1);
        strip.at(ox + x, y) = src.at(sx, sy);
      }
  }
  return strip;
}

// The driving coefficients: a stored take's, or (--video) a folder of frames' (4.4).
struct Driver {
  TakeCoefficients coefficients;
  double fps = 30;
  nlohmann::json report;
};

Result<Driver> take_driver(const ParsedOptions& options, const BilinearModel& model) {
  const std::string store_dir = options.get("store");
  auto take_id = options.get_int("take");
  if (store_dir.empty() || !take_id || *take_id <= 0)
    return fail(
        "give --store DIR and --take ID (`facebooth store info --store DIR` lists the "
        "takes), or --video DIR");
  StoreOptions so;
  so.read_only = true;
  so.create = false;
  auto store = SessionStore::open(store_dir, so);
  if (!store) return store.failure();
  auto take = store->read_take(*take_id);
  if (!take) return take.failure();
  if (take->info.frame_count == 0)
    return fail("take " + std::to_string(*take_id) + " has no frames");
  auto c = take_coefficients(*take, model);
  if (!c) return c.failure();
  Driver d{std::move(*c), take->info.fps, {{"take", *take_id}}};
  d.report["model_shapes_not_in_take"] = d.coefficients.unmapped;
  return d;
}

Result<Driver> video_driver(const ParsedOptions& options, const BilinearModel& model) {
  const std::filesystem::path dir = options.get("video");
  std::vector<std::filesystem::path> files;
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(dir, ec)) {
    const auto ext = entry.path().extension().string();
    if (ext == ".png" || ext == ".jpg" || ext == ".jpeg") files.push_back(entry.path());
  }
  if (ec) return fail("cannot read the video folder " + dir.string() + ": " + ec.message());
  if (files.empty()) return fail(dir.string() + " has no .png or .jpg frames");
  std::sort(files.begin(), files.end());
  auto detector = load_landmark_detector(options.get("shape-predictor"));
  if (!detector) return detector.failure();
  std::vector<ImageLandmarks> points(files.size());
  std::vector<bool> found(files.size(), false);
  Progress progress("photo animate: video landmarks", static_cast<long long>(files.size()));
  for (std::size_t f = 0; f < files.size(); ++f) {
    auto image = read_photo(files[f]);
    if (!image) return image.failure();
    if (auto l = detector->detect(*image); l) {
      points[f].points = l->points;
      points[f].valid.fill(true);
      found[f] = true;
    }
    progress.update(static_cast<long long>(f) + 1);
  }
  auto c = video_coefficients(model, points, found);
  if (!c) return c.failure();
  auto fps = options.get_double("fps");
  if (!fps || *fps <= 0) return fail("--fps must be a positive number");
  Driver d{std::move(c->coefficients), *fps, {{"video_frames_dir", dir.string()}}};
  d.report["video_frames"] = files.size();
  d.report["video_frames_without_face"] = c->frames_without_face;
  d.report["video_joint_fit_error_px"] = c->mean_fit_error_px;
  return d;
}

int run_animate(const ParsedOptions& options) {
  const std::string out_dir = options.get("out");
  if (out_dir.empty()) return report_failure({"give --out DIR for the frames"});
  auto every = options.get_int("every");
  if (!every || *every < 1) return report_failure({"--every must be a whole number >= 1"});
  auto loaded = load_and_fit(options, "photo animate");
  if (!loaded) return report_failure(loaded.error());
  auto driver = options.get("video").empty() ? take_driver(options, loaded->model)
                                             : video_driver(options, loaded->model);
  if (!driver) return report_failure(driver.error());
  const TakeCoefficients* coefficients = &driver->coefficients;
  std::error_code ec;
  std::filesystem::create_directories(out_dir, ec);
  if (ec) return report_failure({"cannot create " + out_dir + ": " + ec.message()});

  const auto triangles = face_region_triangles(loaded->model);
  const bool keep = !options.flag("replace-expression");
  std::vector<float> scratch;
  std::vector<int> frames;
  const int frame_count = static_cast<int>(coefficients->beta.size());
  for (int f = 0; f < frame_count; f += static_cast<int>(*every)) frames.push_back(f);
  Progress progress("photo animate", static_cast<int>(frames.size()));
  const auto start = std::chrono::steady_clock::now();
  double max_shift = 0;
  const std::string strip_path = options.get("strip");
  std::vector<double> shifts;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    MeshWarpStats stats;
    auto frame = animate_photo_frame(loaded->image, loaded->model, loaded->face, triangles,
                                     coefficients->beta[static_cast<std::size_t>(frames[i])], keep,
                                     scratch, &stats);
    if (!frame) return report_failure(frame.error());
    max_shift = std::max(max_shift, stats.max_shift_px);
    char name[32];
    std::snprintf(name, sizeof name, "frame_%04d.png", static_cast<int>(i));
    if (auto w = write_photo(*frame, std::filesystem::path(out_dir) / name); !w)
      return report_failure(w.error());
    shifts.push_back(stats.max_shift_px);
    progress.update(static_cast<int>(i) + 1);
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  nlohmann::json out = fit_json(*loaded);
  out.update(driver->report);
  out["frames"] = frames.size();
  out["fps"] = driver->fps / static_cast<double>(*every);
  out["model_shapes_driven"] = coefficients->mapped_shapes;
  out["max_shift_px"] = max_shift;
  out["ms_per_frame"] = 1000.0 * seconds / static_cast<double>(frames.size());
  out["out"] = out_dir;
  std::string why;
  auto video = encode_frames(out_dir, static_cast<int>(frames.size()), out["fps"], why);
  if (!video) return report_failure(video.error());
  if (video->empty()) {
    out["video"] = nullptr;
    std::cerr << "photo animate: " << why << "\n";
    out["video_note"] = why;
  } else {
    out["video"] = video->string();
  }
  if (!strip_path.empty()) {
    std::vector<ColorImage> strip_images;
    for (int i : strip_frames(shifts, 3)) {
      char name[32];
      std::snprintf(name, sizeof name, "frame_%04d.png", i);
      auto frame = read_photo(std::filesystem::path(out_dir) / name);
      if (!frame) return report_failure(frame.error());
      strip_images.push_back(std::move(*frame));
    }
    if (auto w =
            write_photo(make_strip(loaded->image, strip_images, loaded->landmarks), strip_path);
        !w)
      return report_failure(w.error());
    out["strip"] = strip_path;
  }
  std::cout << out.dump(2) << "\n";
  return kExitOk;
}

// "face_length=+10mm" -> (index, 10). Errors list the attributes.
Result<std::pair<int, double>> parse_attribute(const std::string& text,
                                               const std::vector<AttributeDefinition>& known) {
  std::string names;
  for (const auto& a : known) names += (names.empty() ? "" : ", ") + a.name;
  const auto eq = text.find('=');
  if (eq == std::string::npos)
    return fail("--attribute '" + text + "': expected NAME=CHANGE, e.g. face_length=+10mm");
  const std::string name = text.substr(0, eq);
  std::string value = text.substr(eq + 1);
  int index = -1;
  for (std::size_t i = 0; i < known.size(); ++i)
    if (known[i].name == name) index = static_cast<int>(i);
  if (index < 0) return fail("unknown attribute '" + name + "'; the attributes are " + names);
  if (value.size() > 2 && value.substr(value.size() - 2) == "mm") value.resize(value.size() - 2);
  char* end = nullptr;
  const double v = std::strtod(value.c_str(), &end);
  if (value.empty() || end == nullptr || *end != '\0' || !std::isfinite(v))
    return fail("--attribute " + name + ": '" + text.substr(eq + 1) +
                "' is not a change in millimetres (e.g. +10mm, -4, 2.5mm)");
  if (std::abs(v) > 60)
    return fail("--attribute " + name + ": " + text.substr(eq + 1) +
                " is more than 60 mm; faces do not change that much");
  return std::pair<int, double>{index, v};
}

// An edit keeps the photo's mouth as it is: no cavity where the lips part slightly.
const MeshWarpOptions kClosedMouth{.mouth_cavity = false};

int run_edit(const ParsedOptions& options) {
  const std::string out_path = options.get("out");
  if (out_path.empty()) return report_failure({"give --out EDITED.png"});
  const auto known = default_attributes();
  std::vector<double> change(known.size(), 0.0);
  const auto requested = options.all("attribute");
  if (requested.empty())
    return report_failure(
        {"give at least one --attribute NAME=CHANGE, e.g. face_length=+10mm "
         "(`facebooth photo edit --help` lists them)"});
  for (const auto& text : requested) {
    auto a = parse_attribute(text, known);
    if (!a) return report_failure(a.error());
    change[static_cast<std::size_t>(a->first)] += a->second;
  }
  auto loaded = load_and_fit(options, "photo edit");
  if (!loaded) return report_failure(loaded.error());
  const BilinearModel& model = loaded->model;
  auto regression = fit_attribute_regression(model, known);
  if (!regression) return report_failure(regression.error());
  const auto w_id = apply_attribute_change(*regression, loaded->face.fit.w_id, change);
  std::vector<float> edited(loaded->face.mesh.size());
  model.evaluate(w_id, loaded->face.fit.w_exp, edited);
  MeshWarpStats stats;
  auto image = warp_face(loaded->image, model, loaded->face.fit.pose, loaded->face.mesh, edited,
                         face_region_triangles(model), kClosedMouth, &stats);
  if (!image) return report_failure(image.error());
  if (auto w = write_photo(*image, out_path); !w) return report_failure(w.error());
  // The attributes on the neutral of the fitted identity, before and after.
  std::vector<float> neutral(edited.size());
  model.evaluate(loaded->face.fit.w_id, model.expression_row(0), neutral);
  const auto before = measure_attributes(neutral, model.landmark_vertices, known);
  model.evaluate(w_id, model.expression_row(0), neutral);
  const auto after = measure_attributes(neutral, model.landmark_vertices, known);
  nlohmann::json out = fit_json(*loaded);
  for (std::size_t i = 0; i < known.size(); ++i)
    out["attributes_mm"][known[i].name] = {{"requested_change", change[i]},
                                           {"before", before[i]},
                                           {"after", after[i]},
                                           {"change", after[i] - before[i]}};
  out["max_shift_px"] = stats.max_shift_px;
  out["out"] = out_path;
  std::cout << out.dump(2) << "\n";
  return kExitOk;
}

const std::vector<OptionSpec> kPhotoInput = {
    {"in", "PHOTO", "the photograph (PNG or JPEG), one frontal face", ""},
    {"model", "FILE",
     "bilinear model (`facebooth model build --from-face-model --exp-knobs 54 --out FILE`)", ""},
    {"landmarks", "FILE", "the 68 points (iBUG order, one 'x y' line each) instead of dlib", ""},
    {"shape-predictor", "FILE", "dlib's 68-point model (default: Debian libdlib-data's)", ""}};

std::string attribute_list() {
  std::string s;
  for (const auto& a : default_attributes())
    s += "  " + a.name + ": landmarks " + std::to_string(a.landmark_a) + " - " +
         std::to_string(a.landmark_b) + " of the neutral mesh\n";
  return s;
}

}  // namespace

std::vector<Command> photo_commands() {
  std::vector<OptionSpec> animate = kPhotoInput;
  animate.insert(
      animate.end(),
      {{"store", "DIR", "session store holding the take", ""},
       {"take", "ID", "the take whose expressions animate the photo", ""},
       {"video", "DIR", "instead of a take: a performer's frames (PNG/JPEG, name order; 4.4)", ""},
       {"fps", "N", "the --video frame rate", "30"},
       {"out", "DIR", "folder for frame_NNNN.png (and animation.mp4 or .webp)", ""},
       {"every", "K", "render every K-th frame of the take", "1"},
       {"replace-expression", "",
        "the take's expressions replace the photo's fitted one (B_0 + sum beta (B_i - "
        "B_0), as the paper) instead of adding to it",
        ""},
       {"strip", "FILE", "also write the photo beside the 3 frames that move most (PNG)", ""}});
  std::vector<OptionSpec> edit = kPhotoInput;
  edit.insert(edit.end(), {{"attribute", "NAME=CHANGE",
                            "an attribute change in mm, e.g. face_length=+10mm (repeatable)", ""},
                           {"out", "FILE", "the edited photo (PNG)", ""}});
  return {
      {{"photo animate", "a photograph animated by a stored take (FaceWarehouse 4.3)",
        "The bilinear model is fitted to the photo's 68 landmarks (weak perspective, eq. 13-14), "
        "its image blendshapes B_i = C x2 w_id x3 U_exp[i] built (eq. 17) and driven by the "
        "take's per-frame coefficients (its ARKit curves mapped onto the model's shapes: "
        "browInnerUp and cheekPuff feed both halves), added to the photo's own expression "
        "(--replace-expression: instead of it). Each frame is the photo re-rendered by a "
        "triangle warp of the projected mesh (colours from the photo, the background kept, the "
        "mouth opening dark). The head stays where the photo has it: the take's head motion is "
        "not applied. With --video instead of a take (4.4): dlib on every frame, one identity "
        "fitted jointly over them, each frame's expression weights written in the model's "
        "expressions (less the first frame's: the video starts neutral), clamped to [0, 1]. "
        "Writes frame_NNNN.png and, when ffmpeg or img2webp is installed, "
        "animation.mp4 or animation.webp. Prints a JSON summary.",
        animate},
       run_animate},
      {{"photo edit", "a photograph's face attributes changed (FaceWarehouse 4.1)",
        "The bilinear model is fitted to the photo's landmarks; the attribute regression "
        "(M_fea = W_id F^+, eq. 11-12, over the model's training identities) turns the requested "
        "changes into an identity change, the others held; the photo is re-rendered by the mesh "
        "warp. Millimetres are the model's (a photo under weak perspective has no absolute "
        "size). Attributes:\n" +
            attribute_list() + "Prints the attributes before and after as JSON.",
        edit},
       run_edit}};
}

}  // namespace fb::cli
