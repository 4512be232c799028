#include "algo/wrinkles/salient_regions.hpp"

#include <algorithm>
#include <cmath>

#include "algo/core/polygon.hpp"

namespace fb {

namespace {

// A sign change of the gradient across (x, y) along (dx, dy), both sides over the threshold.
bool sign_change(const ImageGradient& g, int x, int y, int dx, int dy, float t) {
  const FloatImage& d = dx ? g.gx : g.gy;
  const float a = d.at(x - dx, y - dy), b = d.at(x + dx, y + dy);
  return (a < -t && b > t) || (a > t && b < -t);
}

double segment_distance(const Eigen::Vector2d& p, const Eigen::Vector2d& a,
                        const Eigen::Vector2d& b) {
  const Eigen::Vector2d d = b - a;
  const double t = std::clamp((p - a).dot(d) / std::max(d.squaredNorm(), 1e-12), 0.0, 1.0);
  return (a + t * d - p).norm();
}

// Whether p lies on a feature: within feature_radius_px of a nose, mouth or lip landmark
// (27-35, 48-67), or within brow_radius_px of a brow's landmark polyline (17-21, 22-26; the
// forehead's lines run right above it).
bool on_feature(const Eigen::Vector2d& p, const std::array<Eigen::Vector2d, 68>& l,
                const SalientOptions& o) {
  for (int i = 27; i < 68; ++i) {
    if (i >= 36 && i < 48) continue;  // the eyes: crow's feet and lids sit right beside them
    if ((l[static_cast<std::size_t>(i)] - p).norm() < o.feature_radius_px) return true;
  }
  for (int i = 17; i < 26; ++i) {
    if (i == 21) continue;  // the two brows are separate polylines
    if (segment_distance(p, l[static_cast<std::size_t>(i)], l[static_cast<std::size_t>(i + 1)]) <
        o.brow_radius_px)
      return true;
  }
  return false;
}

bool in_polygon(const Eigen::Vector2d& q, const std::vector<Eigen::Vector2d>& polygon) {
  return inside_polygon(polygon, q.x(), q.y());
}

// The face outline of SalientOptions (image coordinates, y down).
std::vector<Eigen::Vector2d> face_outline(const std::array<Eigen::Vector2d, 68>& l,
                                          const SalientOptions& o) {
  std::vector<Eigen::Vector2d> polygon;
  const double lift = o.forehead_fraction * (l[16] - l[0]).norm();
  for (int i = 0; i <= 16; ++i) polygon.push_back(l[static_cast<std::size_t>(i)]);
  for (int i = 26; i >= 17; --i)
    polygon.push_back(l[static_cast<std::size_t>(i)] - Eigen::Vector2d(0.0, lift));
  Eigen::Vector2d c = Eigen::Vector2d::Zero();
  for (const auto& p : polygon) c += p / static_cast<double>(polygon.size());
  for (auto& p : polygon) p = c + o.outline_shrink * (p - c);
  return polygon;
}

float eyelid_distance(const Eigen::Vector2d& p, const std::array<Eigen::Vector2d, 68>& l) {
  double best = 1e30;
  for (const int i : {37, 38, 39, 40, 41, 43, 44, 46, 47, 42})
    best = std::min(best, (l[static_cast<std::size_t>(i)] - p).norm());
  return static_cast<float>(best);
}

// SalientOptions' feature pixels, from the landmarks.
Image<std::uint8_t> feature_pixels(int w, int h, const std::array<Eigen::Vector2d, 68>& l,
                                   const SalientOptions& o) {
  Image<std::uint8_t> out;
  out.resize(w, h);
  std::fill(out.pixels.begin(), out.pixels.end(), std::uint8_t{0});
  std::vector<Eigen::Vector2d> eyes[2];
  for (int i = 36; i < 48; ++i) eyes[i < 42 ? 0 : 1].push_back(l[static_cast<std::size_t>(i)]);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const Eigen::Vector2d p(x, y);
      bool on = false;
      for (int i = 17; i < 26 && !on; ++i)
        on = i != 21 && segment_distance(p, l[static_cast<std::size_t>(i)],
                                         l[static_cast<std::size_t>(i + 1)]) < o.mask_brow_px;
      for (const auto& eye : eyes) {
        if (on) break;
        on = in_polygon(p, eye);
        for (std::size_t i = 0; i < eye.size() && !on; ++i)
          on = segment_distance(p, eye[i], eye[(i + 1) % eye.size()]) < o.mask_eye_px;
      }
      for (int i = 27; i < 68 && !on; ++i)
        on = (i < 36 || i >= 48) &&
             (l[static_cast<std::size_t>(i)] - p).norm() < o.feature_radius_px;
      out.at(x, y) = on;
    }
  return out;
}

// Pixels where the gradient changes sign over the threshold (SalientOptions).
void mark_sign_changes(const ImageGradient& g, const std::vector<PixelRect>& zones,
                       const SalientOptions& o, Image<std::uint8_t>& marked) {
  for (int y = 2; y + 2 < marked.height; ++y)
    for (int x = 2; x + 2 < marked.width; ++x)
      if (sign_change(g, x, y, 0, 1, o.gradient_threshold) ||
          (sign_change(g, x, y, 1, 0, o.gradient_threshold) &&
           !(o.forehead_rows_only && !zones.empty() && zones[0].contains(x, y))))
        marked.at(x, y) = 1;
}

// Off the skin and within `margin` px of a pixel off it nothing is marked: the detector's local
// mean there takes in the wall, and a groove joins the silhouette's marks (SalientOptions::
// silhouette_margin_px).
void clear_near_silhouette(Image<std::uint8_t>& marked, const Image<std::uint8_t>& skin,
                           int margin) {
  for (int y = 0; y < marked.height; ++y)
    for (int x = 0; x < marked.width; ++x) {
      if (!marked.at(x, y)) continue;
      bool off = false;
      for (int dy = -margin; dy <= margin && !off; ++dy)
        for (int dx = -margin; dx <= margin && !off; ++dx)
          off = !skin.contains(x + dx, y + dy) || !skin.at(x + dx, y + dy);
      if (off) marked.at(x, y) = 0;
    }
}

// With SalientOptions::trace_in_zones a line does not cross a zone's border: the zone each
// pixel is cut into (-1: none).
std::vector<std::int8_t> zone_cuts(const std::vector<PixelRect>& zones, const SalientOptions& o,
                                   int w, int h) {
  std::vector<std::int8_t> cut(static_cast<std::size_t>(w) * h, -1);
  for (std::size_t z = o.trace_in_zones == 1 ? 2 : 0; o.trace_in_zones > 0 && z < zones.size(); ++z)
    for (int y = std::max(0, zones[z].y0); y < std::min(h, zones[z].y1); ++y)
      for (int x = std::max(0, zones[z].x0); x < std::min(w, zones[z].x1); ++x)
        cut[static_cast<std::size_t>(y) * w + x] = static_cast<std::int8_t>(z);
  return cut;
}

PixelRect merge(const PixelRect& a, const PixelRect& b) {
  return PixelRect{std::min(a.x0, b.x0), std::min(a.y0, b.y0), std::max(a.x1, b.x1),
                   std::max(a.y1, b.y1)};
}

bool near(const PixelRect& a, const PixelRect& b, int gap) {
  return a.x0 - gap < b.x1 && b.x0 - gap < a.x1 && a.y0 - gap < b.y1 && b.y0 - gap < a.y1;
}

// Lines of one cluster: closer than the gap; on the forehead (zone 0) also side by side at the
// same height (its lines run across it and are found in pieces).
bool joins(const PixelRect& a, const PixelRect& b, int zone, const SalientOptions& o) {
  if (near(a, b, o.cluster_gap_px)) return true;
  if (zone != 0 || !(a.y0 < b.y1 && b.y0 < a.y1)) return false;
  const int gap = std::max(a.x0, b.x0) - std::min(a.x1, b.x1);
  return o.join_forehead_rows || gap <= o.forehead_row_gap_px;
}

// The landmark tests of a traced line (SalientOptions): on a feature, in no zone (sets
// line.zone), outside the face outline, along an eyelid; kKept if it passes them all.
LineDrop judge_line(WrinkleLine& line, const std::array<Eigen::Vector2d, 68>& landmarks,
                    const std::vector<PixelRect>& zones,
                    const std::vector<Eigen::Vector2d>& outline, const SalientOptions& o) {
  Eigen::Vector2d c = Eigen::Vector2d::Zero();
  for (const auto& p : line.pixels) c += p.cast<double>();
  c /= static_cast<double>(line.pixels.size());
  if (on_feature(c, landmarks, o)) return LineDrop::kFeature;
  if (!zones.empty()) {
    line.zone = -1;
    for (std::size_t z = 0; z < zones.size() && line.zone < 0; ++z)
      if (zones[z].contains(static_cast<int>(c.x()), static_cast<int>(c.y())))
        line.zone = static_cast<int>(z);
    // Most of the line, not only its centroid (a component of noise and the silhouette can be
    // centred in a zone).
    if (line.zone >= 0 && o.zone_majority) {
      const PixelRect& z = zones[static_cast<std::size_t>(line.zone)];
      std::size_t in = 0;
      for (const auto& p : line.pixels) in += z.contains(p.x(), p.y());
      if (2 * in <= line.pixels.size()) line.zone = -1;
    }
    if (line.zone < 0) return LineDrop::kNoZone;
  }
  // (A zone is inside the face already; the outline, shrunk, cuts the crow's feet.)
  if (o.inside_face_only && zones.empty()) {
    // Most of the line, not its centroid: the head's silhouette is a loop around the face.
    std::size_t inside = 0;
    for (const auto& p : line.pixels) inside += in_polygon(p.cast<double>(), outline);
    if (2 * inside <= line.pixels.size()) return LineDrop::kOutline;
  }
  // A lid's edge: most of the line lies along the eye's contour.
  int near_lid = 0;
  for (const auto& p : line.pixels)
    near_lid += eyelid_distance(p.cast<double>(), landmarks) < o.eyelid_radius_px;
  if (2 * near_lid > static_cast<int>(line.pixels.size())) return LineDrop::kEyelid;
  return LineDrop::kKept;
}

}  // namespace

FloatImage detection_image(const FloatImage& luminance, const SalientOptions& o) {
  FloatImage out = o.smooth_sigma_px > 0 ? gaussian_blur(luminance, o.smooth_sigma_px) : luminance;
  if (o.relative_sigma_px <= 0) return out;
  const FloatImage mean = gaussian_blur(luminance, o.relative_sigma_px);
  for (std::size_t i = 0; i < out.pixels.size(); ++i)
    out.pixels[i] = 0.5f * out.pixels[i] / std::max(mean.pixels[i], 1e-3f);
  return out;
}

std::vector<PixelRect> wrinkle_zones(const std::array<Eigen::Vector2d, 68>& l,
                                     const SalientOptions& o) {
  const double jaw = (l[16] - l[0]).norm();
  double brow_top = 1e30;
  for (int i = 17; i <= 26; ++i) brow_top = std::min(brow_top, l[static_cast<std::size_t>(i)].y());
  auto rect = [](double x0, double y0, double x1, double y1) {
    const int ix = static_cast<int>(std::floor(std::min(x0, x1))),
              iy = static_cast<int>(std::floor(std::min(y0, y1)));
    return PixelRect{ix, iy, static_cast<int>(std::ceil(std::max(x0, x1))),
                     static_cast<int>(std::ceil(std::max(y0, y1)))};
  };
  std::vector<PixelRect> zones;
  // Forehead: between the brows' outer ends, from the outline's top down to the brows' mean
  // height; the glabella (vertical frown lines) between the inner ends down to the nose's
  // bridge.
  double brow_mean = 0.0;
  for (int i = 17; i <= 26; ++i) brow_mean += l[static_cast<std::size_t>(i)].y() / 10.0;
  zones.push_back(rect(l[17].x(), brow_top - o.forehead_fraction * jaw, l[26].x(), brow_mean));
  zones.push_back(rect(l[21].x(), brow_mean, l[22].x(), l[27].y()));
  // Crow's feet: beyond each outer eye corner (36: image left, 45: image right).
  const double cw = o.crows_feet_width * jaw, ch = 0.5 * o.crows_feet_height * jaw;
  zones.push_back(rect(l[36].x() - cw, l[36].y() - ch, l[36].x(), l[36].y() + ch));
  zones.push_back(rect(l[45].x(), l[45].y() - ch, l[45].x() + cw, l[45].y() + ch));
  return zones;
}

SalientRegions salient_regions(const FloatImage& luminance,
                               const std::optional<std::array<Eigen::Vector2d, 68>>& landmarks,
                               const SalientOptions& o, const Image<std::uint8_t>* skin) {
  SalientRegions out;
  const int w = luminance.width, h = luminance.height;
  out.marked.resize(w, h);
  std::fill(out.marked.pixels.begin(), out.marked.pixels.end(), std::uint8_t{0});
  const FloatImage detection = detection_image(luminance, o);
  const ImageGradient g = image_gradient(detection);
  std::vector<Eigen::Vector2d> outline;
  std::vector<PixelRect> zones;
  if (landmarks) {
    if (o.wrinkle_zones) zones = wrinkle_zones(*landmarks, o);
    outline = face_outline(*landmarks, o);
    out.features = feature_pixels(w, h, *landmarks, o);
  }
  mark_sign_changes(g, zones, o, out.marked);
  if (skin && o.silhouette_margin_px >= 0)
    clear_near_silhouette(out.marked, *skin, o.silhouette_margin_px);
  // With zones, the features' pixels (eyes, brows, ...) break the lines: crow's feet otherwise
  // join the eyelids' edges into one component centred on the eye.
  if (!zones.empty())
    for (std::size_t i = 0; i < out.marked.pixels.size(); ++i)
      if (out.features.pixels[i]) out.marked.pixels[i] = 0;
  const std::vector<std::int8_t> cut = zone_cuts(zones, o, w, h);
  // Trace: 8-connected components of marked pixels.
  Image<std::uint8_t> seen = out.marked;
  std::vector<Eigen::Vector2i> stack;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      if (seen.at(x, y) != 1) continue;
      WrinkleLine line;
      stack.assign(1, {x, y});
      seen.at(x, y) = 2;
      int x0 = x, x1 = x, y0 = y, y1 = y;
      while (!stack.empty()) {
        const Eigen::Vector2i p = stack.back();
        stack.pop_back();
        line.pixels.push_back(p);
        x0 = std::min(x0, p.x()), x1 = std::max(x1, p.x()), y0 = std::min(y0, p.y()),
        y1 = std::max(y1, p.y());
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const int qx = p.x() + dx, qy = p.y() + dy;
            if (seen.contains(qx, qy) && seen.at(qx, qy) == 1 &&
                cut[static_cast<std::size_t>(qy) * w + qx] ==
                    cut[static_cast<std::size_t>(p.y()) * w + p.x()]) {
              seen.at(qx, qy) = 2;
              stack.emplace_back(qx, qy);
            }
          }
      }
      line.box = PixelRect{x0, y0, x1 + 1, y1 + 1};
      const int shortest = std::min(o.min_line_px, o.min_crows_feet_px);
      if (line.length() <
          (o.line_test_min_px > 0 ? std::min(shortest, o.line_test_min_px) : shortest))
        continue;
      auto drop = [&](LineDrop why) {
        line.drop = why;
        out.dropped.push_back(std::move(line));
      };
      if (landmarks) {
        if (const LineDrop why = judge_line(line, *landmarks, zones, outline, o);
            why != LineDrop::kKept) {
          drop(why);
          continue;
        }
      }
      // Crow's feet are short rays (10-15 mm): a shorter line counts there.
      const bool is_short = line.length() < (line.zone >= 2 ? o.min_crows_feet_px : o.min_line_px);
      if (o.line_test_min_px > 0) line.evidence = line_evidence(detection, line.pixels, o.evidence);
      // A short line is kept when the groove it would be a piece of goes on beyond its ends.
      if (is_short && !(o.line_test_min_px > 0 && line.length() >= o.line_test_min_px &&
                        line.evidence.continuation_score >= o.line_keep_score)) {
        drop(LineDrop::kShort);
        continue;
      }
      out.lines.push_back(std::move(line));
    }
  // Cluster: boxes closer than the gap merge until none do.
  // (With zones, only lines of one zone.)
  std::vector<PixelRect> boxes;
  std::vector<int> zone_of;
  for (const auto& l : out.lines) boxes.push_back(l.box), zone_of.push_back(l.zone);
  for (bool merged = true; merged;) {
    merged = false;
    for (std::size_t i = 0; i < boxes.size() && !merged; ++i)
      for (std::size_t j = i + 1; j < boxes.size() && !merged; ++j)
        if (zone_of[i] == zone_of[j] && joins(boxes[i], boxes[j], zone_of[i], o)) {
          boxes[i] = merge(boxes[i], boxes[j]);
          boxes.erase(boxes.begin() + static_cast<long>(j));
          zone_of.erase(zone_of.begin() + static_cast<long>(j));
          merged = true;
        }
  }
  for (std::size_t k = 0; k < boxes.size(); ++k) {
    const PixelRect& b = boxes[k];
    const int x0 = std::max(0, b.x0 - o.margin_px), y0 = std::max(0, b.y0 - o.margin_px);
    const int x1 = std::min(w, b.x1 + o.margin_px), y1 = std::min(h, b.y1 + o.margin_px);
    if (zones.empty()) {
      out.regions.push_back(PixelRect{x0, y0, x1, y1});
      continue;
    }
    // The forehead's rows across its zone; a small zone whole.
    {
      const int zone = zone_of[k];
      const PixelRect& z = zones[static_cast<std::size_t>(zone)];
      const bool across = zone == 0 && o.forehead_across, whole = zone > 0;
      const int zx0 = across || whole ? z.x0 : std::max(x0, z.x0 - o.margin_px);
      const int zy0 = whole ? z.y0 : std::max(y0, z.y0 - o.margin_px);
      const int zx1 = across || whole ? z.x1 : std::min(x1, z.x1 + o.margin_px);
      const int zy1 = whole ? z.y1 : std::min(y1, z.y1 + o.margin_px);
      if (zx1 > zx0 && zy1 > zy0) out.regions.push_back(PixelRect{zx0, zy0, zx1, zy1});
    }
  }
  return out;
}

void fill_holes(Image<std::uint8_t>& mask) {
  const int w = mask.width, h = mask.height;
  constexpr std::uint8_t kOutside = 2;
  std::vector<int> stack;
  auto reach = [&](int x, int y) {
    if (x < 0 || y < 0 || x >= w || y >= h || mask.at(x, y) != 0) return;
    mask.at(x, y) = kOutside;
    stack.push_back(y * w + x);
  };
  for (int x = 0; x < w; ++x) reach(x, 0), reach(x, h - 1);
  for (int y = 0; y < h; ++y) reach(0, y), reach(w - 1, y);
  while (!stack.empty()) {
    const int x = stack.back() % w, y = stack.back() / w;
    stack.pop_back();
    reach(x + 1, y), reach(x - 1, y), reach(x, y + 1), reach(x, y - 1);
  }
  for (auto& m : mask.pixels) m = m != kOutside;
}

}  // namespace fb
