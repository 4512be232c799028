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

const LandmarkEmbedding::Vertices& LandmarkEmbedding::for_expression(
    std::string_view expression) const {
  const auto found = by_expression.find(expression);
  return found == by_expression.end() ? vertices : found->second;
}

Result<LandmarkEmbedding> parse_landmark_embedding(std::string_view text, const FaceModel& model) {
  LandmarkEmbedding out;
  std::array<bool, 68> seen{};
  std::map<std::string, std::vector<std::pair<int, std::uint32_t>>> overrides;
  std::istringstream in{std::string(text)};
  std::string line;
  int line_no = 0;
  bool header = false;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    if (!header) {
      if (line != "landmark,vertex" && line != "landmark,vertex,expression")
        return fail("landmark embedding: line " + std::to_string(line_no) +
                    " should be the header 'landmark,vertex' or 'landmark,vertex,expression'");
      header = true;
      continue;
    }
    std::istringstream row(line);
    long long l = -1, v = -1;
    char comma = 0;
    std::string expression;
    const bool ok = static_cast<bool>(row >> l >> comma >> v) && comma == ',' && l >= 0 && l < 68 &&
                    v >= 0 && v < model.vertex_count;
    bool third = false;
    if (ok && row.peek() == ',') {
      row.get();
      std::getline(row, expression);
      third = true;
    }
    if (!ok || (third && expression.empty()) || (!third && row.peek() != EOF))
      return fail("landmark embedding: line " + std::to_string(line_no) + " ('" + line +
                  "') is not 'landmark,vertex[,expression]' with a landmark 0-67 and a vertex "
                  "of this model (" +
                  std::to_string(model.vertex_count) + " vertices)");
    if (!expression.empty()) {
      overrides[expression].emplace_back(static_cast<int>(l), static_cast<std::uint32_t>(v));
      continue;
    }
    out.vertices[static_cast<std::size_t>(l)] = static_cast<std::uint32_t>(v);
    seen[static_cast<std::size_t>(l)] = true;
  }
  for (int l = 0; l < 68; ++l)
    if (!seen[static_cast<std::size_t>(l)])
      return fail("landmark embedding: landmark " + std::to_string(l) +
                  " has no row without an expression (68 such rows are needed)");
  for (const auto& [name, rows] : overrides) {
    auto& v = out.by_expression[name];
    v = out.vertices;
    for (const auto& [l, vertex] : rows) v[static_cast<std::size_t>(l)] = vertex;
  }
  return out;
}

std::string format_landmark_embedding(const LandmarkEmbedding& embedding,
                                      std::string_view comment) {
  std::ostringstream out;
  std::istringstream lines{std::string(comment)};
  for (std::string line; std::getline(lines, line);) out << "# " << line << "\n";
  out << (embedding.by_expression.empty() ? "landmark,vertex\n" : "landmark,vertex,expression\n");
  for (int l = 0; l < 68; ++l)
    out << l << "," << embedding.vertices[static_cast<std::size_t>(l)] << "\n";
  for (const auto& [name, v] : embedding.by_expression)
    for (int l = 0; l < 68; ++l)
      if (v[static_cast<std::size_t>(l)] != embedding.vertices[static_cast<std::size_t>(l)])
        out << l << "," << v[static_cast<std::size_t>(l)] << "," << name << "\n";
  return out.str();
}

LandmarkEmbedding learn_landmark_embedding(const FaceModel& model, const LandmarkHits& hits,
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

LandmarkEmbedding learn_landmark_embedding(const FaceModel& model,
                                           const std::map<std::string, LandmarkHits>& hits,
                                           int min_hits) {
  LandmarkHits pooled;
  for (const auto& [name, h] : hits)
    for (std::size_t l = 0; l < pooled.size(); ++l)
      pooled[l].insert(pooled[l].end(), h[l].begin(), h[l].end());
  LandmarkEmbedding out = learn_landmark_embedding(model, pooled, min_hits);
  for (const auto& [name, h] : hits) {
    LandmarkHits own = h;
    // A landmark this expression saw too rarely takes the pooled vertex, not the model's.
    LandmarkEmbedding e = learn_landmark_embedding(model, own, min_hits);
    for (std::size_t l = 0; l < own.size(); ++l)
      if (static_cast<int>(own[l].size()) < std::max(1, min_hits)) e.vertices[l] = out.vertices[l];
    if (e.vertices != out.vertices) out.by_expression[name] = e.vertices;
  }
  return out;
}

}  // namespace fb
