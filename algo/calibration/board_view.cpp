#include "algo/calibration/board_view.hpp"

#include <algorithm>
#include <cmath>
#include <deque>

namespace fb {
namespace {

constexpr int kWidth = 640, kHeight = 480;

bool inside_convex(const Eigen::Vector2d& p, const std::vector<Eigen::Vector2d>& polygon) {
  int sign = 0;
  for (std::size_t i = 0; i < polygon.size(); ++i) {
    const Eigen::Vector2d a = polygon[i], b = polygon[(i + 1) % polygon.size()];
    const double cross = (b - a).x() * (p - a).y() - (b - a).y() * (p - a).x();
    const int s = cross > 0 ? 1 : -1;
    if (sign == 0) sign = s;
    if (s != sign) return false;
  }
  return true;
}

// Least-squares 1/z = a u + b v + c over (u, v, z) points, with one pass of outlier rejection.
Eigen::Vector3d fit_inverse_plane(const std::vector<Eigen::Vector3f>& points) {
  Eigen::Vector3d plane = Eigen::Vector3d::Zero();
  std::vector<char> keep(points.size(), 1);
  for (int pass = 0; pass < 3; ++pass) {
    Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
    Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (!keep[i]) continue;
      const Eigen::Vector3d a(points[i].x(), points[i].y(), 1.0);
      normal += a * a.transpose();
      rhs += a / points[i].z();
    }
    plane = normal.ldlt().solve(rhs);
    std::vector<double> errors;
    for (const auto& p : points)
      errors.push_back(std::abs(1.0 / plane.dot(Eigen::Vector3d(p.x(), p.y(), 1.0)) - p.z()));
    std::vector<double> sorted = errors;
    std::nth_element(sorted.begin(), sorted.begin() + static_cast<long>(sorted.size() / 2),
                     sorted.end());
    const double limit = std::max(5.0, 4.0 * sorted[sorted.size() / 2]);
    for (std::size_t i = 0; i < points.size(); ++i) keep[i] = errors[i] < limit;
  }
  return plane;
}

// Walks from (x, y) outward along the scan over missing depth: true when it reaches depth
// clearly behind the plate (the wall) before the image border.
bool behind_plate_beyond(const Image<float>& depth, int x, int y, int step_x, int step_y,
                         float plate_mm) {
  for (int k = 1; k <= 150; ++k) {
    const int nx = x + k * step_x, ny = y + k * step_y;
    if (!depth.contains(nx, ny)) return false;
    const float z = depth.at(nx, ny);
    if (z <= 0.0f) continue;
    return z > plate_mm + std::max(60.0f, 0.08f * plate_mm);
  }
  return false;
}

// Where the tables put the board's inner corners in depth (any depth: the parallax is a few
// pixels; the registration error is what the calibration finds): the outer corners, pulled 30%
// towards their centre as a margin for the unknown registration.
Result<std::vector<Eigen::Vector2d>> board_hull_in_depth(
    const BoardSpec& board, const RegistrationModel& model,
    const std::vector<Eigen::Vector2d>& corners_color) {
  const std::size_t c = static_cast<std::size_t>(board.cols), n = corners_color.size();
  std::vector<Eigen::Vector2d> hull;
  for (std::size_t j : {std::size_t{0}, c - 1, n - 1, n - c}) {
    Eigen::Vector2d uv(320.0, 240.0);
    if (!model.depth_pixel_of(
            RegistrationCorrection{}, corners_color[j], [](double, double) { return 1000.0; },
            uv)) {
      return fail("the board's corners fall outside the depth camera's view");
    }
    hull.push_back(uv);
  }
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  for (const auto& p : hull) centre += p / 4.0;
  for (auto& p : hull) p = centre + 0.7 * (p - centre);  // margin for the unknown registration
  return hull;
}

// The (u, v, z) of every pixel with depth inside the hull.
std::vector<Eigen::Vector3f> depth_inside(const Image<float>& depth,
                                          const std::vector<Eigen::Vector2d>& hull) {
  double x0 = 1e9, y0 = 1e9, x1 = -1e9, y1 = -1e9;
  for (const auto& p : hull) {
    x0 = std::min(x0, p.x()), y0 = std::min(y0, p.y()), x1 = std::max(x1, p.x()),
    y1 = std::max(y1, p.y());
  }
  std::vector<Eigen::Vector3f> seeds;
  for (int y = std::max(0, static_cast<int>(y0)); y <= std::min(kHeight - 1, static_cast<int>(y1));
       ++y) {
    for (int x = std::max(0, static_cast<int>(x0)); x <= std::min(kWidth - 1, static_cast<int>(x1));
         ++x) {
      if (depth.at(x, y) > 0.0f && inside_convex(Eigen::Vector2d(x, y), hull)) {
        seeds.emplace_back(static_cast<float>(x), static_cast<float>(y), depth.at(x, y));
      }
    }
  }
  return seeds;
}

// The plate: connected pixels within `tolerance` of the plane, grown from the seeds.
Image<std::uint8_t> grow_plate(const Image<float>& depth, const std::vector<Eigen::Vector3f>& seeds,
                               const Eigen::Vector3d& plane, float tolerance) {
  auto on_plane = [&](int x, int y) {
    const float z = depth.at(x, y);
    return z > 0.0f && std::abs(z - 1.0 / plane.dot(Eigen::Vector3d(x, y, 1.0))) < tolerance;
  };
  Image<std::uint8_t> mask;
  mask.resize(kWidth, kHeight);
  std::deque<std::pair<int, int>> queue;
  for (const auto& s : seeds) {
    const int x = static_cast<int>(s.x()), y = static_cast<int>(s.y());
    if (on_plane(x, y) && !mask.at(x, y)) mask.at(x, y) = 1, queue.emplace_back(x, y);
  }
  while (!queue.empty()) {
    const auto [x, y] = queue.front();
    queue.pop_front();
    for (const auto& [dx, dy] : {std::pair{1, 0}, {-1, 0}, {0, 1}, {0, -1}}) {
      const int nx = x + dx, ny = y + dy;
      if (mask.contains(nx, ny) && !mask.at(nx, ny) && on_plane(nx, ny)) {
        mask.at(nx, ny) = 1;
        queue.emplace_back(nx, ny);
      }
    }
  }
  return mask;
}

// The plate's pixel count, depth samples and outline samples into `view`.
void sample_plate(const Image<float>& depth, const Image<std::uint8_t>& mask, BoardView& view) {
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x) {
      if (!mask.at(x, y)) continue;
      ++view.plate_pixels;
      // Interior (3 px from the outline) on a stride-2 grid: depth samples.
      bool interior =
          x >= 3 && y >= 3 && x < kWidth - 3 && y < kHeight - 3 && (x % 2 == 0) && (y % 2 == 0);
      for (int dy = -3; dy <= 3 && interior; ++dy) {
        for (int dx = -3; dx <= 3 && interior; ++dx) interior = mask.at(x + dx, y + dy) != 0;
      }
      if (interior)
        view.depth.emplace_back(static_cast<float>(x), static_cast<float>(y), depth.at(x, y));
      // Outline samples: the last plate pixel before the wall, per row and per column.
      const float z = depth.at(x, y);
      for (const auto& [dx, dy] : {std::pair{1, 0}, {-1, 0}, {0, 1}, {0, -1}}) {
        const int nx = x + dx, ny = y + dy;
        if (!mask.contains(nx, ny) || mask.at(nx, ny)) continue;
        if (!behind_plate_beyond(depth, x, y, dx, dy, z)) continue;
        EdgeSample e;
        e.u = static_cast<float>(x);
        e.v = static_cast<float>(y);
        e.axis = static_cast<std::int8_t>(dx != 0 ? 0 : 1);
        e.outward = static_cast<std::int8_t>(dx + dy);
        view.edges.push_back(e);
      }
    }
  }
}

}  // namespace

Image<float> table_depth(const DisparityImage& raw, const KinectCalibration& tables) {
  KinectCalibration plain = tables;
  plain.correction = RegistrationCorrection{};
  const KinectRegistration registration(plain);
  Image<float> out;
  out.resize(raw.width, raw.height);
  for (std::size_t i = 0; i < raw.pixels.size(); ++i) {
    out.pixels[i] = registration.raw_to_mm_exact(raw.pixels[i]);
  }
  return out;
}

Result<BoardView> extract_board_view(const BoardSpec& board, const RegistrationModel& model,
                                     const Image<float>& depth,
                                     std::vector<Eigen::Vector2d> corners_color) {
  if (depth.width != kWidth || depth.height != kHeight) {
    return fail("the depth image is not 640x480; only the Kinect's 640x480 mode is supported");
  }
  if (static_cast<int>(corners_color.size()) != board.corner_count()) {
    return fail("wrong number of board corners");
  }
  BoardView view;
  view.corners_color = std::move(corners_color);
  auto hull = board_hull_in_depth(board, model, view.corners_color);
  if (!hull) return hull.failure();
  std::vector<Eigen::Vector3f> seeds = depth_inside(depth, *hull);
  if (seeds.size() < 50) {
    return fail("no depth where the board is seen in colour (too near, too far or too steep)");
  }
  std::vector<float> zs;
  for (const auto& s : seeds) zs.push_back(s.z());
  std::nth_element(zs.begin(), zs.begin() + static_cast<long>(zs.size() / 2), zs.end());
  const float median = zs[zs.size() / 2];
  std::erase_if(seeds,
                [&](const Eigen::Vector3f& s) { return std::abs(s.z() - median) > 0.1f * median; });
  Eigen::Vector3d plane = fit_inverse_plane(seeds);
  const Image<std::uint8_t> mask = grow_plate(depth, seeds, plane, std::max(20.0f, 0.03f * median));
  sample_plate(depth, mask, view);
  if (view.depth.size() < 100) {
    return fail("the board's plate is too small or too broken up in the depth image");
  }
  view.inverse_depth_plane = fit_inverse_plane(view.depth);
  std::vector<float> depths;
  for (const auto& d : view.depth) depths.push_back(d.z());
  std::nth_element(depths.begin(), depths.begin() + static_cast<long>(depths.size() / 2),
                   depths.end());
  view.median_depth_mm = depths[depths.size() / 2];
  int sides[4] = {0, 0, 0, 0};
  for (const auto& e : view.edges) ++sides[e.axis * 2 + (e.outward > 0 ? 1 : 0)];
  if (*std::min_element(sides, sides + 4) < 10) {
    return fail(
        "the plate's outline is not seen on all four sides in depth (keep the whole "
        "plate in view, in front of a wall or open space)");
  }
  return view;
}

}  // namespace fb
