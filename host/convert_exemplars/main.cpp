// facebooth-convert-exemplars --source DIR --out DIR: the default wrinkle exemplars (seed 004,
// section 3.1) from a real head scan's displacement map (../shared/skin/lps, SOURCE.md there).
// Each exemplar: a crop of the scan's forehead lines, brow furrows or crow's feet, high-passed
// to the wrinkle scale, resampled to kMmPerPx, scaled to millimetres, with its shading as the
// booth's camera sees it, and rotated copies at 30-150 degrees (re-shaded under the same light).
// Writes NAME_ANGLE.height.png (16-bit: mm = (v - 32768) * height_mm_per_unit),
// NAME_ANGLE.shading.png (8-bit luminance), exemplars.json and ATTRIBUTION.md.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "algo/wrinkles/exemplar.hpp"

namespace fs = std::filesystem;

namespace {

constexpr const char* kSourceFile = "Infinite-Level_02_Disp_NoSmoothUV-4096.jpg";
// The scan's pixel size: its eye centres are ~580 px apart in the 4096 map, a typical adult's
// 63 mm (the maker publishes no scale).
constexpr double kSourceMmPerPx = 63.0 / 580.0;
constexpr double kMmPerPx = 0.25;    // the exemplars' pixel size (the texture atlas's order)
constexpr double kHighPassMm = 3.0;  // relief narrower than this is kept (wrinkles, pores)
constexpr double kDepthP99Mm = 0.4;  // the forehead's 99th percentile |relief| (0.1-1 mm)
constexpr double kHeightMmPerUnit = 1.0 / 16384.0;  // 16-bit storage: +-2 mm

struct Region {
  const char* name;
  int x, y, w, h;  // in the 4096 map
};
// Where the wrinkles are in the scan's UV layout (SOURCE.md; checked on a high-passed view).
constexpr Region kRegions[] = {{"forehead", 1650, 640, 800, 320},
                               {"brow_furrows", 1950, 900, 240, 240},
                               {"crows_feet_right", 1400, 1100, 240, 240},
                               {"crows_feet_left", 2440, 1100, 240, 240}};

bool write_png16(const fs::path& path, const fb::FloatImage& mm) {
  cv::Mat m(mm.height, mm.width, CV_16UC1);
  for (int y = 0; y < mm.height; ++y)
    for (int x = 0; x < mm.width; ++x)
      m.at<std::uint16_t>(y, x) = static_cast<std::uint16_t>(
          std::clamp(std::lround(mm.at(x, y) / kHeightMmPerUnit) + 32768L, 0L, 65535L));
  return cv::imwrite(path.string(), m);
}

bool write_png8(const fs::path& path, const fb::FloatImage& v) {
  cv::Mat m(v.height, v.width, CV_8UC1);
  for (int y = 0; y < v.height; ++y)
    for (int x = 0; x < v.width; ++x)
      m.at<std::uint8_t>(y, x) =
          static_cast<std::uint8_t>(std::clamp(v.at(x, y) * 255.0f + 0.5f, 0.0f, 255.0f));
  return cv::imwrite(path.string(), m);
}

double percentile_abs(const fb::FloatImage& im, double q) {
  std::vector<float> a;
  for (float v : im.pixels) a.push_back(std::abs(v));
  std::nth_element(a.begin(), a.begin() + static_cast<long>(q * (a.size() - 1)), a.end());
  return a[static_cast<std::size_t>(q * (a.size() - 1))];
}

int usage() {
  std::cerr << "usage: facebooth-convert-exemplars --source DIR --out DIR\n"
               "  DIR with "
            << kSourceFile
            << " (../shared/skin/lps); writes the exemplar set "
               "(data/wrinkle_exemplars in the project)\n";
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  fs::path source, out;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") return usage(), 0;
    if (a == "--source" && i + 1 < argc)
      source = argv[++i];
    else if (a == "--out" && i + 1 < argc)
      out = argv[++i];
    else
      return usage();
  }
  if (source.empty() || out.empty()) return usage();
  const cv::Mat grey = cv::imread((source / kSourceFile).string(), cv::IMREAD_GRAYSCALE);
  if (grey.empty() || grey.cols != 4096 || grey.rows != 4096) {
    std::cerr << "facebooth-convert-exemplars: cannot read the 4096x4096 map "
              << (source / kSourceFile) << "; point --source at ../shared/skin/lps\n";
    return 1;
  }
  std::error_code ec;
  fs::create_directories(out, ec);
  // High-passed crops at the exemplars' pixel size, in grey levels.
  std::vector<fb::FloatImage> relief;
  for (const auto& r : kRegions) {
    // A margin so the blur has context; cut off after the high-pass.
    const int m = static_cast<int>(std::ceil(3.0 * kHighPassMm / kSourceMmPerPx));
    fb::FloatImage crop;
    crop.resize(r.w + 2 * m, r.h + 2 * m);
    for (int y = 0; y < crop.height; ++y)
      for (int x = 0; x < crop.width; ++x)
        crop.at(x, y) = grey.at<std::uint8_t>(std::clamp(r.y - m + y, 0, 4095),
                                              std::clamp(r.x - m + x, 0, 4095));
    const fb::FloatImage hp = fb::high_pass(crop, kHighPassMm / kSourceMmPerPx);
    fb::FloatImage inner;
    inner.resize(r.w, r.h);
    for (int y = 0; y < r.h; ++y)
      for (int x = 0; x < r.w; ++x) inner.at(x, y) = hp.at(x + m, y + m);
    relief.push_back(fb::resample(inner, kSourceMmPerPx / kMmPerPx));
  }
  // One depth scale for all (the forehead's relief sets it): grey level -> mm, sign kept
  // (the map's brighter is outward).
  const double mm_per_grey = kDepthP99Mm / std::max(1e-6, percentile_abs(relief.front(), 0.99));
  nlohmann::json list = nlohmann::json::array();
  for (std::size_t k = 0; k < relief.size(); ++k) {
    fb::FloatImage mm = relief[k];
    for (auto& v : mm.pixels) v = static_cast<float>(v * mm_per_grey);
    const int side = static_cast<int>(std::floor(std::min(mm.width, mm.height) / std::sqrt(2.0)));
    for (const int angle : {0, 30, 60, 90, 120, 150}) {
      const fb::FloatImage h = angle == 0 ? mm : fb::rotate_square(mm, angle, side);
      const fb::FloatImage shading = fb::shade_relief(h, kMmPerPx);
      const std::string stem = std::string(kRegions[k].name) + "_" + std::to_string(angle);
      if (!write_png16(out / (stem + ".height.png"), h) ||
          !write_png8(out / (stem + ".shading.png"), shading)) {
        std::cerr << "facebooth-convert-exemplars: cannot write into " << out << "\n";
        return 1;
      }
      list.push_back({{"name", kRegions[k].name},
                      {"angle_deg", angle},
                      {"width", h.width},
                      {"height", h.height},
                      {"height_png", stem + ".height.png"},
                      {"shading_png", stem + ".shading.png"},
                      {"height_p99_mm", percentile_abs(h, 0.99)}});
    }
  }
  nlohmann::json doc = {
      {"format", "facebooth wrinkle exemplars 1"},
      {"mm_per_px", kMmPerPx},
      {"height_encoding", "16-bit PNG: mm = (value - 32768) / 16384"},
      {"shading",
       "8-bit luminance: albedo 0.7 x (0.3 ambient + 0.75 key light from the upper "
       "left, (-0.35, 0.45, 1) in (right, up, out of the skin)), as the booth lights"},
      {"source",
       "Infinite, 3D Head Scan by Lee Perry-Smith, displacement map (CC BY 3.0); "
       "regions in its 4096 map, high-passed at 3 mm, depth scaled so the forehead's "
       "99th percentile is 0.4 mm, pixel size from a 63 mm eye distance"},
      {"exemplars", list}};
  std::ofstream(out / "exemplars.json") << doc.dump(2) << "\n";
  std::ofstream(out / "ATTRIBUTION.md")
      << "# Attribution\n\nThe wrinkle exemplars in this folder are derived from the displacement "
         "map of \"Infinite, 3D Head Scan\" by Lee Perry-Smith, licensed under a Creative "
         "Commons Attribution 3.0 Unported License (https://creativecommons.org/licenses/by/3.0/). "
         "Based on a work at www.triplegangers.com.\n\nChanges: crops of the forehead, the brow "
         "furrows and the crow's feet, high-passed, resampled to 0.25 mm per pixel, scaled to "
         "millimetres, rotated, and shaded; made by facebooth-convert-exemplars "
         "(host/convert_exemplars) from ../shared/skin/lps.\n";
  std::cout << "facebooth-convert-exemplars: " << list.size() << " exemplars into " << out << " ("
            << mm_per_grey << " mm per grey level)\n";
  return 0;
}
