#include "algo/facemodel/landmark_embedding.hpp"

#include <algorithm>
#include <sstream>

#include <Eigen/Core>

namespace fb {
namespace {

Eigen::Vector3d mean_face_vertex(const FaceModel& model, std::uint32_t v) {
  return {model.neutral[3 * v], model.neutral[3 * v + 1], model.neutral[3 * v + 2]};
}

double median(std::vector<double>& a) {
  const auto mid = a.begin() + static_cast<std::ptrdiff_t>(a.size() / 2);
  std::nth_element(a.begin(), mid, a.end());
  return *mid;
}

}  // namespace

LandmarkEmbedding model_landmark_embedding(const FaceModel& model) {
  LandmarkEmbedding out;
  std::copy(model.landmark_vertices.begin(), model.landmark_vertices.end(), out.vertices.begin());
  return out;
}

Result<LandmarkEmbedding> parse_landmark_embedding(std::string_view text, const FaceModel& model) {
  LandmarkEmbedding out;
  std::array<bool, 68> seen{};
  std::istringstream in{std::string(text)};
  std::string line;
  int line_no = 0;
  bool header = false;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    if (!header) {
      if (line != "landmark,vertex")
        return fail("landmark embedding: line " + std::to_string(line_no) +
                    " should be the header 'landmark,vertex'");
      header = true;
      continue;
    }
    std::istringstream row(line);
    long long l = -1, v = -1;
    char comma = 0;
    if (!(row >> l >> comma >> v) || comma != ',' || l < 0 || l >= 68 || v < 0 ||
        v >= model.vertex_count)
      return fail("landmark embedding: line " + std::to_string(line_no) + " ('" + line +
                  "') is not 'landmark,vertex' with a landmark 0-67 and a vertex of this model (" +
                  std::to_string(model.vertex_count) + " vertices)");
    out.vertices[static_cast<std::size_t>(l)] = static_cast<std::uint32_t>(v);
    seen[static_cast<std::size_t>(l)] = true;
  }
  for (int l = 0; l < 68; ++l)
    if (!seen[static_cast<std::size_t>(l)])
      return fail("landmark embedding: landmark " + std::to_string(l) +
                  " has no row (68 rows are needed)");
  return out;
}

std::string format_landmark_embedding(const LandmarkEmbedding& embedding,
                                      std::string_view comment) {
  std::ostringstream out;
  std::istringstream lines{std::string(comment)};
  for (std::string line; std::getline(lines, line);) out << "# " << line << "\n";
  out << "landmark,vertex\n";
  for (int l = 0; l < 68; ++l)
    out << l << "," << embedding.vertices[static_cast<std::size_t>(l)] << "\n";
  return out.str();
}

LandmarkEmbedding learn_landmark_embedding(const FaceModel& model,
                                           const std::array<std::vector<std::uint32_t>, 68>& hits,
                                           int min_hits) {
  LandmarkEmbedding out = model_landmark_embedding(model);
  const int face = std::min(model.face_vertex_count, model.vertex_count);
  for (int l = 17; l < 68; ++l) {
    const auto& h = hits[static_cast<std::size_t>(l)];
    if (static_cast<int>(h.size()) < std::max(1, min_hits)) continue;
    Eigen::Vector3d centre;
    for (int a = 0; a < 3; ++a) {
      std::vector<double> c;
      c.reserve(h.size());
      for (std::uint32_t v : h) c.push_back(mean_face_vertex(model, v)[a]);
      centre[a] = median(c);
    }
    double best = 1e300;
    for (int v = 0; v < face; ++v) {
      const double d =
          (mean_face_vertex(model, static_cast<std::uint32_t>(v)) - centre).squaredNorm();
      if (d < best) {
        best = d;
        out.vertices[static_cast<std::size_t>(l)] = static_cast<std::uint32_t>(v);
      }
    }
  }
  return out;
}

}  // namespace fb
