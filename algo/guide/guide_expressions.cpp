#include "algo/guide/guide_expressions.hpp"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <set>

namespace fb {

int GuideSet::find(std::string_view name) const {
  for (std::size_t i = 0; i < expressions.size(); ++i)
    if (expressions[i].name == name) return static_cast<int>(i);
  return -1;
}

Result<GuideSet> parse_guide_expressions(std::string_view json_text) {
  nlohmann::json doc;
  try {
    doc = nlohmann::json::parse(json_text.begin(), json_text.end());
  } catch (const nlohmann::json::exception& e) {
    return fail(std::string("guide expressions: not valid JSON: ") + e.what());
  }
  // find(), not value(): value() throws when the member has another type ("format": 1).
  const auto format = doc.is_object() ? doc.find("format") : doc.end();
  if (format == doc.end() || *format != "facebooth-guide-expressions")
    return fail("guide expressions: missing \"format\": \"facebooth-guide-expressions\"");
  const auto version = doc.find("version");
  if (version == doc.end() || *version != 1)
    return fail("guide expressions: unsupported version (this build reads version 1)");
  if (!doc.contains("expressions") || !doc["expressions"].is_array())
    return fail("guide expressions: \"expressions\" must be an array");
  GuideSet set;
  std::set<std::string> names;
  try {
    for (const auto& e : doc["expressions"]) {
      GuideExpression g;
      const auto& id = e.at("id");
      // Checked before narrowing to int: an id of 2^32 must not read as 0.
      if (!id.is_number_integer() || id < 0 || id > 1000)
        return fail("guide expressions: an id must be an integer in 0..1000");
      g.id = id.get<int>();
      g.name = e.at("name").get<std::string>();
      g.label = e.value("label", g.name);
      if (g.name.empty()) return fail("guide expressions: an expression has an empty name");
      if (!names.insert(g.name).second)
        return fail("guide expressions: duplicate name '" + g.name + "'");
      const auto& w = e.at("weights");
      if (!w.is_object())
        return fail("guide expressions: '" + g.name + "' weights must be an object");
      for (auto it = w.begin(); it != w.end(); ++it) {
        if (!it.value().is_number())
          return fail("guide expressions: '" + g.name + "' weight of '" + it.key() +
                      "' is not a number");
        const double v = it.value().get<double>();
        if (!std::isfinite(v) || v < 0.0 || v > 1.0)
          return fail("guide expressions: '" + g.name + "' weight of '" + it.key() +
                      "' must be in [0, 1]");
        g.weights.emplace_back(it.key(), static_cast<float>(v));
      }
      set.expressions.push_back(std::move(g));
    }
  } catch (const nlohmann::json::exception& e) {
    return fail(std::string("guide expressions: bad entry: ") + e.what());
  }
  std::sort(set.expressions.begin(), set.expressions.end(),
            [](const GuideExpression& a, const GuideExpression& b) { return a.id < b.id; });
  for (std::size_t i = 0; i < set.expressions.size(); ++i)
    if (set.expressions[i].id != static_cast<int>(i))
      return fail("guide expressions: ids must run 0..N-1 without gaps (missing id " +
                  std::to_string(i) + ")");
  if (set.expressions.empty() || !set.expressions[0].weights.empty())
    return fail("guide expressions: id 0 must be the neutral face with no weights");
  return set;
}

Result<std::vector<float>> guide_weights(const GuideExpression& expression,
                                         const FaceModel& model) {
  std::vector<float> w(static_cast<std::size_t>(model.expression_count), 0.0f);
  for (const auto& [name, weight] : expression.weights) {
    const int j = model.expression_index(name);
    if (j < 0)
      return fail("guide expression '" + expression.name + "' uses shape '" + name +
                  "', which the face model does not have");
    w[static_cast<std::size_t>(j)] = weight;
  }
  return w;
}

Result<void> validate_guide(const GuideSet& guide, const FaceModel& model) {
  for (const auto& e : guide.expressions)
    if (auto w = guide_weights(e, model); !w) return w.failure();
  return success();
}

Result<std::vector<float>> guide_mesh(const GuideExpression& expression, const FaceModel& model) {
  auto w = guide_weights(expression, model);
  if (!w) return w.failure();
  std::vector<float> mesh(static_cast<std::size_t>(model.vertex_count) * 3);
  model.evaluate({}, *w, mesh);
  return mesh;
}

Result<std::vector<std::vector<float>>> guide_part_meshes(const GuideExpression& expression,
                                                          const FaceModel& model) {
  auto all = guide_weights(expression, model);
  if (!all) return all.failure();
  std::vector<std::vector<float>> out;
  std::vector<float> w(static_cast<std::size_t>(model.expression_count), 0.0f);
  for (const auto& [name, weight] : expression.weights) {
    const auto j = static_cast<std::size_t>(model.expression_index(name));
    w[j] = weight;
    out.emplace_back(static_cast<std::size_t>(model.vertex_count) * 3);
    model.evaluate({}, w, out.back());
    w[j] = 0.0f;
  }
  return out;
}

}  // namespace fb
