#include "sim/camera/expressive_track.hpp"

#include <cmath>
#include <numbers>

namespace fb {

std::vector<std::vector<float>> expressive_track(const FaceModel& model, int frames) {
  struct Bump {
    const char* shapes[4];
    double start_s, duration_s;
    float peak;
  };
  constexpr Bump kScript[] = {
      {{"jawOpen"}, 0.4, 1.0, 0.6f},
      {{"mouthSmile_L", "mouthSmile_R"}, 1.4, 1.0, 0.8f},
      {{"eyeBlink_L", "eyeBlink_R"}, 2.45, 0.3, 1.0f},
      {{"browInnerUp_L", "browInnerUp_R", "browOuterUp_L", "browOuterUp_R"}, 2.9, 1.0, 0.8f},
      {{"eyeBlink_L", "eyeBlink_R"}, 4.3, 0.3, 1.0f},
  };
  constexpr double kPeriodS = 5.0;
  std::vector<std::vector<float>> track(
      static_cast<std::size_t>(frames),
      std::vector<float>(static_cast<std::size_t>(model.expression_count), 0.0f));
  for (int f = 0; f < frames; ++f) {
    const double t = std::fmod(f / 30.0, kPeriodS);
    for (const Bump& bump : kScript) {
      const double x = (t - bump.start_s) / bump.duration_s;
      if (x <= 0.0 || x >= 1.0) continue;
      const float w =
          bump.peak * static_cast<float>(0.5 - 0.5 * std::cos(2.0 * std::numbers::pi * x));
      for (const char* name : bump.shapes) {
        if (name == nullptr) continue;
        const int j = model.expression_index(name);
        if (j >= 0) track[static_cast<std::size_t>(f)][static_cast<std::size_t>(j)] = w;
      }
    }
  }
  return track;
}

}  // namespace fb
