#include "algo/fusion/icp_tracker.hpp"

#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include "algo/fusion/multiversion.hpp"

namespace fb {
namespace {

// Upper triangle of J^T W J (21), J^T W r (6), sum r^2, inlier count. A row sums into the float
// one (a row has at most a few hundred terms, so float is exact enough), flushed into the double
// one per row.
template <class T>
struct Normal6T {
  T a[21] = {};
  T b[6] = {};
  T r2 = 0;
  int count = 0;

  void add(const float j[6], float r, float w) {
    int k = 0;
    for (int i = 0; i < 6; ++i) {
      const T wji = static_cast<T>(w * j[i]);
      for (int c = i; c < 6; ++c) a[k++] += wji * j[c];
      b[i] += wji * r;
    }
    r2 += static_cast<T>(r) * r;
    ++count;
  }
  template <class U>
  void merge(const Normal6T<U>& o) {
    for (int i = 0; i < 21; ++i) a[i] += o.a[i];
    for (int i = 0; i < 6; ++i) b[i] += o.b[i];
    r2 += o.r2;
    count += o.count;
  }
};
using Normal6f = Normal6T<float>;
using Normal6 = Normal6T<double>;

}  // namespace

void IcpTracker::configure(const FusionOptions& options) {
  options_ = options;
  cos_normal_ = std::cos(options.icp_normal_angle_deg * static_cast<float>(M_PI) / 180.0f);
}

FB_CLONE_X86_64_V3 IcpResult IcpTracker::track(const DepthPyramid& input, const ModelView& model,
                                               const RigidPoseF& initial,
                                               ParallelRunner& runner) const {
  IcpResult result;
  result.world_from_camera = initial;
  result.solved = true;
  // Work in the model camera's frame: T maps input camera points into it.
  const RigidPoseF model_from_world = model.world_from_camera.inverse();
  RigidPoseF t_rel = model_from_world * initial;
  const float huber = options_.icp_huber_mm;
  Normal6 parts_acc[2];

  for (int level = kPyramidLevels - 1; level >= 0; --level) {
    const MapLevel& in = input.levels[level];
    const MapLevel& mv = model.for_input_level(level);
    const LevelIntrinsics& mk = mv.k;
    // Coarse levels tolerate larger misalignment.
    const float gate = options_.icp_distance_mm * (1.0f + 0.5f * static_cast<float>(level));
    const float gate2 = gate * gate;
    const PixelRect& box = in.box;
    const PixelRect& mbox = mv.box;
    for (int iter = 0; iter < options_.icp_iterations[level]; ++iter) {
      const Eigen::Matrix3f r = t_rel.r;
      const Eigen::Vector3f t = t_rel.t;
      const int nparts = std::min(runner.parts(), 2);
      for (auto& acc : parts_acc) acc = Normal6{};
      int candidates[2] = {0, 0};
      auto body = [&](int part, int parts) FB_INLINE {
        if (part >= 2) return;
        int y0, y1;
        ParallelRunner::split(box.y0, box.y1, part, std::min(parts, 2), y0, y1);
        Normal6& acc = parts_acc[part];
        int cand = 0;
        for (int y = y0; y < y1; ++y) {
          Normal6f row_acc;
          const Eigen::Vector3f* vrow = &in.vertices.at(0, y);
          const Eigen::Vector3f* nrow = &in.normals.at(0, y);
          // Full resolution: a checkerboard (every other pixel, alternating per row) halves the
          // cost; the half-resolution level already holds the coarse structure.
          const int x_step = level == 0 ? options_.icp_level0_step : 1;
          const int x_start = box.x0 + (x_step > 1 ? (y & 1) : 0);
          for (int x = x_start; x < box.x1; x += x_step) {
            const Eigen::Vector3f& v = vrow[x];
            if (v.z() <= 0.0f) continue;
            const Eigen::Vector3f& nin = nrow[x];
            if (nin.z() == 0.0f && nin.x() == 0.0f) continue;
            const Eigen::Vector3f p = r * v + t;
            if (p.z() <= 0.0f) continue;
            const float iz = 1.0f / p.z();
            const int u = static_cast<int>(mk.fx * p.x() * iz + mk.cx + 0.5f);
            const int w = static_cast<int>(mk.fy * p.y() * iz + mk.cy + 0.5f);
            if (!mbox.contains(u, w)) continue;
            const Eigen::Vector3f& m = mv.vertices.at(u, w);
            if (m.z() <= 0.0f) continue;
            // Candidates: points that land on the model. Background outside the volume (a wall
            // behind the head) never does; a face that left the box lands there and fails.
            ++cand;
            const Eigen::Vector3f& n = mv.normals.at(u, w);
            const Eigen::Vector3f diff = p - m;
            if (diff.squaredNorm() > gate2) continue;
            if ((r * nin).dot(n) < cos_normal_) continue;
            const float res = n.dot(diff);
            const Eigen::Vector3f pxn = p.cross(n);
            const float j[6] = {pxn.x(), pxn.y(), pxn.z(), n.x(), n.y(), n.z()};
            const float ar = std::abs(res);
            const float wgt = ar <= huber ? 1.0f : huber / ar;
            row_acc.add(j, res, wgt);
          }
          acc.merge(row_acc);
        }
        candidates[part] = cand;
      };
      if (nparts > 1) {
        runner.run(body);
      } else {
        body(0, 1);
      }
      Normal6 acc = parts_acc[0];
      if (nparts > 1) acc.merge(parts_acc[1]);
      ++result.iterations;
      if (level == 0) {
        result.inliers = acc.count;
        result.candidates = candidates[0] + candidates[1];
        result.rms_mm = acc.count > 0 ? static_cast<float>(std::sqrt(acc.r2 / acc.count)) : 0.0f;
      }
      if (acc.count < 6) {
        result.solved = false;
        break;
      }
      Eigen::Matrix<double, 6, 6> a;
      Eigen::Matrix<double, 6, 1> b;
      int k = 0;
      for (int i = 0; i < 6; ++i) {
        for (int c = i; c < 6; ++c) {
          a(i, c) = acc.a[k];
          a(c, i) = acc.a[k];
          ++k;
        }
        b(i) = acc.b[i];
      }
      Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(a);
      if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) {
        result.solved = false;
        break;
      }
      const Eigen::Matrix<double, 6, 1> xi = ldlt.solve(-b);
      if (!xi.allFinite()) {
        result.solved = false;
        break;
      }
      // T <- exp(xi) T, with the rotation part taken exactly (axis-angle).
      const Eigen::Vector3d w = xi.head<3>();
      const double angle = w.norm();
      Eigen::Matrix3f dr = Eigen::Matrix3f::Identity();
      if (angle > 1e-12) dr = Eigen::AngleAxisd(angle, w / angle).toRotationMatrix().cast<float>();
      t_rel.r = dr * t_rel.r;
      t_rel.t = dr * t_rel.t + xi.tail<3>().cast<float>();
      // Keep R orthonormal despite float round-off over many frames.
      const Eigen::Quaternionf q(t_rel.r);
      t_rel.r = q.normalized().toRotationMatrix();
      if (angle + xi.tail<3>().norm() * 1e-3 < options_.icp_converged && level > 0) break;
      if (angle + xi.tail<3>().norm() * 1e-3 < options_.icp_converged && level == 0) {
        // Converged: the statistics above are of the final pose up to this tiny step.
        break;
      }
    }
  }
  result.world_from_camera = model.world_from_camera * t_rel;
  return result;
}

}  // namespace fb
