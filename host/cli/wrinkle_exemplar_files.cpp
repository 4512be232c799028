#include "host/cli/wrinkle_exemplar_files.hpp"

#include <cmath>
#include <cstdlib>
#include <fstream>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "algo/wrinkles/exemplar.hpp"

#include "storage/asset_files.hpp"

namespace fb::cli {

namespace fs = std::filesystem;

fs::path default_exemplar_directory() {
  return data_directory() / "wrinkle_exemplars";
}

Result<ExemplarSet> load_exemplar_set(const fs::path& directory) {
  const fs::path list = directory / "exemplars.json";
  std::ifstream in(list);
  if (!in)
    return fail("cannot read " + list.string() +
                "; point --exemplars at a folder made by facebooth-convert-exemplars");
  const auto doc = nlohmann::json::parse(in, nullptr, false);
  if (doc.is_discarded() || !doc.contains("exemplars") || !doc.contains("mm_per_px"))
    return fail(list.string() + " is not an exemplar list (exemplars, mm_per_px)");
  ExemplarSet set;
  set.mm_per_px = doc["mm_per_px"].get<double>();
  for (const auto& e : doc["exemplars"]) {
    const fs::path hp = directory / e.value("height_png", ""),
                   sp = directory / e.value("shading_png", "");
    const cv::Mat h = cv::imread(hp.string(), cv::IMREAD_UNCHANGED);
    const cv::Mat s = cv::imread(sp.string(), cv::IMREAD_GRAYSCALE);
    if (h.empty() || h.type() != CV_16UC1 || s.empty() || s.size() != h.size())
      return fail("exemplar " + hp.string() + " / " + sp.string() +
                  " is missing or not a 16-bit height PNG with an 8-bit shading PNG of its size");
    WrinkleExemplar x;
    x.name = e.value("name", "exemplar") + "_" + std::to_string(e.value("angle_deg", 0));
    x.height_mm.resize(h.cols, h.rows);
    x.luminance.resize(h.cols, h.rows);
    for (int y = 0; y < h.rows; ++y)
      for (int c = 0; c < h.cols; ++c) {
        x.height_mm.at(c, y) = static_cast<float>((h.at<std::uint16_t>(y, c) - 32768) / 16384.0);
        x.luminance.at(c, y) = s.at<std::uint8_t>(y, c) / 255.0f;
      }
    set.exemplars.push_back(std::move(x));
  }
  if (set.exemplars.empty()) return fail(list.string() + " lists no exemplars");
  return set;
}

Result<UserExemplarSpec> parse_user_exemplar(const std::string& arg) {
  const std::string form =
      "--exemplar takes HEIGHT.png:COLOUR.png[:MM_PER_LEVEL] (a height map and a colour image "
      "of the same skin, and the height map's millimetres per grey level), not '" +
      arg + "'";
  std::vector<std::string> parts;
  for (std::size_t start = 0;;) {
    const std::size_t colon = arg.find(':', start);
    parts.push_back(arg.substr(start, colon - start));
    if (colon == std::string::npos) break;
    start = colon + 1;
  }
  if (parts.size() < 2 || parts.size() > 3 || parts[0].empty() || parts[1].empty())
    return fail(form);
  UserExemplarSpec spec{parts[0], parts[1], std::nullopt};
  if (parts.size() == 3) {
    char* end = nullptr;
    const double v = std::strtod(parts[2].c_str(), &end);
    if (end == parts[2].c_str() || *end != '\0' || !std::isfinite(v) || v <= 0.0)
      return fail(form + ": MM_PER_LEVEL must be a positive number, e.g. 0.001");
    spec.mm_per_level = v;
  }
  return spec;
}

Result<std::vector<WrinkleExemplar>> load_user_exemplar(const UserExemplarSpec& spec,
                                                        double mm_per_px, double to_mm_per_px) {
  if (!(mm_per_px > 0.0) || !(to_mm_per_px > 0.0))
    return fail("the exemplar pixel size must be positive (--exemplar-mm-per-px)");
  const cv::Mat h = cv::imread(spec.height.string(), cv::IMREAD_UNCHANGED);
  if (h.empty())
    return fail("cannot read the exemplar height map " + spec.height.string() +
                " (missing, or not an image OpenCV reads: give a grey PNG)");
  if (h.channels() != 1 || (h.depth() != CV_8U && h.depth() != CV_16U))
    return fail("the exemplar height map " + spec.height.string() +
                " is not a single-channel 8- or 16-bit grey image (heights are grey levels)");
  const cv::Mat c = cv::imread(spec.colour.string(), cv::IMREAD_COLOR);
  if (c.empty())
    return fail("cannot read the exemplar colour image " + spec.colour.string() +
                " (missing, or not an image OpenCV reads)");
  if (c.size() != h.size())
    return fail("the exemplar's height map " + spec.height.string() + " is " +
                std::to_string(h.cols) + " x " + std::to_string(h.rows) + " but its colour image " +
                spec.colour.string() + " is " + std::to_string(c.cols) + " x " +
                std::to_string(c.rows) + "; they must show the same skin pixel for pixel");
  const bool wide = h.depth() == CV_16U;
  const double level = spec.mm_per_level.value_or(wide ? 1.0 / 16384.0 : 1.0 / 128.0);
  FloatImage height, luma;
  height.resize(h.cols, h.rows);
  luma.resize(h.cols, h.rows);
  cv::Mat grey;
  cv::cvtColor(c, grey, cv::COLOR_BGR2GRAY);
  double mean = 0.0;
  for (int y = 0; y < h.rows; ++y)
    for (int x = 0; x < h.cols; ++x) {
      const double v = wide ? h.at<std::uint16_t>(y, x) : h.at<std::uint8_t>(y, x);
      height.at(x, y) = static_cast<float>(v * level);
      mean += height.at(x, y);
      luma.at(x, y) = grey.at<std::uint8_t>(y, x) / 255.0f;
    }
  // Heights about their mean: the relief is what matters, the map's zero level is arbitrary.
  mean /= static_cast<double>(height.pixels.size());
  for (auto& v : height.pixels) v -= static_cast<float>(mean);
  if (std::abs(mm_per_px - to_mm_per_px) > 1e-9) {
    height = resample(height, mm_per_px / to_mm_per_px);
    luma = resample(luma, mm_per_px / to_mm_per_px);
  }
  const int side = static_cast<int>(std::min(height.width, height.height) / std::sqrt(2.0));
  if (side < 16)
    return fail("the exemplar " + spec.height.string() + " is " + std::to_string(height.width) +
                " x " + std::to_string(height.height) + " pixels at " +
                std::to_string(to_mm_per_px) +
                " mm per pixel; it needs at least 23 x 23 (16 after rotation): give a larger "
                "crop or its true --exemplar-mm-per-px");
  const std::string stem = spec.height.stem().string();
  std::vector<WrinkleExemplar> out;
  for (const int angle : {0, 30, 60, 90, 120, 150}) {
    WrinkleExemplar e;
    e.name = stem + "_" + std::to_string(angle);
    e.height_mm = angle == 0 ? height : rotate_square(height, angle, side);
    e.luminance = angle == 0 ? luma : rotate_square(luma, angle, side);
    e.shaded = false;  // a photograph: its own light, never re-shaded
    out.push_back(std::move(e));
  }
  return out;
}

}  // namespace fb::cli
