#include "algo/landmarks/landmark_detector.hpp"

#include <algorithm>
#include <optional>

#include <dlib/image_processing.h>
#include <dlib/image_processing/frontal_face_detector.h>

namespace fb {

struct LandmarkDetector::State {
  LandmarkDetectorOptions options;
  dlib::frontal_face_detector detector = dlib::get_frontal_face_detector();
  dlib::shape_predictor predictor;
  dlib::array2d<unsigned char> gray;    // whole image, reused
  dlib::array2d<unsigned char> window;  // tracking window, reused
  std::optional<dlib::rectangle> last;
};

LandmarkDetector::LandmarkDetector(std::unique_ptr<State> state) : state_(std::move(state)) {}
LandmarkDetector::LandmarkDetector(LandmarkDetector&&) noexcept = default;
LandmarkDetector& LandmarkDetector::operator=(LandmarkDetector&&) noexcept = default;
LandmarkDetector::~LandmarkDetector() = default;

Result<LandmarkDetector> LandmarkDetector::create(std::istream& shape_predictor,
                                                  const LandmarkDetectorOptions& options) {
  auto s = std::make_unique<State>();
  s->options = options;
  try {
    dlib::deserialize(s->predictor, shape_predictor);
  } catch (const std::exception& e) {
    return fail(std::string("landmarks: cannot read the shape predictor (expected dlib's "
                            "shape_predictor_68_face_landmarks.dat): ") +
                e.what());
  }
  if (s->predictor.num_parts() != 68)
    return fail("landmarks: the shape predictor has " + std::to_string(s->predictor.num_parts()) +
                " points, expected the 68-point iBUG model");
  return LandmarkDetector(std::move(s));
}

void LandmarkDetector::reset_tracking() {
  state_->last.reset();
}

Result<DetectedLandmarks> LandmarkDetector::detect(const ColorImage& image) {
  State& s = *state_;
  if (image.empty()) return fail("landmarks: the colour image is empty");
  const int w = image.width, h = image.height;
  try {
    s.gray.set_size(h, w);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const Rgb8 p = image.at(x, y);
        // Rec. 601 luma in integer arithmetic.
        s.gray[y][x] = static_cast<unsigned char>((77 * p.r + 150 * p.g + 29 * p.b) >> 8);
      }
    std::vector<std::pair<double, dlib::rectangle>> found;
    bool tracked = false;
    if (s.options.track && s.last) {
      // Face-region tracking: detect in a window around the last face only.
      const dlib::rectangle& r = *s.last;
      const double scale = s.options.track_window_scale;
      const long cw = static_cast<long>(r.width() * scale),
                 ch = static_cast<long>(r.height() * scale);
      const long x0 = std::clamp<long>(dlib::center(r).x() - cw / 2, 0, w - 1);
      const long y0 = std::clamp<long>(dlib::center(r).y() - ch / 2, 0, h - 1);
      const long x1 = std::min<long>(x0 + cw, w), y1 = std::min<long>(y0 + ch, h);
      if (x1 - x0 >= 80 && y1 - y0 >= 80) {
        s.window.set_size(y1 - y0, x1 - x0);
        for (long y = y0; y < y1; ++y)
          for (long x = x0; x < x1; ++x) s.window[y - y0][x - x0] = s.gray[y][x];
        std::vector<dlib::rect_detection> dets;
        s.detector(s.window, dets, 0.0);
        for (const auto& d : dets)
          found.emplace_back(d.detection_confidence, dlib::translate_rect(d.rect, x0, y0));
        tracked = !found.empty();
      }
    }
    if (found.empty()) {
      std::vector<dlib::rect_detection> dets;
      dlib::array2d<unsigned char> up;
      if (s.options.upsample > 0) {
        dlib::assign_image(up, s.gray);
        dlib::pyramid_up(up);
        s.detector(up, dets, 0.0);
        for (auto& d : dets)
          d.rect = dlib::rectangle(d.rect.left() / 2, d.rect.top() / 2, d.rect.right() / 2,
                                   d.rect.bottom() / 2);
      } else {
        s.detector(s.gray, dets, 0.0);
      }
      for (const auto& d : dets) found.emplace_back(d.detection_confidence, d.rect);
    }
    if (found.empty()) {
      s.last.reset();
      return fail("landmarks: no face found in the colour image");
    }
    // The largest face is the subject (people behind are smaller).
    const auto best = std::max_element(
        found.begin(), found.end(),
        [](const auto& a, const auto& b) { return a.second.area() < b.second.area(); });
    const dlib::full_object_detection shape = s.predictor(s.gray, best->second);
    DetectedLandmarks out;
    out.face = {static_cast<int>(best->second.left()), static_cast<int>(best->second.top()),
                static_cast<int>(best->second.width()), static_cast<int>(best->second.height())};
    out.tracked = tracked;
    out.detection_score = best->first;
    for (unsigned i = 0; i < 68; ++i)
      out.points[i] = Eigen::Vector2d(shape.part(i).x(), shape.part(i).y());
    s.last = best->second;
    return out;
  } catch (const std::exception& e) {
    s.last.reset();
    return fail(std::string("landmarks: dlib failed: ") + e.what());
  }
}

}  // namespace fb
