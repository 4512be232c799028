#include "sim/scoring/occlusion_eval.hpp"

#include <algorithm>

namespace fb::cli {
namespace {

bool scored(const FrameResult& r) {
  return r.calibrated && r.state != TrackState::kCalibrating;
}

template <class T>
double median_of(std::vector<T> v) {
  if (v.empty()) return 0.0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

}  // namespace

void OcclusionScore::add(const RenderedTake& take, const std::vector<FrameResult>& results) {
  const std::size_t n = std::min(take.frames.size(), results.size());
  for (std::size_t f = 0; f < n; ++f) {
    const FrameResult& r = results[f];
    if (!scored(r)) continue;
    const double truth = take.frames[f].truth.face_hidden_fraction;
    if (truth >= kOcclusionMustReport) {
      ++hidden_frames_;
      reported_ += r.occluded ? 1 : 0;
      if (r.occluded)
        least_hidden_reported_ = std::min(least_hidden_reported_, r.occluded_fraction);
    } else if (truth < kOcclusionClear) {
      ++clear_frames_;
      false_reports_ += r.occluded ? 1 : 0;
      if (tracked(r.state))
        most_clear_measured_ = std::max(most_clear_measured_, r.occluded_fraction);
    } else {
      ++partial_frames_;
      partial_reported_ += r.occluded ? 1 : 0;
    }
  }
  // Recovery: after a run of frames hidden >= 30 %, from the first frame the hand has left the
  // face (truth under the clear bound) to the first one tracked and not reported occluded.
  for (std::size_t f = 1; f < n; ++f) {
    if (take.frames[f - 1].truth.face_hidden_fraction < kOcclusionMustReport) continue;
    if (take.frames[f].truth.face_hidden_fraction >= kOcclusionMustReport) continue;
    if (!scored(results[f])) continue;
    std::size_t left = f;
    while (left < n && take.frames[left].truth.face_hidden_fraction >= kOcclusionClear) ++left;
    if (left >= n) continue;  // the take ends with the hand on the face
    ++leaves_;
    int frames = -1;
    for (std::size_t g = left; g < n; ++g) {
      if (tracked(results[g].state) && !results[g].occluded) {
        frames = static_cast<int>(g - left);
        break;
      }
    }
    if (recovery_ >= 0) recovery_ = frames < 0 ? -1 : std::max(recovery_, frames);
  }
}

nlohmann::json OcclusionScore::json() const {
  nlohmann::json j;
  j["occlusion_reported_fraction"] =
      hidden_frames_ ? nlohmann::json(static_cast<double>(reported_) / hidden_frames_) : nullptr;
  j["occlusion_false_reports"] = false_reports_;
  j["occlusion_recovery_frames"] = leaves_ ? nlohmann::json(recovery_) : nullptr;
  j["occlusion_frames"] = {{"hidden_30pct", hidden_frames_},
                           {"hidden_30pct_reported", reported_},
                           {"least_hidden_fraction_reported",
                            hidden_frames_ && reported_ ? nlohmann::json(least_hidden_reported_)
                                                        : nlohmann::json(nullptr)},
                           {"clear", clear_frames_},
                           {"clear_reported", false_reports_},
                           {"most_hidden_fraction_measured_on_clear", most_clear_measured_},
                           {"partly_hidden", partial_frames_},
                           {"partly_hidden_reported", partial_reported_},
                           {"hand_left_face", leaves_}};
  return j;
}

bool has_nearer_distractors(const RenderedTake& take) {
  if (take.frames.empty() || take.frames[0].truth.landmarks_3d.size() < 68) return false;
  const TakeFrame& frame = take.frames[0];
  // The nose tip (iBUG 30) is the face's nearest point when it faces the camera.
  const double nose_z = frame.truth.landmarks_3d[30].z();
  int nearer = 0;
  for (const float d : frame.depth.pixels) nearer += d > 0.0f && d < nose_z - 20.0 ? 1 : 0;
  return nearer >= 300;
}

void AcquisitionScore::add(const RenderedTake& take, const std::vector<FrameResult>& results) {
  if (!has_nearer_distractors(take)) return;
  ++runs_;
  std::vector<double> rot, centre;
  for (const FrameResult& r : results) {
    if (!scored(r) || !tracked(r.state)) continue;
    rot.push_back(r.rotation_error_deg);
    centre.push_back(r.centre_error_mm);
  }
  if (!rot.empty() && median_of(rot) < 10.0 && median_of(centre) < 25.0) ++acquired_;
}

nlohmann::json AcquisitionScore::json() const {
  nlohmann::json j;
  j["acquired_with_nearer_distractors"] =
      runs_ ? nlohmann::json(static_cast<double>(acquired_) / runs_) : nullptr;
  j["runs_with_nearer_distractors"] = runs_;
  return j;
}

nlohmann::json occlusion_setup_notes() {
  return {{"occlusion_reported_fraction",
           "of the frames a hand hides >= 30 % of the face (after calibration), those the "
           "tracker reports occluded (TrackReport::occluded)"},
          {"occlusion_false_reports",
           "frames hidden < 10 % the tracker reports occluded (10-30 %: the hand arriving or "
           "leaving, counted in occlusion_frames.partly_hidden)"},
          {"occlusion_recovery_frames",
           "worst take: frames from the hand leaving the face (< 10 % hidden) to the first "
           "frame tracked and not reported occluded"},
          {"acquired_with_nearer_distractors",
           "of the runs (with landmarks and depth only) on takes whose first frame shows a "
           "surface nearer than the face, those that calibrated and tracked the face (median "
           "error < 10 deg, < 25 mm)"}};
}

}  // namespace fb::cli
