#include "algo/landmarks/landmark_detector.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <optional>

#include <dlib/image_processing.h>
#include <dlib/image_processing/frontal_face_detector.h>

namespace fb {

namespace {

// Axis-aligned box as centre + size (double precision; dlib's rectangle is inclusive ints).
struct Box {
  double cx = 0, cy = 0, w = 0, h = 0;
};

Box box_of(const dlib::rectangle& r) {
  return {r.left() + r.width() / 2.0, r.top() + r.height() / 2.0, static_cast<double>(r.width()),
          static_cast<double>(r.height())};
}

dlib::rectangle rect_of(const Box& b) {
  const long left = std::lround(b.cx - b.w / 2), top = std::lround(b.cy - b.h / 2);
  return dlib::rectangle(left, top, left + std::max(1L, std::lround(b.w)) - 1,
                         top + std::max(1L, std::lround(b.h)) - 1);
}

// Bounding box of the 68 points.
Box points_box(const dlib::full_object_detection& shape) {
  double x0 = 1e30, y0 = 1e30, x1 = -1e30, y1 = -1e30;
  for (unsigned i = 0; i < shape.num_parts(); ++i) {
    x0 = std::min<double>(x0, shape.part(i).x());
    y0 = std::min<double>(y0, shape.part(i).y());
    x1 = std::max<double>(x1, shape.part(i).x());
    y1 = std::max<double>(y1, shape.part(i).y());
  }
  return {(x0 + x1) / 2, (y0 + y1) / 2, x1 - x0, y1 - y0};
}

bool inside_image(const dlib::full_object_detection& shape, long w, long h) {
  for (unsigned i = 0; i < shape.num_parts(); ++i) {
    const dlib::point p = shape.part(i);
    if (p.x() < 0 || p.y() < 0 || p.x() >= w || p.y() >= h) return false;
  }
  return true;
}

// The grey image under a box, resampled to kPatch x kPatch (nearest pixel, clamped to the
// image), zero-mean and unit-norm; all zeros when the patch is flat.
constexpr int kPatch = 24;
using Patch = std::array<float, kPatch * kPatch>;

Patch patch_of(const dlib::array2d<unsigned char>& gray, const Box& b) {
  Patch out{};
  const long w = gray.nc(), h = gray.nr();
  double mean = 0;
  for (int j = 0; j < kPatch; ++j) {
    const long y = std::clamp<long>(std::lround(b.cy + b.h * ((j + 0.5) / kPatch - 0.5)), 0, h - 1);
    for (int i = 0; i < kPatch; ++i) {
      const long x =
          std::clamp<long>(std::lround(b.cx + b.w * ((i + 0.5) / kPatch - 0.5)), 0, w - 1);
      out[j * kPatch + i] = gray[y][x];
      mean += gray[y][x];
    }
  }
  mean /= kPatch * kPatch;
  double norm = 0;
  for (float& v : out) {
    v -= static_cast<float>(mean);
    norm += double(v) * v;
  }
  if (norm < 1e-6 * kPatch * kPatch) return Patch{};
  for (float& v : out) v /= static_cast<float>(std::sqrt(norm));
  return out;
}

// Normalised cross-correlation of two patches (0 when either is flat).
double correlation(const Patch& a, const Patch& b) {
  double c = 0;
  for (std::size_t i = 0; i < a.size(); ++i) c += double(a[i]) * b[i];
  return c;
}

// The per-call scratch of ShapeCascade::operator(): each detector has its own, so one cascade
// (read-only after loading) serves several detectors on several threads.
struct CascadeScratch {
  struct LeafRef {
    const std::int16_t* values;
    float scale;
  };
  std::vector<float> features;
  std::vector<LeafRef> leaves;
};

// dlib's shape_predictor (same model file, same trees), with the trees of each cascade level
// packed into contiguous arrays (splits, leaf vectors) and evaluated in two passes: first every
// tree is walked to its leaf (the features are fixed within a level) and the leaf vector is
// prefetched, then the leaves are summed. dlib's operator() walks and sums tree by tree through
// ~7500 separately allocated trees, so the CPU mostly waits for cache misses in the 65 MB of
// leaves; this costs several times less.
// The leaves are stored as 16-bit integers with one scale per leaf vector (value = scale * q,
// scale = max |value| of that leaf / 32767): 33 MB instead of 65 MB of the device's 256 MB
// budget. A value's rounding error is <= scale / 2 (~1e-6 of the face box); it only shows where
// it moves a feature pixel across a pixel boundary and so flips a split. Measured over a head
// turn: 29 of 2040 points differ from dlib's (whole pixels) by one rounding step, mean 0.015 px
// (one scale per tree instead: 245 differ, mean 0.13 px).
struct ShapeCascade {
  struct Split {
    std::uint32_t idx1, idx2;
    float thresh;
  };
  struct Level {
    std::vector<Split> splits;
    std::vector<std::int16_t> leaves;        // leaf vectors, initial_shape.size() values each
    std::vector<float> leaf_scale;           // per leaf vector: value = leaf_scale * q
    std::vector<std::uint32_t> split_begin;  // per tree (+1 end): first split
    std::vector<std::uint32_t> leaf_begin;   // per tree: first leaf (in leaf vectors)
    std::vector<unsigned long> anchor_idx;
    std::vector<dlib::vector<float, 2>> deltas;
  };
  dlib::matrix<float, 0, 1> initial_shape;
  std::vector<Level> levels;

  unsigned long num_parts() const { return initial_shape.size() / 2; }

  // c += scale * q, eight values at a time.
  static void add_into(float* __restrict c, const std::int16_t* __restrict q, float scale, long n) {
    using V8f = float __attribute__((vector_size(32)));
    using V8s = std::int16_t __attribute__((vector_size(16)));
    long k = 0;
    for (; k + 8 <= n; k += 8) {
      V8f a;
      V8s b;
      std::memcpy(&a, c + k, sizeof a);
      std::memcpy(&b, q + k, sizeof b);
      a += __builtin_convertvector(b, V8f) * scale;
      std::memcpy(c + k, &a, sizeof a);
    }
    for (; k < n; ++k) c[k] += scale * static_cast<float>(q[k]);
  }

  void deserialize(std::istream& in) {
    int version = 0;
    dlib::deserialize(version, in);
    if (version != 1)
      throw dlib::serialization_error("unexpected version of dlib::shape_predictor");
    std::vector<std::vector<dlib::impl::regression_tree>> forests;
    std::vector<std::vector<unsigned long>> anchor_idx;
    std::vector<std::vector<dlib::vector<float, 2>>> deltas;
    dlib::deserialize(initial_shape, in);
    dlib::deserialize(forests, in);
    dlib::deserialize(anchor_idx, in);
    dlib::deserialize(deltas, in);
    if (anchor_idx.size() != forests.size() || deltas.size() != forests.size())
      throw dlib::serialization_error("inconsistent shape_predictor cascade");
    const long n = initial_shape.size();
    levels.clear();
    levels.resize(forests.size());
    for (std::size_t l = 0; l < forests.size(); ++l) {
      Level& level = levels[l];
      level.anchor_idx = std::move(anchor_idx[l]);
      level.deltas = std::move(deltas[l]);
      std::size_t leaf_values = 0;
      for (const auto& tree : forests[l]) leaf_values += tree.leaf_values.size() * n;
      level.leaves.reserve(leaf_values);
      level.leaf_scale.reserve(leaf_values / n);
      std::uint32_t leaf_count = 0;
      for (const auto& tree : forests[l]) {
        if (tree.leaf_values.size() != tree.splits.size() + 1)
          throw dlib::serialization_error("shape_predictor tree is not complete");
        level.split_begin.push_back(static_cast<std::uint32_t>(level.splits.size()));
        level.leaf_begin.push_back(leaf_count);
        for (const auto& sp : tree.splits) {
          if (sp.idx1 >= level.deltas.size() || sp.idx2 >= level.deltas.size())
            throw dlib::serialization_error("shape_predictor split uses an unknown pixel");
          level.splits.push_back({static_cast<std::uint32_t>(sp.idx1),
                                  static_cast<std::uint32_t>(sp.idx2), sp.thresh});
        }
        for (const auto& leaf : tree.leaf_values) {
          if (leaf.size() != n)
            throw dlib::serialization_error("shape_predictor leaf has the wrong size");
          float largest = 0;
          for (float v : leaf) largest = std::max(largest, std::abs(v));
          const float scale = largest > 0 ? largest / 32767.0f : 1.0f;
          level.leaf_scale.push_back(scale);
          for (float v : leaf)
            level.leaves.push_back(static_cast<std::int16_t>(std::lround(v / scale)));
          ++leaf_count;
        }
      }
      level.split_begin.push_back(static_cast<std::uint32_t>(level.splits.size()));
      std::vector<dlib::impl::regression_tree>().swap(forests[l]);  // free as we go
    }
  }

  dlib::full_object_detection operator()(const dlib::array2d<unsigned char>& img,
                                         const dlib::rectangle& rect,
                                         CascadeScratch& scratch) const {
    auto& features = scratch.features;
    auto& leaves = scratch.leaves;
    dlib::matrix<float, 0, 1> shape = initial_shape;
    const long n = shape.size();
    float* c = &shape(0);
    for (const Level& level : levels) {
      dlib::impl::extract_feature_pixel_values(img, rect, shape, initial_shape, level.anchor_idx,
                                               level.deltas, features);
      const std::size_t trees = level.leaf_begin.size();
      leaves.resize(trees);
      for (std::size_t t = 0; t < trees; ++t) {
        const Split* splits = level.splits.data() + level.split_begin[t];
        const std::uint32_t count = level.split_begin[t + 1] - level.split_begin[t];
        std::uint32_t i = 0;
        while (i < count)
          i = features[splits[i].idx1] - features[splits[i].idx2] > splits[i].thresh ? 2 * i + 1
                                                                                     : 2 * i + 2;
        const std::uint32_t leaf_index = level.leaf_begin[t] + i - count;
        const std::int16_t* leaf = level.leaves.data() + static_cast<std::size_t>(leaf_index) * n;
        leaves[t] = {leaf, level.leaf_scale[leaf_index]};
        __builtin_prefetch(leaf);
      }
      // Sum in tree order, prefetching a few leaves ahead.
      constexpr std::size_t kAhead = 6;
      for (std::size_t t = 0; t < trees; ++t) {
        if (t + kAhead < trees)
          for (long k = 0; k < n; k += 32) __builtin_prefetch(leaves[t + kAhead].values + k);
        add_into(c, leaves[t].values, leaves[t].scale, n);
      }
    }
    const dlib::point_transform_affine to_image = dlib::impl::unnormalizing_tform(rect);
    std::vector<dlib::point> parts(static_cast<std::size_t>(n / 2));
    for (std::size_t i = 0; i < parts.size(); ++i)
      parts[i] = to_image(dlib::impl::location(shape, static_cast<unsigned long>(i)));
    return dlib::full_object_detection(rect, parts);
  }
};

// The re-detection window's face size: the frontal detector's template is 80 px and its pyramid
// steps by 6/5, so a face of 96 px is found on the second level; four levels then cover faces
// of 5/6 to (6/5)^2 = 1.44 times the last one. (With three, a face that came 1.6x nearer was
// still found, on the top level, but with a box 0.7x its size: 3.9 px point error against 2.8.)
constexpr double kWindowFacePx = 96.0;
constexpr unsigned long kWindowPyramidLevels = 4;

// dlib's frontal face detector (same filters) scanning only the first pyramid levels.
dlib::frontal_face_detector window_detector_of(const dlib::frontal_face_detector& full) {
  dlib::frontal_face_detector::image_scanner_type scanner;
  scanner.copy_configuration(full.get_scanner());
  scanner.set_max_pyramid_levels(kWindowPyramidLevels);
  std::vector<dlib::frontal_face_detector::feature_vector_type> filters;
  for (unsigned long i = 0; i < full.num_detectors(); ++i) filters.push_back(full.get_w(i));
  return dlib::frontal_face_detector(scanner, full.get_overlap_tester(), filters);
}

// A face box the detector found, with its HOG margin.
using FaceCandidate = std::pair<double, dlib::rectangle>;

}  // namespace

struct LandmarkDetector::State {
  LandmarkDetectorOptions options;
  dlib::frontal_face_detector detector = dlib::get_frontal_face_detector();
  dlib::frontal_face_detector window_detector = window_detector_of(detector);
  std::shared_ptr<const ShapeCascade> predictor;  // read-only, shared by share()
  CascadeScratch scratch;
  dlib::array2d<unsigned char> gray;    // whole image, reused
  dlib::array2d<unsigned char> window;  // tracking window, reused
  std::optional<dlib::rectangle> last;  // the box the predictor last ran on
  std::optional<Box> last_points;       // bounding box of the last frame's points
  Patch last_patch{};                   // the grey image under it
  // Detector box relative to the points' bounding box at the last real detection: centre
  // offset in units of the points' box size, and size ratio.
  double map_dx = 0, map_dy = 0, map_sw = 1, map_sh = 1;
  double last_score = 0;    // HOG margin of the last real detection
  int since_detection = 0;  // frames tracked from points since then

  void forget() {
    last.reset();
    last_points.reset();
    since_detection = 0;
  }

  // Grey conversion of [x0, x1) x [y0, y1); frames tracked from points convert only a window
  // around the face (the predictor's pixels lie within the face box).
  void to_gray(const ColorImage& image, long x0, long y0, long x1, long y1) {
    for (long y = y0; y < y1; ++y)
      for (long x = x0; x < x1; ++x) {
        const Rgb8 p = image.at(static_cast<int>(x), static_cast<int>(y));
        // Rec. 601 luma in integer arithmetic.
        gray[y][x] = static_cast<unsigned char>((77 * p.r + 150 * p.g + 29 * p.b) >> 8);
      }
  }

  DetectedLandmarks result(const dlib::rectangle& r, const dlib::full_object_detection& shape,
                           bool tracked, bool from_landmarks) const {
    DetectedLandmarks out;
    out.face = PixelRect::from_size(static_cast<int>(r.left()), static_cast<int>(r.top()),
                                    static_cast<int>(r.width()), static_cast<int>(r.height()));
    out.tracked = tracked;
    out.from_landmarks = from_landmarks;
    out.detection_score = last_score;
    out.frames_since_detection = since_detection;
    for (unsigned i = 0; i < 68; ++i)
      out.points[i] = Eigen::Vector2d(shape.part(i).x(), shape.part(i).y());
    return out;
  }

  // Tracking from points: the previous frame's points, mapped to a detector-style box. Empty
  // when the result is implausible (the detector then runs on this frame).
  std::optional<DetectedLandmarks> track_from_points(const ColorImage& image) {
    const LandmarkDetectorOptions& o = options;
    const int w = image.width, h = image.height;
    const Box& p = *last_points;
    const dlib::rectangle r =
        rect_of({p.cx + map_dx * p.w, p.cy + map_dy * p.h, map_sw * p.w, map_sh * p.h});
    const Box g = box_of(r);
    const double hw = g.w * o.track_window_scale / 2, hh = g.h * o.track_window_scale / 2;
    const long gx0 = std::clamp<long>(std::lround(g.cx - hw), 0, w),
               gy0 = std::clamp<long>(std::lround(g.cy - hh), 0, h),
               gx1 = std::clamp<long>(std::lround(g.cx + hw), 0, w),
               gy1 = std::clamp<long>(std::lround(g.cy + hh), 0, h);
    to_gray(image, gx0, gy0, gx1, gy1);
    const dlib::full_object_detection shape = (*predictor)(gray, r, scratch);
    const Box b = points_box(shape);
    const bool in_region = b.cx - b.w / 2 >= gx0 && b.cy - b.h / 2 >= gy0 && b.cx + b.w / 2 < gx1 &&
                           b.cy + b.h / 2 < gy1;
    const Patch patch = patch_of(gray, b);
    const bool plausible =
        in_region && correlation(patch, last_patch) >= o.min_appearance_correlation &&
        inside_image(shape, w, h) && std::abs(b.w / p.w - 1) <= o.max_box_size_change &&
        std::abs(b.h / p.h - 1) <= o.max_box_size_change &&
        std::hypot(b.cx - p.cx, b.cy - p.cy) <= o.max_box_shift * std::max(p.w, p.h);
    if (!plausible) return std::nullopt;
    ++since_detection;
    last = r;
    last_points = b;
    last_patch = patch;
    return result(r, shape, true, true);
  }

  // Face-region tracking: detect in a window around the last face only. The face cannot
  // change size much since the last frame, so the window is resampled to put the last face
  // at the HOG template's second pyramid level (80 px * 6/5 = 96 px) and only levels 0-3
  // are scanned (faces 5/6 to 1.44x the last size). At full resolution the detector would
  // scan every level from the window's size down to 64 px, several times the pixels.
  std::vector<FaceCandidate> detect_in_window(const ColorImage& image) {
    std::vector<FaceCandidate> found;
    const int w = image.width, h = image.height;
    const dlib::rectangle& r = *last;
    const double scale = options.track_window_scale;
    const long cw = static_cast<long>(r.width() * scale),
               ch = static_cast<long>(r.height() * scale);
    const long x0 = std::clamp<long>(dlib::center(r).x() - cw / 2, 0, w - 1);
    const long y0 = std::clamp<long>(dlib::center(r).y() - ch / 2, 0, h - 1);
    const long x1 = std::min<long>(x0 + cw, w), y1 = std::min<long>(y0 + ch, h);
    const double shrink = std::min(1.0, kWindowFacePx / double(std::max(r.width(), r.height())));
    const long sw = std::lround((x1 - x0) * shrink), sh = std::lround((y1 - y0) * shrink);
    if (sw < 80 || sh < 80) return found;
    to_gray(image, x0, y0, x1, y1);
    const auto region = dlib::sub_image(gray, dlib::rectangle(x0, y0, x1 - 1, y1 - 1));
    window.set_size(sh, sw);
    if (shrink < 1.0)
      dlib::resize_image(region, window, dlib::interpolate_bilinear());
    else
      dlib::assign_image(window, region);
    std::vector<dlib::rect_detection> dets;
    window_detector(window, dets, 0.0);
    const double grow = double(x1 - x0) / sw, grow_y = double(y1 - y0) / sh;
    for (const auto& d : dets) {
      const dlib::drectangle full(x0 + d.rect.left() * grow, y0 + d.rect.top() * grow_y,
                                  x0 + (d.rect.right() + 1) * grow - 1,
                                  y0 + (d.rect.bottom() + 1) * grow_y - 1);
      found.emplace_back(d.detection_confidence,
                         dlib::rectangle(std::lround(full.left()), std::lround(full.top()),
                                         std::lround(full.right()), std::lround(full.bottom())));
    }
    return found;
  }

  // The frontal detector over the whole (grey) image, upsampled first when asked.
  std::vector<FaceCandidate> detect_in_image() {
    std::vector<FaceCandidate> found;
    std::vector<dlib::rect_detection> dets;
    dlib::array2d<unsigned char> up;
    if (options.upsample > 0) {
      dlib::assign_image(up, gray);
      dlib::pyramid_up(up);
      detector(up, dets, 0.0);
      for (auto& d : dets)
        d.rect = dlib::rectangle(d.rect.left() / 2, d.rect.top() / 2, d.rect.right() / 2,
                                 d.rect.bottom() / 2);
    } else {
      detector(gray, dets, 0.0);
    }
    for (const auto& d : dets) found.emplace_back(d.detection_confidence, d.rect);
    return found;
  }

  // The points on the largest face found (the subject: people behind are smaller), and what
  // the next frames track from.
  DetectedLandmarks predict_on_largest(const std::vector<FaceCandidate>& found, bool tracked) {
    const auto best = std::max_element(
        found.begin(), found.end(),
        [](const auto& a, const auto& b) { return a.second.area() < b.second.area(); });
    const dlib::full_object_detection shape = (*predictor)(gray, best->second, scratch);
    // Learn the points' box -> detector box mapping for the frames tracked from points.
    const Box d = box_of(best->second), p = points_box(shape);
    if (p.w >= 1 && p.h >= 1) {
      map_dx = (d.cx - p.cx) / p.w;
      map_dy = (d.cy - p.cy) / p.h;
      map_sw = d.w / p.w;
      map_sh = d.h / p.h;
      last_points = p;
      last_patch = patch_of(gray, p);
    } else {
      last_points.reset();  // degenerate shape: the next frame runs the detector again
    }
    last = best->second;
    last_score = best->first;
    since_detection = 0;
    return result(best->second, shape, tracked, false);
  }
};

LandmarkDetector::LandmarkDetector(std::unique_ptr<State> state) : state_(std::move(state)) {}
LandmarkDetector::LandmarkDetector(LandmarkDetector&&) noexcept = default;
LandmarkDetector& LandmarkDetector::operator=(LandmarkDetector&&) noexcept = default;
LandmarkDetector::~LandmarkDetector() = default;

Result<LandmarkDetector> LandmarkDetector::create(std::istream& shape_predictor,
                                                  const LandmarkDetectorOptions& options) {
  auto s = std::make_unique<State>();
  s->options = options;
  auto cascade = std::make_shared<ShapeCascade>();
  try {
    cascade->deserialize(shape_predictor);
  } catch (const std::exception& e) {
    return fail(std::string("landmarks: cannot read the shape predictor (expected dlib's "
                            "shape_predictor_68_face_landmarks.dat): ") +
                e.what());
  }
  if (cascade->num_parts() != 68)
    return fail("landmarks: the shape predictor has " + std::to_string(cascade->num_parts()) +
                " points, expected the 68-point iBUG model");
  s->predictor = std::move(cascade);
  return LandmarkDetector(std::move(s));
}

LandmarkDetector LandmarkDetector::share() const {
  auto s = std::make_unique<State>();
  s->options = state_->options;
  s->predictor = state_->predictor;
  return LandmarkDetector(std::move(s));
}

void LandmarkDetector::reset_tracking() {
  state_->forget();
}

Result<DetectedLandmarks> LandmarkDetector::detect(const ColorImage& image) {
  State& s = *state_;
  if (image.empty()) return fail("landmarks: the colour image is empty");
  const int w = image.width, h = image.height;
  try {
    if (s.gray.nr() != h || s.gray.nc() != w) {
      s.forget();  // a new image size: nothing carried over
      s.gray.set_size(h, w);
    }
    const LandmarkDetectorOptions& o = s.options;
    if (o.track && o.track_landmarks && s.last && s.last_points &&
        (o.redetect_every <= 0 || s.since_detection < o.redetect_every))
      if (auto from_points = s.track_from_points(image)) return *from_points;
    std::vector<FaceCandidate> found;
    if (o.track && s.last) found = s.detect_in_window(image);
    const bool tracked = !found.empty();
    // The predictor reads pixels around the box it runs on: a face found in the window has
    // them converted already (the window is track_window_scale times the face); otherwise the
    // whole image is needed.
    if (!tracked) s.to_gray(image, 0, 0, w, h);
    if (found.empty()) found = s.detect_in_image();
    if (found.empty()) {
      s.forget();
      return fail("landmarks: no face found in the colour image");
    }
    return s.predict_on_largest(found, tracked);
  } catch (const std::exception& e) {
    s.forget();
    return fail(std::string("landmarks: dlib failed: ") + e.what());
  }
}

}  // namespace fb
