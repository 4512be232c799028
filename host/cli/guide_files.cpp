#include "host/cli/guide_files.hpp"

#include <fstream>
#include <random>
#include <sstream>

#include "storage/asset_files.hpp"

namespace fb::cli {

Result<std::string> read_text(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return fail("cannot read " + path.string());
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

Result<GuideSet> load_guide(const FaceModel& model, const std::string& option) {
  const std::filesystem::path path =
      option.empty() ? data_directory() / "guide_expressions.json" : std::filesystem::path(option);
  auto text = read_text(path);
  if (!text) return text.failure();
  auto guide = parse_guide_expressions(*text);
  if (!guide) return fail(path.string() + ": " + guide.error().message);
  if (auto ok = validate_guide(*guide, model); !ok)
    return fail(path.string() + ": " + ok.error().message);
  return guide;
}

std::vector<float> identity_draw(std::uint64_t seed, int count) {
  std::mt19937_64 rng(0x9e3779b97f4a7c15ull ^ seed);
  std::normal_distribution<float> n(0.0f, 1.0f);
  std::vector<float> c(static_cast<std::size_t>(count));
  for (auto& x : c) x = n(rng);
  return c;
}

}  // namespace fb::cli
