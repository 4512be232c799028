// facebooth-convert-facemodel: turns the ICT FaceKit "Light" source folder (OBJ + JSON, cm)
// into the compact asset data/facemodel.fbfm (float32, mm) that the rest of the project loads.
//
// Usage: facebooth-convert-facemodel [--source DIR] [--out FILE]
// See data/README.md for the output layout and SOURCE.md in the source folder for the input.
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"
#include "algo/facemodel/face_model_format.hpp"

namespace fs = std::filesystem;

namespace fb {
namespace {

// The skin surface the project works with: face (0-9408) + back of head (9409-11247), and
// the polygons 0-11143 that cover exactly those vertices (upstream README table).
constexpr int kSkinVertexCount = 11248;
constexpr int kFaceVertexCount = 9409;
constexpr int kSkinPolygonCount = 11144;
constexpr int kSourceVertexCount = 26719;
constexpr double kCmToMm = 10.0;
constexpr const char* kExtraExpressions[] = {"cheekRaiser_L", "cheekRaiser_R", "PupilDilate_L",
                                             "PupilDilate_R"};

struct ConvertOptions {
  fs::path source_dir;
  fs::path out_file;
};

// Where the converter found each input; the OBJ and vertex_indices.json live in FaceXModel/
// in the shared snapshot, but a flat folder (everything in DIR) is accepted too.
struct SourceLayout {
  fs::path model_dir;
  fs::path vertex_indices_json;
  fs::path jawline_json;
};

Result<std::string> read_text(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return fail("cannot open " + path.string());
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) return fail("error while reading " + path.string());
  return ss.str();
}

std::optional<fs::path> find_in(const fs::path& dir, const std::vector<fs::path>& subdirs,
                                const std::string& name) {
  for (const auto& sub : subdirs) {
    fs::path p = dir / sub / name;
    std::error_code ec;
    if (fs::is_regular_file(p, ec)) return p;
  }
  return std::nullopt;
}

Result<SourceLayout> locate_source(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) {
    return fail("source directory " + dir.string() +
                " does not exist. Pass --source with the ICT FaceKit folder (the one holding "
                "SOURCE.md and FaceXModel/).");
  }
  const std::vector<fs::path> subdirs = {"FaceXModel", "."};
  SourceLayout s;
  auto neutral = find_in(dir, subdirs, "generic_neutral_mesh.obj");
  auto indices = find_in(dir, subdirs, "vertex_indices.json");
  auto jaw = find_in(dir, {".", "FaceXModel", ".."}, "jawline_indices.json");
  if (!neutral || !indices || !jaw) {
    std::string missing;
    if (!neutral) missing += " generic_neutral_mesh.obj";
    if (!indices) missing += " vertex_indices.json";
    if (!jaw) missing += " jawline_indices.json";
    return fail("source directory " + dir.string() + " is missing:" + missing +
                " (looked in it and in its FaceXModel/ subfolder). Is this the ICT FaceKit "
                "folder from ../shared/facemodel/ict-facekit?");
  }
  s.model_dir = neutral->parent_path();
  s.vertex_indices_json = *indices;
  s.jawline_json = *jaw;
  return s;
}

// Parsed OBJ content that the converter needs: all `v` positions (cm, double) and, when asked,
// the polygons as 0-based vertex index lists.
struct ObjData {
  std::vector<double> positions;  // 3 per vertex
  std::vector<std::vector<int>> polygons;
  std::vector<double> uvs;                    // 2 per `vt` line (with polygons only)
  std::vector<std::vector<int>> polygon_uvs;  // 0-based vt index per corner, -1 = none
};

std::string_view trim_left(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  return s;
}

Result<ObjData> parse_obj(const fs::path& path, bool want_polygons) {
  auto text = read_text(path);
  if (!text) return text.failure();
  ObjData obj;
  obj.positions.reserve(3 * kSourceVertexCount);
  std::string_view rest(*text);
  int line_no = 0;
  auto garbled = [&](const std::string& why) {
    return fail(path.string() + ":" + std::to_string(line_no) + ": " + why +
                ". The source file looks damaged; copy it again from the ICT FaceKit snapshot.");
  };
  while (!rest.empty()) {
    ++line_no;
    const auto eol = rest.find('\n');
    std::string_view line = rest.substr(0, eol);
    rest = eol == std::string_view::npos ? std::string_view{} : rest.substr(eol + 1);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    if (line.size() >= 2 && line[0] == 'v' && (line[1] == ' ' || line[1] == '\t')) {
      std::string_view p = line.substr(2);
      for (int k = 0; k < 3; ++k) {
        p = trim_left(p);
        double value = 0.0;
        const auto [end, ec] = std::from_chars(p.data(), p.data() + p.size(), value);
        if (ec != std::errc() || !std::isfinite(value)) {
          return garbled("cannot read coordinate " + std::to_string(k + 1) + " of a `v` line");
        }
        obj.positions.push_back(value);
        p.remove_prefix(static_cast<std::size_t>(end - p.data()));
      }
    } else if (want_polygons && line.size() >= 3 && line[0] == 'v' && line[1] == 't' &&
               (line[2] == ' ' || line[2] == '\t')) {
      std::string_view p = line.substr(3);
      for (int k = 0; k < 2; ++k) {
        p = trim_left(p);
        double value = 0.0;
        const auto [end, ec] = std::from_chars(p.data(), p.data() + p.size(), value);
        if (ec != std::errc() || !std::isfinite(value)) {
          return garbled("cannot read coordinate " + std::to_string(k + 1) + " of a `vt` line");
        }
        obj.uvs.push_back(value);
        p.remove_prefix(static_cast<std::size_t>(end - p.data()));
      }
    } else if (want_polygons && line.size() >= 2 && line[0] == 'f' && line[1] == ' ') {
      std::vector<int> poly;
      std::vector<int> poly_uvs;
      std::string_view p = line.substr(2);
      while (true) {
        p = trim_left(p);
        if (p.empty()) break;
        int index = 0;
        const auto [end, ec] = std::from_chars(p.data(), p.data() + p.size(), index);
        if (ec != std::errc() || index <= 0) {
          // Negative (relative) indices are legal OBJ but never used by this model.
          return garbled("cannot read a positive vertex index in an `f` line");
        }
        poly.push_back(index - 1);
        p.remove_prefix(static_cast<std::size_t>(end - p.data()));
        int uv = 0;
        if (!p.empty() && p.front() == '/') {  // "v/vt", "v/vt/vn" or "v//vn"
          p.remove_prefix(1);
          const auto [uv_end, uv_ec] = std::from_chars(p.data(), p.data() + p.size(), uv);
          if (uv_ec != std::errc())
            uv = 0;
          else
            p.remove_prefix(static_cast<std::size_t>(uv_end - p.data()));
        }
        poly_uvs.push_back(uv - 1);
        while (!p.empty() && p.front() != ' ' && p.front() != '\t') p.remove_prefix(1);  // "/vn"
      }
      if (poly.size() < 3) return garbled("polygon with fewer than 3 vertices");
      obj.polygons.push_back(std::move(poly));
      obj.polygon_uvs.push_back(std::move(poly_uvs));
    }
  }
  if (obj.positions.size() != 3u * kSourceVertexCount) {
    return fail(path.string() + " has " + std::to_string(obj.positions.size() / 3) +
                " vertices, expected " + std::to_string(kSourceVertexCount) +
                " (every ICT FaceKit shape has the same vertices). The file is truncated or "
                "not part of this model.");
  }
  return obj;
}

// Reads a JSON array of non-negative integers.
Result<std::vector<std::uint32_t>> index_list(const nlohmann::json& doc, const std::string& key,
                                              const fs::path& file) {
  if (!doc.contains(key) || !doc[key].is_array()) {
    return fail(file.string() + " has no array \"" + key + "\"");
  }
  std::vector<std::uint32_t> out;
  for (const auto& v : doc[key]) {
    if (!v.is_number_integer() || v.get<long long>() < 0) {
      return fail(file.string() + ": \"" + key + "\" holds a value that is not a vertex index");
    }
    out.push_back(static_cast<std::uint32_t>(v.get<long long>()));
  }
  return out;
}

Result<nlohmann::json> read_json(const fs::path& path) {
  auto text = read_text(path);
  if (!text) return text.failure();
  auto doc = nlohmann::json::parse(*text, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded()) return fail(path.string() + " is not valid JSON");
  return doc;
}

// Appends (shape - neutral) for the skin vertices, in mm, computed in double so the stored
// float delta is as accurate as float allows.
void append_delta(const ObjData& shape, const ObjData& neutral, std::vector<float>& out) {
  for (int i = 0; i < 3 * kSkinVertexCount; ++i) {
    out.push_back(static_cast<float>((shape.positions[i] - neutral.positions[i]) * kCmToMm));
  }
}

double dist2(const ObjData& obj, int a, int b) {
  double d = 0.0;
  for (int k = 0; k < 3; ++k) {
    const double t = obj.positions[3 * a + k] - obj.positions[3 * b + k];
    d += t * t;
  }
  return d;
}

// The skin's UV layout: the distinct (u, v) values its triangle corners use (the source repeats
// some values under several vt indices), numbered in order of first use, and each corner's index
// into them.
Result<void> keep_uvs(const ObjData& neutral, const std::vector<int>& corner_uvs, FaceModel& m) {
  const int source_uvs = static_cast<int>(neutral.uvs.size() / 2);
  std::map<std::pair<float, float>, std::uint32_t> numbered;
  for (std::size_t c = 0; c < corner_uvs.size(); ++c) {
    const int uv = corner_uvs[c];
    if (uv < 0 || uv >= source_uvs) {
      return fail("generic_neutral_mesh.obj: skin triangle corner " + std::to_string(c) +
                  " has no valid texture coordinate (vt index " + std::to_string(uv + 1) + " of " +
                  std::to_string(source_uvs) + ")");
    }
    const std::pair<float, float> value(
        static_cast<float>(neutral.uvs[2 * static_cast<std::size_t>(uv)]),
        static_cast<float>(neutral.uvs[2 * static_cast<std::size_t>(uv) + 1]));
    const auto [it, added] = numbered.emplace(value, static_cast<std::uint32_t>(m.uvs.size() / 2));
    if (added) {
      m.uvs.push_back(value.first);
      m.uvs.push_back(value.second);
    }
    m.triangle_uvs.push_back(it->second);
  }
  std::cerr << "  UVs: " << m.uvs.size() / 2 << " distinct texture coordinates on the skin (the "
            << "source has " << source_uvs << " vt lines)\n";
  return success();
}

Result<void> triangulate(const ObjData& neutral, FaceModel& m) {
  if (static_cast<int>(neutral.polygons.size()) < kSkinPolygonCount) {
    return fail("generic_neutral_mesh.obj has only " + std::to_string(neutral.polygons.size()) +
                " polygons, expected at least " + std::to_string(kSkinPolygonCount));
  }
  int quads = 0;
  int tris = 0;
  std::vector<int> corner_uvs;  // source vt index per triangle corner
  for (int p = 0; p < kSkinPolygonCount; ++p) {
    const auto& poly = neutral.polygons[p];
    for (const int v : poly) {
      if (v >= kSkinVertexCount) {
        return fail("generic_neutral_mesh.obj: skin polygon " + std::to_string(p) +
                    " references vertex " + std::to_string(v) + ", beyond the skin block 0-" +
                    std::to_string(kSkinVertexCount - 1) +
                    ". The polygon order differs from the ICT FaceKit layout this converter "
                    "expects.");
      }
    }
    const auto& poly_uvs = neutral.polygon_uvs[p];
    auto tri = [&](int a, int b, int c) {
      for (int k : {a, b, c}) {
        m.triangles.push_back(static_cast<std::uint32_t>(poly[k]));
        corner_uvs.push_back(poly_uvs[k]);
      }
    };
    if (poly.size() == 3) {
      tri(0, 1, 2);
      ++tris;
    } else if (poly.size() == 4) {
      // Split along the shorter diagonal: better-shaped triangles keep cotangent Laplacian
      // weights (used by the refinement fit) positive. Winding is kept from the OBJ.
      if (dist2(neutral, poly[0], poly[2]) <= dist2(neutral, poly[1], poly[3])) {
        tri(0, 1, 2);
        tri(0, 2, 3);
      } else {
        tri(0, 1, 3);
        tri(1, 2, 3);
      }
      ++quads;
    } else {
      for (std::size_t k = 1; k + 1 < poly.size(); ++k)
        tri(0, static_cast<int>(k), static_cast<int>(k + 1));
    }
  }
  std::cerr << "  skin polygons: " << kSkinPolygonCount << " (" << quads << " quads, " << tris
            << " triangles) -> " << m.triangles.size() / 3 << " triangles\n";
  return keep_uvs(neutral, corner_uvs, m);
}

Result<FaceModel> convert(const SourceLayout& src) {
  FaceModel m;
  m.vertex_count = kSkinVertexCount;
  m.face_vertex_count = kFaceVertexCount;

  std::cerr << "reading " << src.vertex_indices_json.string() << "\n";
  auto indices_doc = read_json(src.vertex_indices_json);
  if (!indices_doc) return indices_doc.failure();
  auto jaw_doc = read_json(src.jawline_json);
  if (!jaw_doc) return jaw_doc.failure();

  std::cerr << "reading neutral mesh\n";
  auto neutral = parse_obj(src.model_dir / "generic_neutral_mesh.obj", true);
  if (!neutral) return neutral.failure();
  m.neutral.reserve(3 * kSkinVertexCount);
  for (int i = 0; i < 3 * kSkinVertexCount; ++i) {
    m.neutral.push_back(static_cast<float>(neutral->positions[i] * kCmToMm));
  }
  if (auto r = triangulate(*neutral, m); !r) return r.failure();

  // Identity modes: identity000.obj, identity001.obj, ... as many as exist consecutively.
  for (int k = 0;; ++k) {
    char name[32];
    std::snprintf(name, sizeof name, "identity%03d.obj", k);
    const fs::path path = src.model_dir / name;
    std::error_code ec;
    if (!fs::is_regular_file(path, ec)) break;
    auto shape = parse_obj(path, false);
    if (!shape) return shape.failure();
    append_delta(*shape, *neutral, m.identity_basis);
    ++m.identity_count;
    if (k % 10 == 9) std::cerr << "  identity modes: " << (k + 1) << "\n";
  }
  if (m.identity_count == 0) {
    return fail("no identity000.obj in " + src.model_dir.string() +
                ": the identity modes are missing from the source folder");
  }

  auto expressions =
      indices_doc->contains("expressions") && (*indices_doc)["expressions"].is_array()
          ? (*indices_doc)["expressions"]
          : nlohmann::json();
  if (expressions.is_null() || expressions.empty()) {
    return fail(src.vertex_indices_json.string() + " has no \"expressions\" list");
  }
  std::vector<std::string> names;
  for (const auto& e : expressions) {
    if (!e.is_string()) return fail(src.vertex_indices_json.string() + ": non-string expression");
    names.push_back(e.get<std::string>());
  }
  m.fitting_expression_count = static_cast<int>(names.size());
  for (const char* extra : kExtraExpressions) names.emplace_back(extra);
  for (std::size_t j = 0; j < names.size(); ++j) {
    const fs::path path = src.model_dir / (names[j] + ".obj");
    auto shape = parse_obj(path, false);
    if (!shape) return shape.failure();
    append_delta(*shape, *neutral, m.expression_basis);
    m.expression_names.push_back(names[j]);
    ++m.expression_count;
    if (j % 10 == 9 || j + 1 == names.size()) {
      std::cerr << "  expressions: " << (j + 1) << "/" << names.size() << "\n";
    }
  }

  const auto& vi = src.vertex_indices_json;
  auto landmarks = index_list(*indices_doc, "idx_to_landmark_verts", vi);
  if (!landmarks) return landmarks.failure();
  if (landmarks->size() != 68) {
    return fail(vi.string() + ": idx_to_landmark_verts has " + std::to_string(landmarks->size()) +
                " entries, expected 68");
  }
  std::copy(landmarks->begin(), landmarks->end(), m.landmark_vertices.begin());
  auto rigid_lmk = index_list(*indices_doc, "idx_to_rigid_landmark_idx", vi);
  if (!rigid_lmk) return rigid_lmk.failure();
  m.rigid_landmarks = std::move(*rigid_lmk);

  const auto& jf = src.jawline_json;
  struct {
    const char* key;
    std::vector<std::uint32_t>* out;
  } const jaw[] = {
      {"right_jawline_for_lmk_0_7", &m.right_jawline},
      {"left_jawline_for_lmk_9_16", &m.left_jawline},
      {"right_extended_jawline", &m.right_extended_jawline},
      {"left_extended_jawline", &m.left_extended_jawline},
  };
  for (const auto& j : jaw) {
    auto list = index_list(*jaw_doc, j.key, jf);
    if (!list) return list.failure();
    *j.out = std::move(*list);
  }

  // Fitting and rigid vertex subsets, restricted to the skin (the rigid list also covers
  // eyes and teeth, which this asset does not carry).
  auto restrict = [&](const char* key, std::vector<std::uint32_t>& out) -> Result<void> {
    auto list = index_list(*indices_doc, key, vi);
    if (!list) return list.failure();
    for (const auto v : *list) {
      if (v < static_cast<std::uint32_t>(kSkinVertexCount)) out.push_back(v);
    }
    std::cerr << "  " << key << ": kept " << out.size() << " of " << list->size()
              << " (skin only)\n";
    return success();
  };
  if (auto r = restrict("idx_to_fitting_verts", m.fitting_vertices); !r) return r.failure();
  if (auto r = restrict("idx_to_rigid_verts", m.rigid_vertices); !r) return r.failure();

  m.provenance =
      "ICT FaceKit \"Light\" face model (github.com/ICT-VGL/ICT-FaceKit, commit "
      "da5f95a607f5e6b37755b38d3385d7f2853732e5), MIT License, Copyright (c) 2020 USC "
      "Institute for Creative Technologies; see data/LICENSE. Converted by "
      "facebooth-convert-facemodel: skin vertices 0-11247, millimetres, float32 deltas, the "
      "source's UV layout for the skin.";
  return m;
}

Result<void> write_file(const fs::path& path, const std::vector<std::byte>& bytes) {
  std::error_code ec;
  if (path.has_parent_path()) fs::create_directories(path.parent_path(), ec);
  // Write to a temporary name and rename, so a crash never leaves a half-written asset
  // in place of a good one.
  fs::path tmp = path;
  tmp += ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) {
      return fail("cannot create " + tmp.string() +
                  ": check that the directory exists and is writable, or pass another --out");
    }
    out.write(reinterpret_cast<const char*>(bytes.data()),
              static_cast<std::streamsize>(bytes.size()));
    out.flush();
    if (!out) return fail("error while writing " + tmp.string() + " (disk full?)");
  }
  fs::rename(tmp, path, ec);
  if (ec)
    return fail("cannot rename " + tmp.string() + " to " + path.string() + ": " + ec.message());
  return success();
}

void print_usage(std::ostream& os) {
  os << "Usage: facebooth-convert-facemodel [--source DIR] [--out FILE]\n"
        "  --source DIR  ICT FaceKit folder (default: " FB_DEFAULT_SOURCE_DIR
        ")\n"
        "  --out FILE    output asset (default: " FB_DEFAULT_OUT_FILE ")\n";
}

}  // namespace
}  // namespace fb

int main(int argc, char** argv) {
  using namespace fb;
  ConvertOptions opt{FB_DEFAULT_SOURCE_DIR, FB_DEFAULT_OUT_FILE};
  for (int i = 1; i < argc; ++i) {
    const std::string_view a = argv[i];
    if (a == "-h" || a == "--help") {
      print_usage(std::cout);
      return 0;
    }
    if ((a == "--source" || a == "--out") && i + 1 < argc) {
      (a == "--source" ? opt.source_dir : opt.out_file) = argv[++i];
    } else if (a == "--source" || a == "--out") {
      std::cerr << "error: " << a << " needs a value\n";
      print_usage(std::cerr);
      return 2;
    } else {
      std::cerr << "error: unknown argument '" << a << "'\n";
      print_usage(std::cerr);
      return 2;
    }
  }

  auto layout = locate_source(opt.source_dir);
  if (!layout) {
    std::cerr << "error: " << layout.error().message << "\n";
    return 1;
  }
  std::cerr << "converting " << layout->model_dir.string() << "\n";
  auto model = convert(*layout);
  if (!model) {
    std::cerr << "error: " << model.error().message << "\n";
    return 1;
  }
  auto bytes = serialize_face_model(*model);
  if (!bytes) {
    std::cerr << "error: " << bytes.error().message << "\n";
    return 1;
  }
  // Parse what we are about to write: the converter must never ship an asset the loader rejects.
  if (auto check = parse_face_model(*bytes); !check) {
    std::cerr << "error: internal: the written model does not parse back: " << check.error().message
              << "\n";
    return 1;
  }
  if (auto r = write_file(opt.out_file, *bytes); !r) {
    std::cerr << "error: " << r.error().message << "\n";
    return 1;
  }
  std::cerr << "wrote " << opt.out_file.string() << ": " << bytes->size() << " bytes, "
            << model->vertex_count << " vertices, " << model->triangle_count() << " triangles, "
            << model->identity_count << " identity modes, " << model->expression_count
            << " expressions\n";
  return 0;
}
