#include "host/cli/wrinkle_exemplar_files.hpp"

#include <fstream>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

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

}  // namespace fb::cli
