#include "firmware/daemon/guide_steps.hpp"

#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

namespace fb {

Result<std::vector<GuideStep>> parse_guide_steps(std::string_view json_text) {
  nlohmann::json doc = nlohmann::json::parse(json_text, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded() || !doc.is_object() || !doc.contains("expressions") ||
      !doc["expressions"].is_array())
    return fail("guide expressions: not a JSON object with an \"expressions\" array");
  std::vector<GuideStep> steps;
  for (const auto& e : doc["expressions"]) {
    if (!e.is_object() || !e.contains("name") || !e["name"].is_string())
      return fail("guide expressions: entry " + std::to_string(steps.size()) + " has no name");
    GuideStep step;
    step.name = e["name"].get<std::string>();
    step.label = step.name;
    if (e.contains("label")) {  // not value(): it throws when the label is not a string
      if (!e["label"].is_string())
        return fail("guide expressions: " + step.name + ".label is not a string");
      step.label = e["label"].get<std::string>();
    }
    std::string spec;
    if (e.contains("weights") && e["weights"].is_object()) {
      for (const auto& [shape, weight] : e["weights"].items()) {
        if (!weight.is_number())
          return fail("guide expressions: " + step.name + "." + shape + " is not a number");
        std::ostringstream term;
        term << shape << ":" << weight.get<double>();
        spec += (spec.empty() ? "" : "+") + term.str();
        step.weights.emplace_back(shape, weight.get<float>());
      }
    }
    step.synthetic_expr = spec.empty() ? "neutral" : spec;
    steps.push_back(std::move(step));
  }
  if (steps.empty()) return fail("guide expressions: the list is empty");
  return steps;
}

Result<std::vector<GuideStep>> load_guide_steps(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in)
    return fail("cannot read the guide expressions '" + path.string() +
                "'; set [session] guide_file in the config");
  std::ostringstream text;
  text << in.rdbuf();
  auto steps = parse_guide_steps(text.str());
  if (!steps) return fail(path.string() + ": " + steps.error().message);
  return steps;
}

}  // namespace fb
