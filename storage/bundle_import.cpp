#include "storage/bundle_import.hpp"

#include <cstring>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <string_view>

#include "storage/export/mesh_files.hpp"
#include "storage/export/png_file.hpp"
#include "storage/sha256.hpp"

namespace fb {

namespace {

using nlohmann::json;
constexpr std::size_t kBlock = 512;

// An octal number field of a tar header (NUL/space padded); nullopt when it is not one (GNU's
// base-256 sizes included: a bundle never needs them).
std::optional<std::uint64_t> octal(const std::uint8_t* field, std::size_t width) {
  std::uint64_t v = 0;
  bool digits = false;
  for (std::size_t i = 0; i < width; ++i) {
    const char c = static_cast<char>(field[i]);
    if (c == '\0' || c == ' ') {
      if (digits) break;
      continue;
    }
    if (c < '0' || c > '7' || v > (std::uint64_t{1} << 60)) return std::nullopt;
    v = v * 8 + static_cast<std::uint64_t>(c - '0');
    digits = true;
  }
  if (!digits) return std::nullopt;
  return v;
}

std::string field_text(const std::uint8_t* field, std::size_t width) {
  const auto* p = reinterpret_cast<const char*>(field);
  return std::string(p, strnlen(p, width));
}

// Why a name may not be written under a folder (empty when it may): the one path check of a
// bundle, for archive entries and for the names its manifest and session.json list.
std::string unsafe_name(std::string_view name) {
  if (name.empty()) return "an empty name";
  if (name.front() == '/') return "an absolute path";
  if (name.find('\\') != std::string_view::npos) return "a backslash";
  std::size_t start = 0;
  while (start <= name.size()) {
    const std::size_t end = std::min(name.find('/', start), name.size());
    const std::string_view part = name.substr(start, end - start);
    if (part == "..") return "a '..' component";
    if (part == ".") return "a '.' component";
    if (part.empty()) return "an empty component";
    start = end + 1;
  }
  return {};
}

const char* kind_of(char type) {
  switch (type) {
    case '1':
      return "a hard link";
    case '2':
      return "a symbolic link";
    case '3':
    case '4':
      return "a device";
    case '6':
      return "a FIFO";
    case 'L':
    case 'K':
      return "a GNU long-name entry";
    case 'x':
    case 'g':
      return "a pax header";
    default:
      return "an entry of an unknown type";
  }
}

Failure refused(const std::string& name, const std::string& why) {
  return fail("the bundle's entry '" + name + "' is " + why +
              ": refused (a bundle holds plain files inside its own folder); nothing was written");
}

}  // namespace

Result<std::vector<TarEntry>> list_tar(std::span<const std::uint8_t> archive) {
  std::vector<TarEntry> out;
  std::set<std::string> seen;
  std::size_t at = 0;
  for (;;) {
    if (at + kBlock > archive.size())
      return fail("the bundle is truncated (no end-of-archive block after " + std::to_string(at) +
                  " bytes): the transfer was cut; sync again");
    const std::uint8_t* h = archive.data() + at;
    if (std::all_of(h, h + kBlock, [](std::uint8_t b) { return b == 0; })) break;
    std::string name = field_text(h, 100);
    if (std::memcmp(h + 257, "ustar", 5) == 0) {
      const std::string prefix = field_text(h + 345, 155);
      if (!prefix.empty()) name = prefix + "/" + name;
    }
    unsigned sum = 0;
    for (std::size_t i = 0; i < kBlock; ++i)
      sum += (i >= 148 && i < 156) ? ' ' : static_cast<unsigned>(h[i]);
    const auto stored = octal(h + 148, 8);
    if (!stored || *stored != sum)
      return fail("the bundle's header at byte " + std::to_string(at) +
                  " has a wrong checksum (not a tar archive, or damaged): refused; nothing was "
                  "written");
    const auto size = octal(h + 124, 12);
    if (!size) return refused(name, "of an unreadable size");
    const char type = static_cast<char>(h[156]);
    const bool file = type == '0' || type == '\0';
    if (!file && type != '5') return refused(name, kind_of(type));
    std::string_view checked = name;
    if (type == '5' && !checked.empty() && checked.back() == '/') checked.remove_suffix(1);
    if (const std::string why = unsafe_name(checked); !why.empty())
      return refused(name, "a path with " + why);
    const std::uint64_t data = at + kBlock;
    if (*size > archive.size() || data + *size > archive.size())
      return fail("the bundle is truncated inside '" + name +
                  "': the transfer was cut; sync again");
    if (file) {
      if (!seen.insert(name).second) return refused(name, "listed twice");
      out.push_back({name, data, *size});
    }
    at = data + (*size + kBlock - 1) / kBlock * kBlock;
  }
  return out;
}

namespace {

// The bundle's files by their name inside the top folder, each checked against the manifest.
struct BundleFiles {
  std::string folder;
  std::map<std::string, std::span<const std::uint8_t>> files;

  Result<std::span<const std::uint8_t>> get(const json& name, const std::string& what) const {
    if (!name.is_string()) return fail("session.json: " + what + " is not a file name");
    auto it = files.find(name.get<std::string>());
    if (it == files.end())
      return fail("session.json names " + what + " '" + name.get<std::string>() +
                  "', which is not in the bundle");
    return it->second;
  }
};

// A member of a JSON object, or null when it is absent or the value is no object. (The const
// operator[] on a missing key is undefined behaviour, the non-const one throws on a non-object:
// a hostile bundle must meet neither; fuzzing found the first.)
const json& member(const json& object, const char* key) {
  static const json kAbsent;  // immutable
  if (!object.is_object()) return kAbsent;
  const auto it = object.find(key);
  return it == object.end() ? kAbsent : *it;
}

// A string or integer member, or `otherwise` when absent or of another type (json::value throws
// on a present value of the wrong type).
std::string text_member(const json& object, const char* key, const std::string& otherwise) {
  const json& v = member(object, key);
  return v.is_string() ? v.get<std::string>() : otherwise;
}
int int_member(const json& object, const char* key, int otherwise) {
  const json& v = member(object, key);
  return v.is_number_integer() ? v.get<int>() : otherwise;
}

Result<json> parse_json(std::span<const std::uint8_t> bytes, const std::string& name) {
  auto j = json::parse(bytes.begin(), bytes.end(), nullptr, false);
  if (j.is_discarded() || !j.is_object()) return fail(name + " is not a JSON object");
  return j;
}

Result<BundleFiles> checked_files(std::span<const std::uint8_t> archive) {
  auto entries = list_tar(archive);
  if (!entries) return entries.failure();
  if (entries->empty()) return fail("the bundle is empty");
  BundleFiles b;
  b.folder = entries->front().name.substr(0, entries->front().name.find('/'));
  for (const auto& e : *entries) {
    if (e.name.size() <= b.folder.size() + 1 ||
        e.name.compare(0, b.folder.size() + 1, b.folder + "/") != 0)
      return refused(e.name, "outside the bundle's folder '" + b.folder + "/'");
    b.files[e.name.substr(b.folder.size() + 1)] = archive.subspan(e.offset, e.size);
  }
  auto manifest_bytes = b.files.find("manifest.json");
  if (manifest_bytes == b.files.end()) return fail("the bundle has no manifest.json");
  auto manifest = parse_json(manifest_bytes->second, "the bundle's manifest.json");
  if (!manifest) return manifest.failure();
  if (!member(*manifest, "files").is_array())
    return fail("the bundle's manifest.json lists no files");
  std::set<std::string> listed = {"manifest.json"};
  for (const auto& f : member(*manifest, "files")) {
    if (!f.is_object() || !member(f, "path").is_string() ||
        !member(f, "bytes").is_number_unsigned() || !member(f, "sha256").is_string())
      return fail("the bundle's manifest.json has a malformed entry: " + f.dump());
    const std::string path = member(f, "path").get<std::string>();
    if (const std::string why = unsafe_name(path); !why.empty())
      return refused(path, "listed in the manifest with " + why);
    auto it = b.files.find(path);
    if (it == b.files.end())
      return fail("the bundle lacks '" + path +
                  "', which its manifest lists: refused; nothing was written");
    if (it->second.size() != member(f, "bytes").get<std::uint64_t>() ||
        sha256_hex(it->second) != member(f, "sha256").get<std::string>())
      return fail("the bundle's file '" + path +
                  "' does not match the SHA-256 (or size) in the booth's manifest: damaged in "
                  "transfer or altered; refused, nothing was written (sync again; if it "
                  "repeats, check the booth's store with `store info --verify`)");
    listed.insert(path);
  }
  for (const auto& [name, bytes] : b.files)
    if (!listed.count(name))
      return refused(b.folder + "/" + name, "not listed in the bundle's manifest");
  return b;
}

Result<DepthImage> decode_pgm16(std::span<const std::uint8_t> bytes, const std::string& name) {
  // "P5\n<w> <h>\n65535\n" then big-endian samples (storage/export/png_file.cpp writes it).
  std::string head(reinterpret_cast<const char*>(bytes.data()),
                   std::min<std::size_t>(64, bytes.size()));
  int w = 0, h = 0, maxval = 0, used = 0;
  if (std::sscanf(head.c_str(), "P5 %d %d %d%n", &w, &h, &maxval, &used) != 3 || maxval != 65535 ||
      w <= 0 || h <= 0 || w > 16384 || h > 16384)
    return fail(name + " is not a 16-bit PGM depth map");
  const std::size_t start = static_cast<std::size_t>(used) + 1;  // one whitespace byte
  const std::size_t n = static_cast<std::size_t>(w) * static_cast<std::size_t>(h);
  if (bytes.size() != start + 2 * n)
    return fail(name + " has the wrong size for " + head.substr(0, start));
  DepthImage d;
  d.resize(w, h);
  for (std::size_t i = 0; i < n; ++i)
    d.pixels[i] = static_cast<std::uint16_t>(bytes[start + 2 * i] << 8 | bytes[start + 2 * i + 1]);
  return d;
}

Result<std::vector<Landmark>> decode_landmarks(std::span<const std::uint8_t> bytes,
                                               const std::string& name, LandmarkSource& source) {
  auto doc = parse_json(bytes, name);
  if (!doc) return doc.failure();
  source = text_member(*doc, "source", "") == "operator" ? LandmarkSource::kOperator
                                                         : LandmarkSource::kAutomatic;
  std::vector<Landmark> out;
  if (!member(*doc, "points").is_array()) return fail(name + " has no points");
  for (const auto& p : member(*doc, "points")) {
    if (!p.is_object() || !member(p, "u").is_number() || !member(p, "v").is_number())
      return fail(name + " has a point without u and v");
    Landmark l;
    l.u = member(p, "u").get<float>();
    l.v = member(p, "v").get<float>();
    if (p.contains("xyz_mm")) {
      const auto& x = member(p, "xyz_mm");
      if (!x.is_array() || x.size() != 3 || !x[0].is_number() || !x[1].is_number() ||
          !x[2].is_number())
        return fail(name + " has a malformed xyz_mm");
      l.has_3d = true;
      l.x = x[0].get<float>();
      l.y = x[1].get<float>();
      l.z = x[2].get<float>();
    }
    out.push_back(l);
  }
  return out;
}

Result<ImportedCapture> decode_capture(const BundleFiles& b, const json& c, std::size_t i) {
  ImportedCapture out;
  const std::string what = "session.json: capture " + std::to_string(i);
  if (!c.is_object() || !member(c, "index").is_number_integer() ||
      !member(c, "expression").is_string() || !member(c, "state").is_string())
    return fail(what + " is malformed");
  out.index = member(c, "index").get<int>();
  out.expression = member(c, "expression").get<std::string>();
  const std::string state = member(c, "state").get<std::string>();
  out.state = state == "done"        ? CaptureState::kDone
              : state == "rejected"  ? CaptureState::kRejected
              : state == "capturing" ? CaptureState::kCapturing
                                     : CaptureState::kPending;
  out.attempts = int_member(c, "attempts", 0);
  if (member(c, "qa").is_object())
    for (const auto& [k, v] : member(c, "qa").items())
      if (v.is_number()) out.qa_scores[k] = v.get<double>();
  if (out.state != CaptureState::kDone) return out;
  // The frontal colour frame stands for the take (the booth keeps the head-turn sequence).
  auto color = b.get(member(c, "color"), "the colour frame of " + out.expression);
  if (!color) return color.failure();
  auto image = decode_png(std::vector<std::uint8_t>(color->begin(), color->end()));
  if (!image) return fail("the colour frame of " + out.expression + ": " + image.error().message);
  out.frames.emplace_back();
  out.frames.back().color = std::move(*image);
  if (c.contains("fused_depth")) {
    auto bytes = b.get(member(c, "fused_depth"), "the fused depth of " + out.expression);
    if (!bytes) return bytes.failure();
    auto depth = decode_pgm16(*bytes, member(c, "fused_depth").get<std::string>());
    if (!depth) return depth.failure();
    out.fused_depth = std::move(*depth);
  }
  if (c.contains("landmarks")) {
    auto bytes = b.get(member(c, "landmarks"), "the landmarks of " + out.expression);
    if (!bytes) return bytes.failure();
    auto points =
        decode_landmarks(*bytes, member(c, "landmarks").get<std::string>(), out.landmark_source);
    if (!points) return points.failure();
    out.landmarks = std::move(*points);
  }
  if (c.contains("mesh")) {
    auto bytes = b.get(member(c, "mesh"), "the mesh of " + out.expression);
    if (!bytes) return bytes.failure();
    auto mesh =
        parse_obj(std::string_view(reinterpret_cast<const char*>(bytes->data()), bytes->size()),
                  member(c, "mesh").get<std::string>());
    if (!mesh) return mesh.failure();
    out.mesh = std::move(mesh->mesh);
    out.mesh_role =
        text_member(c, "mesh_role", "fitted") == "neutral" ? MeshRole::kNeutral : MeshRole::kFitted;
  }
  return out;
}

}  // namespace

Result<SessionImport> read_session_bundle(std::span<const std::uint8_t> archive,
                                          const std::string& booth, std::int64_t expected_session) {
  auto b = checked_files(archive);
  if (!b) return b.failure();
  auto session_bytes = b->files.find("session.json");
  if (session_bytes == b->files.end()) return fail("the bundle has no session.json");
  auto doc = parse_json(session_bytes->second, "the bundle's session.json");
  if (!doc) return doc.failure();
  const json& s = *doc;
  if (text_member(s, "format", "") != "facebooth-session-bundle" ||
      !member(s, "session").is_number_integer() || !member(s, "subject_id").is_number_integer() ||
      !member(s, "captures").is_array())
    return fail("the bundle's session.json is not a facebooth session bundle");
  SessionImport out;
  out.booth = booth;
  out.origin_session = member(s, "session").get<std::int64_t>();
  out.origin_subject = member(s, "subject_id").get<std::int64_t>();
  out.subject_name = text_member(s, "subject", "");
  if (expected_session > 0 && out.origin_session != expected_session)
    return fail("the bundle holds session " + std::to_string(out.origin_session) +
                ", not the session " + std::to_string(expected_session) + " asked for");
  if (s.contains("calibration")) {
    auto bytes = b->get(member(s, "calibration"), "the calibration");
    if (!bytes) return bytes.failure();
    out.calibration_json.assign(reinterpret_cast<const char*>(bytes->data()), bytes->size());
  }
  for (std::size_t i = 0; i < member(s, "captures").size(); ++i) {
    auto c = decode_capture(*b, member(s, "captures")[i], i);
    if (!c)
      return fail("session " + std::to_string(out.origin_session) + " of booth " + booth + ": " +
                  c.error().message);
    out.captures.push_back(std::move(*c));
  }
  return out;
}

}  // namespace fb
