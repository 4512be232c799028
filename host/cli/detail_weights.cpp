#include "host/cli/detail_weights.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>

#include "algo/tracking/arkit.hpp"
#include "host/cli/take_columns.hpp"
#include "storage/export/export_session.hpp"
#include "storage/export/png_file.hpp"

namespace fb::cli {

namespace {

struct DecodedMaps {
  FloatImage displacement;
  ColorImage normal;
};

Result<DecodedMaps> decode(const WrinkleDetailData& d) {
  DecodedMaps out;
  out.displacement.resize(d.width, d.height);
  out.displacement.pixels = d.displacement_mm;
  auto normal = decode_png(d.normal_png);
  if (!normal) return normal.failure();
  if (normal->width != d.width || normal->height != d.height)
    return fail("a stored wrinkle normal map is " + std::to_string(normal->width) + " x " +
                std::to_string(normal->height) + ", its displacement map " +
                std::to_string(d.width) + " x " + std::to_string(d.height) +
                "; rebuild the detail with facebooth wrinkles");
  out.normal = std::move(*normal);
  return out;
}

std::string column_name(const SessionDetailBlend& b, std::size_t e) {
  return b.expressions[e] + "@" + std::to_string(b.captures[e]);
}

}  // namespace

Result<std::vector<RigDetailCapture>> session_detail_captures(const SessionStore& store,
                                                              SessionId session,
                                                              const GuideSet& guide,
                                                              std::vector<std::string>* skipped) {
  auto details = store.wrinkle_details(session);
  if (!details) return details.failure();
  std::set<int> with_detail;
  for (const auto& d : *details) with_detail.insert(d.capture_index);
  std::vector<RigDetailCapture> out;
  if (!with_detail.contains(0)) return out;  // no neutral maps: nothing to blend
  auto captures = store.captures(session);
  if (!captures) return captures.failure();
  for (const int index : with_detail) {
    if (index == 0) continue;
    std::string expression;
    for (const auto& c : *captures)
      if (c.index == index) expression = c.expression;
    if (guide.find(expression) <= 0) {
      if (skipped != nullptr)
        skipped->push_back("capture " + std::to_string(index) + " ('" + expression +
                           "'): not a guide expression, so its blendshape weights are unknown");
      continue;
    }
    out.push_back({index, expression});
  }
  return out;
}

Result<SessionDetailBlend> load_session_detail_blend(const SessionStore& store, SessionId session,
                                                     const FaceModel& model,
                                                     const GuideSet& guide) {
  auto details = store.wrinkle_details(session);
  if (!details) return details.failure();
  std::map<int, WrinkleDetailId> newest;
  for (const auto& d : *details) newest[d.capture_index] = d.id;  // listed oldest first
  const std::string run = "facebooth wrinkles --store " + store.root().string() + " --session " +
                          std::to_string(session);
  if (newest.find(0) == newest.end())
    return fail("session " + std::to_string(session) +
                " has no wrinkle detail on its neutral (capture 0), so there are no map weights "
                "to compute; run `" +
                run + "` first");
  SessionDetailBlend out;
  auto with_detail = session_detail_captures(store, session, guide, &out.skipped);
  if (!with_detail) return with_detail.failure();
  std::vector<DecodedMaps> decoded;
  std::vector<std::vector<float>> recipes;
  std::vector<RigDetailCapture> all{{0, ""}};
  all.insert(all.end(), with_detail->begin(), with_detail->end());
  for (const auto& [index, expression] : all) {
    if (index != 0) {
      const int g = guide.find(expression);
      auto w = guide_weights(guide.expressions[static_cast<std::size_t>(g)], model);
      if (!w) return w.failure();
      w->resize(static_cast<std::size_t>(model.fitting_expression_count));
      recipes.push_back(std::move(*w));
    }
    auto data = store.read_wrinkle_detail(newest.at(index));
    if (!data) return data.failure();
    auto maps = decode(*data);
    if (!maps) return maps.failure();
    if (!decoded.empty() && (maps->displacement.width != decoded.front().displacement.width ||
                             maps->displacement.height != decoded.front().displacement.height))
      return fail("capture " + std::to_string(index) + "'s wrinkle maps are " +
                  std::to_string(maps->displacement.width) + " x " +
                  std::to_string(maps->displacement.height) +
                  ", the neutral's differ; rebuild them at one size: `" + run + "`");
    decoded.push_back(std::move(*maps));
    out.maps.push_back(std::move(*data));
    if (index == 0) continue;
    out.captures.push_back(index);
    out.expressions.push_back(expression);
  }
  if (out.captures.empty())
    return fail("session " + std::to_string(session) +
                " has wrinkle detail on its neutral only; the map weights need detail on its "
                "expressions (`" +
                run + "` builds every fitted capture's)");
  std::vector<DetailLayerView> layers;
  for (std::size_t e = 1; e < decoded.size(); ++e)
    layers.push_back({&decoded[e].displacement, &decoded[e].normal});
  auto blend = DetailBlend::build({&decoded[0].displacement, &decoded[0].normal}, layers, recipes,
                                  model.fitting_expression_count);
  if (!blend) return blend.failure();
  out.blend = std::move(*blend);
  return out;
}

Result<DetailWeightsCsv> DetailWeightsCsv::open(const std::filesystem::path& path,
                                                const SessionDetailBlend& blend) {
  DetailWeightsCsv csv;
  csv.path_ = path;
  csv.out_.open(path, std::ios::binary | std::ios::trunc);
  if (!csv.out_)
    return fail("cannot write the detail weights file " + path.string() +
                " (does its folder exist and is it writable?)");
  csv.out_ << header(blend) << "\n";
  return csv;
}

std::vector<std::string> detail_weight_columns(const SessionDetailBlend& blend) {
  std::vector<std::string> out;
  for (std::size_t e = 0; e < blend.captures.size(); ++e) out.push_back(column_name(blend, e));
  return out;
}

std::string DetailWeightsCsv::header(const SessionDetailBlend& blend) {
  std::string h = "frame,time_s,face_found";
  for (const auto& column : detail_weight_columns(blend)) h += "," + column;
  return h;
}

std::string DetailWeightsCsv::row(long long frame, double time_s, bool face_found,
                                  std::span<const float> weights) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%lld,%.6f,%d", frame, time_s, face_found ? 1 : 0);
  std::string r = buf;
  for (const float w : weights) {
    std::snprintf(buf, sizeof buf, ",%.6f", static_cast<double>(w));
    r += buf;
  }
  return r;
}

Result<void> DetailWeightsCsv::append(long long frame, double time_s, bool face_found,
                                      std::span<const float> weights) {
  out_ << row(frame, time_s, face_found, weights) << "\n";
  if (!out_) return fail("writing the detail weights file " + path_.string() + " failed");
  return success();
}

Result<void> DetailWeightsCsv::close() {
  out_.flush();
  const bool ok = static_cast<bool>(out_);
  out_.close();
  if (!ok) return fail("writing the detail weights file " + path_.string() + " failed");
  return success();
}

std::string detail_weights_description() {
  return "per frame one weight c_e per captured expression with wrinkle detail (column "
         "EXPRESSION@CAPTURE); the frame's detail maps are E = N + sum_e c_e (D_e - N) on the "
         "displacement (mm) and on the normal map's slopes (x/z, y/z; the normal is (sx, sy, 1) "
         "normalised), N the neutral's maps, D_e capture e's; c = pinv(W)^T a, W the captures' "
         "guide recipes over the face model's shapes, a the frame's shape weights "
         "(docs/wrinkles.md)";
}

Result<std::vector<float>> take_map_weights(const TakeData& take, const SessionDetailBlend& blend,
                                            const FaceModel& model) {
  auto mapping = make_arkit_mapping(model);
  if (!mapping) return mapping.failure();
  // The take's columns by ARKit name (camelCase or Live Link's), back to the model's shapes.
  const std::array<int, kArkitShapeCount> column = arkit_columns(take.info.shape_names);
  const std::size_t layers = blend.captures.size();
  std::vector<float> out(layers * static_cast<std::size_t>(take.info.frame_count));
  std::vector<float> weights(static_cast<std::size_t>(model.fitting_expression_count));
  for (int f = 0; f < take.info.frame_count; ++f) {
    std::fill(weights.begin(), weights.end(), 0.0f);
    mapping->to_model(arkit_curves(take, column, f), weights);
    blend.blend.map_weights(
        weights, std::span<float>(out).subspan(static_cast<std::size_t>(f) * layers, layers));
  }
  return out;
}

Result<int> write_take_detail_weights(ExportFolder& folder, const TakeData& take,
                                      const SessionDetailBlend& blend, const FaceModel& model) {
  auto c = take_map_weights(take, blend, model);
  if (!c) return c.failure();
  const std::size_t layers = blend.captures.size();
  std::string text = DetailWeightsCsv::header(blend) + "\n";
  for (int f = 0; f < take.info.frame_count; ++f)
    text += DetailWeightsCsv::row(
                f, take.times_s[static_cast<std::size_t>(f)], true,
                std::span<const float>(*c).subspan(static_cast<std::size_t>(f) * layers, layers)) +
            "\n";
  if (auto r =
          folder.write_text("take_" + std::to_string(take.info.id) + "_detail_weights.csv", text);
      !r)
    return r.failure();
  std::vector<int> indices{blend.neutral_capture};
  indices.insert(indices.end(), blend.captures.begin(), blend.captures.end());
  for (std::size_t i = 0; i < indices.size(); ++i) {
    const WrinkleDetailData& d = blend.maps[i];
    if (auto r =
            write_detail_map_files(folder, "wrinkles/capture_" + std::to_string(indices[i]), d);
        !r)
      return r.failure();
  }
  return static_cast<int>(blend.captures.size());
}

}  // namespace fb::cli
