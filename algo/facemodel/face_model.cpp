#include "algo/facemodel/face_model.hpp"

#include <Eigen/Core>
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <optional>
#include <set>
#include <string>

#include "algo/facemodel/face_model_format.hpp"

// The format is little-endian and the parser copies raw words. Every target of this project
// (x86-64, aarch64 boards) is little-endian; a big-endian port would need byte swaps here.
static_assert(std::endian::native == std::endian::little,
              "the .fbfm reader/writer assumes a little-endian host");
static_assert(std::numeric_limits<float>::is_iec559, "the .fbfm payload is IEEE-754 float32");

namespace fb {
namespace {

constexpr const char* kRegenerateHint =
    " Regenerate the asset with `facebooth-convert-facemodel --out data/facemodel.fbfm`"
    " (see data/README.md).";

std::string hex32(std::uint32_t v) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "0x%08X", v);
  return buf;
}

// Bounds-checked little-endian reads. Callers check sizes first; the checks here are a
// second line of defence so a logic slip becomes an error, not an out-of-bounds read.
template <class T>
T load(std::span<const std::byte> bytes, std::size_t offset) {
  T v{};
  if (offset <= bytes.size() && sizeof(T) <= bytes.size() - offset) {
    std::memcpy(&v, bytes.data() + offset, sizeof(T));
  }
  return v;
}

template <class T>
void store(std::vector<std::byte>& out, std::size_t offset, T v) {
  std::memcpy(out.data() + offset, &v, sizeof(T));
}

struct SectionEntry {
  std::uint32_t id = 0;
  std::uint32_t type = 0;
  std::uint64_t offset = 0;
  std::uint64_t size = 0;
};

// What each known section must look like. Sections with unknown ids are skipped, so later
// versions can add optional sections without breaking older readers.
struct SectionSpec {
  fbfm::SectionId id;
  fbfm::ElementType type;
  bool required;
};

constexpr SectionSpec kSectionSpecs[] = {
    {fbfm::SectionId::kNeutral, fbfm::ElementType::kFloat32, true},
    {fbfm::SectionId::kIdentityBasis, fbfm::ElementType::kFloat32, true},
    {fbfm::SectionId::kExpressionBasis, fbfm::ElementType::kFloat32, true},
    {fbfm::SectionId::kExpressionNames, fbfm::ElementType::kBytes, true},
    {fbfm::SectionId::kTriangles, fbfm::ElementType::kUint32, true},
    {fbfm::SectionId::kLandmarks, fbfm::ElementType::kUint32, true},
    {fbfm::SectionId::kRigidLandmarks, fbfm::ElementType::kUint32, true},
    {fbfm::SectionId::kRightJawline, fbfm::ElementType::kUint32, true},
    {fbfm::SectionId::kLeftJawline, fbfm::ElementType::kUint32, true},
    {fbfm::SectionId::kRightExtendedJawline, fbfm::ElementType::kUint32, true},
    {fbfm::SectionId::kLeftExtendedJawline, fbfm::ElementType::kUint32, true},
    {fbfm::SectionId::kFittingVertices, fbfm::ElementType::kUint32, true},
    {fbfm::SectionId::kRigidVertices, fbfm::ElementType::kUint32, true},
    {fbfm::SectionId::kProvenance, fbfm::ElementType::kBytes, false},
    {fbfm::SectionId::kUvs, fbfm::ElementType::kFloat32, false},
    {fbfm::SectionId::kTriangleUvs, fbfm::ElementType::kUint32, false},
};

const SectionSpec* find_spec(std::uint32_t id) {
  for (const auto& s : kSectionSpecs) {
    if (static_cast<std::uint32_t>(s.id) == id) return &s;
  }
  return nullptr;
}

class Parser {
 public:
  explicit Parser(std::span<const std::byte> bytes) : bytes_(bytes) {}

  Result<FaceModel> run();

 private:
  Result<void> check_header();
  Result<void> read_sections();
  Result<void> read_payload(FaceModel& m);
  std::optional<SectionEntry> section(fbfm::SectionId id) const {
    for (const auto& e : sections_) {
      if (e.id == static_cast<std::uint32_t>(id)) return e;
    }
    return std::nullopt;
  }
  std::span<const std::byte> section_bytes(const SectionEntry& e) const {
    return bytes_.subspan(static_cast<std::size_t>(e.offset), static_cast<std::size_t>(e.size));
  }
  Result<void> read_floats(fbfm::SectionId id, std::uint64_t expected_count,
                           std::vector<float>& out) const;
  Result<void> read_indices(fbfm::SectionId id, std::optional<std::uint64_t> expected_count,
                            std::uint64_t limit, const char* limit_what,
                            std::vector<std::uint32_t>& out) const;

  std::span<const std::byte> bytes_;
  std::uint64_t file_size_ = 0;
  std::uint32_t section_count_ = 0;
  std::uint32_t vertex_count_ = 0;
  std::uint32_t face_vertex_count_ = 0;
  std::uint32_t identity_count_ = 0;
  std::uint32_t expression_count_ = 0;
  std::uint32_t fitting_expression_count_ = 0;
  std::uint32_t triangle_count_ = 0;
  std::vector<SectionEntry> sections_;
};

Result<void> Parser::check_header() {
  const std::size_t n = bytes_.size();
  if (n == 0) return fail(std::string("face model: the file is empty.") + kRegenerateHint);

  // Compare the magic over whatever prefix exists, so a short prefix of a valid file is
  // reported as truncated and a foreign file as "not a face model".
  const std::size_t magic_have = std::min(n, fbfm::kMagic.size());
  for (std::size_t i = 0; i < magic_have; ++i) {
    if (static_cast<std::uint8_t>(bytes_[i]) != fbfm::kMagic[i]) {
      std::string got;
      for (std::size_t j = 0; j < magic_have; ++j) {
        char b[4];
        std::snprintf(b, sizeof b, "%02X", static_cast<unsigned>(bytes_[j]));
        got += (j ? " " : "");
        got += b;
      }
      return fail("face model: bad magic (first bytes " + got +
                  ", expected 46 42 46 4D 0D 0A 1A 0A = \"FBFM\\r\\n\\x1a\\n\"): this is not a "
                  "facebooth face model, or it was mangled by a text-mode copy." +
                  kRegenerateHint);
    }
  }
  if (n < fbfm::kOffVersion + 4) {
    return fail("face model: truncated at byte " + std::to_string(n) +
                ": the file ends inside the header (" + std::to_string(fbfm::kHeaderSize) +
                " bytes)." + kRegenerateHint);
  }
  const auto version = load<std::uint32_t>(bytes_, fbfm::kOffVersion);
  if (version == 0) {
    return fail(std::string("face model: invalid format version 0.") + kRegenerateHint);
  }
  if (version > fbfm::kFormatVersion) {
    return fail("face model: format version " + std::to_string(version) +
                " is newer than this build supports (version " +
                std::to_string(fbfm::kFormatVersion) +
                "). Update facebooth, or convert the model with this build's "
                "facebooth-convert-facemodel.");
  }
  if (n < fbfm::kHeaderSize) {
    return fail("face model: truncated at byte " + std::to_string(n) +
                ": the file ends inside the header (" + std::to_string(fbfm::kHeaderSize) +
                " bytes)." + kRegenerateHint);
  }
  file_size_ = load<std::uint64_t>(bytes_, fbfm::kOffFileSize);
  if (file_size_ > n) {
    return fail("face model: truncated at byte " + std::to_string(n) +
                ": the header says the file has " + std::to_string(file_size_) +
                " bytes. The copy is incomplete." + kRegenerateHint);
  }
  if (file_size_ < n) {
    return fail("face model: " + std::to_string(n - file_size_) +
                " unexpected trailing bytes after the declared end of the file (" +
                std::to_string(file_size_) + " bytes)." + kRegenerateHint);
  }
  const auto stored = load<std::uint32_t>(bytes_, fbfm::kOffChecksum);
  const auto computed = fbfm::crc32(bytes_.subspan(fbfm::kChecksumBegin));
  if (stored != computed) {
    return fail("face model: checksum mismatch (stored " + hex32(stored) + ", computed " +
                hex32(computed) + "): the file is corrupted." + kRegenerateHint);
  }
  section_count_ = load<std::uint32_t>(bytes_, fbfm::kOffSectionCount);
  if (section_count_ > fbfm::kMaxSections ||
      fbfm::kHeaderSize + std::uint64_t{section_count_} * fbfm::kSectionEntrySize > file_size_) {
    return fail("face model: the section table (" + std::to_string(section_count_) +
                " entries) does not fit in the file (" + std::to_string(file_size_) + " bytes)." +
                kRegenerateHint);
  }
  if (load<std::uint32_t>(bytes_, fbfm::kOffFlags) != 0 ||
      load<std::uint32_t>(bytes_, fbfm::kOffReserved) != 0) {
    return fail("face model: unknown header flags for format version " + std::to_string(version) +
                "; the file was written by an incompatible converter." + kRegenerateHint);
  }

  vertex_count_ = load<std::uint32_t>(bytes_, fbfm::kOffVertexCount);
  face_vertex_count_ = load<std::uint32_t>(bytes_, fbfm::kOffFaceVertexCount);
  identity_count_ = load<std::uint32_t>(bytes_, fbfm::kOffIdentityCount);
  expression_count_ = load<std::uint32_t>(bytes_, fbfm::kOffExpressionCount);
  fitting_expression_count_ = load<std::uint32_t>(bytes_, fbfm::kOffFittingExpressionCount);
  triangle_count_ = load<std::uint32_t>(bytes_, fbfm::kOffTriangleCount);
  const auto landmark_count = load<std::uint32_t>(bytes_, fbfm::kOffLandmarkCount);

  // Counts are bounded so that every later size computation fits in 64 bits and int.
  constexpr std::uint32_t kMaxVertices = 1u << 24;
  constexpr std::uint32_t kMaxShapes = 1u << 12;
  if (vertex_count_ == 0 || vertex_count_ > kMaxVertices) {
    return fail("face model: implausible vertex count " + std::to_string(vertex_count_) + "." +
                kRegenerateHint);
  }
  if (face_vertex_count_ > vertex_count_) {
    return fail("face model: face vertex count " + std::to_string(face_vertex_count_) +
                " exceeds the vertex count " + std::to_string(vertex_count_) + "." +
                kRegenerateHint);
  }
  if (identity_count_ > kMaxShapes || expression_count_ > kMaxShapes) {
    return fail("face model: implausible shape counts (" + std::to_string(identity_count_) +
                " identity modes, " + std::to_string(expression_count_) + " expressions)." +
                kRegenerateHint);
  }
  if (fitting_expression_count_ > expression_count_) {
    return fail("face model: fitting expression count " +
                std::to_string(fitting_expression_count_) + " exceeds the expression count " +
                std::to_string(expression_count_) + "." + kRegenerateHint);
  }
  if (triangle_count_ == 0 || triangle_count_ > (1u << 26)) {
    return fail("face model: implausible triangle count " + std::to_string(triangle_count_) + "." +
                kRegenerateHint);
  }
  if (landmark_count != 68) {
    return fail("face model: landmark count is " + std::to_string(landmark_count) +
                ", expected the 68 iBUG points." + kRegenerateHint);
  }
  return success();
}

Result<void> Parser::read_sections() {
  const std::uint64_t table_end =
      fbfm::kHeaderSize + std::uint64_t{section_count_} * fbfm::kSectionEntrySize;
  std::set<std::uint32_t> seen;
  for (std::uint32_t i = 0; i < section_count_; ++i) {
    const std::size_t at = fbfm::kHeaderSize + std::size_t{i} * fbfm::kSectionEntrySize;
    SectionEntry e;
    e.id = load<std::uint32_t>(bytes_, at);
    e.type = load<std::uint32_t>(bytes_, at + 4);
    e.offset = load<std::uint64_t>(bytes_, at + 8);
    e.size = load<std::uint64_t>(bytes_, at + 16);
    const std::string what = "face model: section " + std::string(fbfm::section_name(e.id)) +
                             " (table entry " + std::to_string(i) + ")";
    if (!seen.insert(e.id).second) {
      return fail(what + " appears twice." + kRegenerateHint);
    }
    if (e.offset < table_end || e.offset > file_size_ || e.size > file_size_ - e.offset) {
      return fail(what + " at offset " + std::to_string(e.offset) + " with " +
                  std::to_string(e.size) + " bytes lies outside the payload (file has " +
                  std::to_string(file_size_) + " bytes)." + kRegenerateHint);
    }
    const SectionSpec* spec = find_spec(e.id);
    if (spec == nullptr) continue;  // unknown optional section from a later converter
    if (e.type != static_cast<std::uint32_t>(spec->type)) {
      return fail(what + " has element type " + std::to_string(e.type) + ", expected " +
                  std::to_string(static_cast<std::uint32_t>(spec->type)) + "." + kRegenerateHint);
    }
    if (spec->type != fbfm::ElementType::kBytes && (e.offset % 4 != 0 || e.size % 4 != 0)) {
      return fail(what + " is not aligned to 4-byte words." + kRegenerateHint);
    }
    sections_.push_back(e);
  }
  for (const auto& spec : kSectionSpecs) {
    if (spec.required && !section(spec.id)) {
      return fail("face model: required section " +
                  std::string(fbfm::section_name(static_cast<std::uint32_t>(spec.id))) +
                  " is missing." + kRegenerateHint);
    }
  }
  return success();
}

Result<void> Parser::read_floats(fbfm::SectionId id, std::uint64_t expected_count,
                                 std::vector<float>& out) const {
  const SectionEntry e = *section(id);
  const std::string name(fbfm::section_name(e.id));
  if (e.size != expected_count * 4) {
    return fail("face model: section " + name + " has " + std::to_string(e.size) +
                " bytes, but the header counts need " + std::to_string(expected_count * 4) +
                " (counts do not fit the data)." + kRegenerateHint);
  }
  out.resize(static_cast<std::size_t>(expected_count));
  if (expected_count != 0) std::memcpy(out.data(), section_bytes(e).data(), e.size);
  // A NaN or infinity would silently poison every fit that touches the model.
  for (std::size_t i = 0; i < out.size(); ++i) {
    if (!std::isfinite(out[i])) {
      return fail("face model: section " + name + " holds a non-finite value at element " +
                  std::to_string(i) + "." + kRegenerateHint);
    }
  }
  return success();
}

Result<void> Parser::read_indices(fbfm::SectionId id, std::optional<std::uint64_t> expected_count,
                                  std::uint64_t limit, const char* limit_what,
                                  std::vector<std::uint32_t>& out) const {
  const SectionEntry e = *section(id);
  const std::string name(fbfm::section_name(e.id));
  if (expected_count && e.size != *expected_count * 4) {
    return fail("face model: section " + name + " has " + std::to_string(e.size) +
                " bytes, but the header counts need " + std::to_string(*expected_count * 4) +
                " (counts do not fit the data)." + kRegenerateHint);
  }
  out.resize(static_cast<std::size_t>(e.size / 4));
  if (!out.empty()) std::memcpy(out.data(), section_bytes(e).data(), e.size);
  for (std::size_t i = 0; i < out.size(); ++i) {
    if (out[i] >= limit) {
      return fail("face model: section " + name + " entry " + std::to_string(i) + " is " +
                  std::to_string(out[i]) + ", out of range (must be < " + std::to_string(limit) +
                  ", the " + limit_what + ")." + kRegenerateHint);
    }
  }
  return success();
}

Result<void> Parser::read_payload(FaceModel& m) {
  using fbfm::SectionId;
  const std::uint64_t n3 = std::uint64_t{vertex_count_} * 3;
  m.vertex_count = static_cast<int>(vertex_count_);
  m.face_vertex_count = static_cast<int>(face_vertex_count_);
  m.identity_count = static_cast<int>(identity_count_);
  m.expression_count = static_cast<int>(expression_count_);
  m.fitting_expression_count = static_cast<int>(fitting_expression_count_);

  if (auto r = read_floats(SectionId::kNeutral, n3, m.neutral); !r) return r;
  if (auto r = read_floats(SectionId::kIdentityBasis, n3 * identity_count_, m.identity_basis); !r)
    return r;
  if (auto r = read_floats(SectionId::kExpressionBasis, n3 * expression_count_, m.expression_basis);
      !r)
    return r;

  const char* kVerts = "vertex count";
  if (auto r = read_indices(SectionId::kTriangles, std::uint64_t{triangle_count_} * 3,
                            vertex_count_, kVerts, m.triangles);
      !r)
    return r;
  std::vector<std::uint32_t> landmarks;
  if (auto r = read_indices(SectionId::kLandmarks, 68, vertex_count_, kVerts, landmarks); !r)
    return r;
  std::copy(landmarks.begin(), landmarks.end(), m.landmark_vertices.begin());
  if (auto r = read_indices(SectionId::kRigidLandmarks, std::nullopt, 68, "number of landmarks",
                            m.rigid_landmarks);
      !r)
    return r;
  struct {
    SectionId id;
    std::vector<std::uint32_t>* out;
  } const lists[] = {
      {SectionId::kRightJawline, &m.right_jawline},
      {SectionId::kLeftJawline, &m.left_jawline},
      {SectionId::kRightExtendedJawline, &m.right_extended_jawline},
      {SectionId::kLeftExtendedJawline, &m.left_extended_jawline},
      {SectionId::kFittingVertices, &m.fitting_vertices},
      {SectionId::kRigidVertices, &m.rigid_vertices},
  };
  for (const auto& l : lists) {
    if (auto r = read_indices(l.id, std::nullopt, vertex_count_, kVerts, *l.out); !r) return r;
  }

  // Expression names: expression_count records of (u32 length, bytes).
  {
    const SectionEntry e = *section(SectionId::kExpressionNames);
    const auto s = section_bytes(e);
    std::size_t pos = 0;
    std::set<std::string, std::less<>> unique;
    for (std::uint32_t j = 0; j < expression_count_; ++j) {
      if (s.size() - pos < 4) {
        return fail("face model: section EXPRESSION_NAMES ends after " + std::to_string(j) +
                    " of " + std::to_string(expression_count_) + " names." + kRegenerateHint);
      }
      const auto len = load<std::uint32_t>(s, pos);
      pos += 4;
      if (len == 0 || len > 256 || len > s.size() - pos) {
        return fail("face model: section EXPRESSION_NAMES: name " + std::to_string(j) +
                    " has an invalid length " + std::to_string(len) + "." + kRegenerateHint);
      }
      std::string name(reinterpret_cast<const char*>(s.data() + pos), len);
      pos += len;
      for (const char c : name) {
        if (static_cast<unsigned char>(c) < 0x21 || static_cast<unsigned char>(c) > 0x7E) {
          return fail("face model: section EXPRESSION_NAMES: name " + std::to_string(j) +
                      " contains a non-printable character." + kRegenerateHint);
        }
      }
      if (!unique.insert(name).second) {
        return fail("face model: expression name \"" + name + "\" appears twice." +
                    kRegenerateHint);
      }
      m.expression_names.push_back(std::move(name));
    }
    if (pos != s.size()) {
      return fail("face model: section EXPRESSION_NAMES has " + std::to_string(s.size() - pos) +
                  " bytes after the last of " + std::to_string(expression_count_) +
                  " names (counts do not fit the data)." + kRegenerateHint);
    }
  }

  if (auto e = section(SectionId::kProvenance)) {
    const auto s = section_bytes(*e);
    m.provenance.assign(reinterpret_cast<const char*>(s.data()), s.size());
  }

  // UVs: optional, but the coordinates and the corners' indices only make sense together.
  const auto uvs = section(SectionId::kUvs);
  const auto corners = section(SectionId::kTriangleUvs);
  if (uvs.has_value() != corners.has_value()) {
    return fail(std::string("face model: section ") + (uvs ? "UVS" : "TRIANGLE_UVS") +
                " is there without " + (uvs ? "TRIANGLE_UVS" : "UVS") + "." + kRegenerateHint);
  }
  if (uvs) {
    if (uvs->size == 0 || uvs->size % 8 != 0) {
      return fail("face model: section UVS has " + std::to_string(uvs->size) +
                  " bytes, not a whole number of (u, v) pairs." + kRegenerateHint);
    }
    if (auto r = read_floats(SectionId::kUvs, uvs->size / 4, m.uvs); !r) return r;
    if (auto r = read_indices(SectionId::kTriangleUvs, std::uint64_t{triangle_count_} * 3,
                              uvs->size / 8, "UV count", m.triangle_uvs);
        !r)
      return r;
  }
  return success();
}

Result<FaceModel> Parser::run() {
  if (auto r = check_header(); !r) return r.failure();
  if (auto r = read_sections(); !r) return r.failure();
  FaceModel m;
  if (auto r = read_payload(m); !r) return r.failure();
  return m;
}

// Slicing-by-8 tables: 8 KiB, built once. About 10x faster than the bytewise loop, which
// matters because the whole 21 MB asset is checked on every load.
struct Crc32Tables {
  std::uint32_t t[8][256];
  Crc32Tables() {
    for (std::uint32_t i = 0; i < 256; ++i) {
      std::uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = (c & 1u) ? (0xEDB88320u ^ (c >> 1)) : (c >> 1);
      t[0][i] = c;
    }
    for (std::uint32_t i = 0; i < 256; ++i) {
      for (int s = 1; s < 8; ++s) t[s][i] = (t[s - 1][i] >> 8) ^ t[0][t[s - 1][i] & 0xFFu];
    }
  }
};

void append_u32(std::vector<std::byte>& out, std::uint32_t v) {
  const auto at = out.size();
  out.resize(at + 4);
  store(out, at, v);
}

}  // namespace

namespace fbfm {

std::string_view section_name(std::uint32_t id) {
  switch (static_cast<SectionId>(id)) {
    case SectionId::kNeutral:
      return "NEUTRAL";
    case SectionId::kIdentityBasis:
      return "IDENTITY_BASIS";
    case SectionId::kExpressionBasis:
      return "EXPRESSION_BASIS";
    case SectionId::kExpressionNames:
      return "EXPRESSION_NAMES";
    case SectionId::kTriangles:
      return "TRIANGLES";
    case SectionId::kLandmarks:
      return "LANDMARKS";
    case SectionId::kRigidLandmarks:
      return "RIGID_LANDMARKS";
    case SectionId::kRightJawline:
      return "RIGHT_JAWLINE";
    case SectionId::kLeftJawline:
      return "LEFT_JAWLINE";
    case SectionId::kRightExtendedJawline:
      return "RIGHT_EXTENDED_JAWLINE";
    case SectionId::kLeftExtendedJawline:
      return "LEFT_EXTENDED_JAWLINE";
    case SectionId::kFittingVertices:
      return "FITTING_VERTICES";
    case SectionId::kRigidVertices:
      return "RIGID_VERTICES";
    case SectionId::kUvs:
      return "UVS";
    case SectionId::kTriangleUvs:
      return "TRIANGLE_UVS";
    case SectionId::kProvenance:
      return "PROVENANCE";
  }
  return "UNKNOWN";
}

std::uint32_t crc32(std::span<const std::byte> bytes, std::uint32_t crc) {
  static const Crc32Tables tables;
  const auto& t = tables.t;
  std::uint32_t c = ~crc;
  const auto* p = reinterpret_cast<const std::uint8_t*>(bytes.data());
  std::size_t n = bytes.size();
  while (n >= 8) {
    std::uint32_t lo;
    std::uint32_t hi;
    std::memcpy(&lo, p, 4);
    std::memcpy(&hi, p + 4, 4);
    lo ^= c;
    c = t[7][lo & 0xFF] ^ t[6][(lo >> 8) & 0xFF] ^ t[5][(lo >> 16) & 0xFF] ^ t[4][lo >> 24] ^
        t[3][hi & 0xFF] ^ t[2][(hi >> 8) & 0xFF] ^ t[1][(hi >> 16) & 0xFF] ^ t[0][hi >> 24];
    p += 8;
    n -= 8;
  }
  while (n-- > 0) c = t[0][(c ^ *p++) & 0xFFu] ^ (c >> 8);
  return ~c;
}

void reseal_checksum(std::span<std::byte> file) {
  if (file.size() < kHeaderSize) return;
  const std::uint32_t c = crc32(file.subspan(kChecksumBegin));
  std::memcpy(file.data() + kOffChecksum, &c, 4);
}

}  // namespace fbfm

Result<FaceModel> parse_face_model(std::span<const std::byte> bytes) {
  return Parser(bytes).run();
}

Result<std::vector<std::byte>> serialize_face_model(const FaceModel& m) {
  using fbfm::ElementType;
  using fbfm::SectionId;
  const std::size_t n3 = static_cast<std::size_t>(std::max(m.vertex_count, 0)) * 3;
  if (m.vertex_count <= 0 || m.neutral.size() != n3 ||
      m.identity_basis.size() != n3 * static_cast<std::size_t>(std::max(m.identity_count, 0)) ||
      m.expression_basis.size() != n3 * static_cast<std::size_t>(std::max(m.expression_count, 0)) ||
      m.expression_names.size() != static_cast<std::size_t>(m.expression_count) ||
      m.triangles.size() % 3 != 0 || m.triangles.empty()) {
    return fail("serialize_face_model: the model's vectors do not match its counts");
  }
  if (m.uvs.size() % 2 != 0 || (m.uvs.empty() != m.triangle_uvs.empty()) ||
      (!m.triangle_uvs.empty() && m.triangle_uvs.size() != m.triangles.size())) {
    return fail("serialize_face_model: the UVs do not match the triangles");
  }
  if (m.face_vertex_count < 0 || m.face_vertex_count > m.vertex_count ||
      m.fitting_expression_count < 0 || m.fitting_expression_count > m.expression_count) {
    return fail("serialize_face_model: face vertex or fitting expression count out of range");
  }

  struct Pending {
    SectionId id;
    ElementType type;
    std::vector<std::byte> data;
  };
  std::vector<Pending> pending;
  auto add_raw = [&](SectionId id, ElementType type, const void* data, std::size_t size) {
    Pending p{id, type, std::vector<std::byte>(size)};
    if (size) std::memcpy(p.data.data(), data, size);
    pending.push_back(std::move(p));
  };
  auto add_f32 = [&](SectionId id, const std::vector<float>& v) {
    add_raw(id, ElementType::kFloat32, v.data(), v.size() * 4);
  };
  auto add_u32 = [&](SectionId id, std::span<const std::uint32_t> v) {
    add_raw(id, ElementType::kUint32, v.data(), v.size() * 4);
  };
  add_f32(SectionId::kNeutral, m.neutral);
  add_f32(SectionId::kIdentityBasis, m.identity_basis);
  add_f32(SectionId::kExpressionBasis, m.expression_basis);
  {
    std::vector<std::byte> names;
    for (const auto& name : m.expression_names) {
      append_u32(names, static_cast<std::uint32_t>(name.size()));
      const auto at = names.size();
      names.resize(at + name.size());
      std::memcpy(names.data() + at, name.data(), name.size());
    }
    pending.push_back({SectionId::kExpressionNames, ElementType::kBytes, std::move(names)});
  }
  add_u32(SectionId::kTriangles, m.triangles);
  add_u32(SectionId::kLandmarks, m.landmark_vertices);
  add_u32(SectionId::kRigidLandmarks, m.rigid_landmarks);
  add_u32(SectionId::kRightJawline, m.right_jawline);
  add_u32(SectionId::kLeftJawline, m.left_jawline);
  add_u32(SectionId::kRightExtendedJawline, m.right_extended_jawline);
  add_u32(SectionId::kLeftExtendedJawline, m.left_extended_jawline);
  add_u32(SectionId::kFittingVertices, m.fitting_vertices);
  add_u32(SectionId::kRigidVertices, m.rigid_vertices);
  if (!m.provenance.empty()) {
    add_raw(SectionId::kProvenance, ElementType::kBytes, m.provenance.data(), m.provenance.size());
  }
  if (!m.uvs.empty()) {
    add_f32(SectionId::kUvs, m.uvs);
    add_u32(SectionId::kTriangleUvs, m.triangle_uvs);
  }

  auto align = [](std::size_t v) {
    return (v + fbfm::kSectionAlignment - 1) / fbfm::kSectionAlignment * fbfm::kSectionAlignment;
  };
  const std::size_t table_end = fbfm::kHeaderSize + pending.size() * fbfm::kSectionEntrySize;
  std::size_t total = align(table_end);
  std::vector<std::size_t> offsets;
  for (const auto& p : pending) {
    offsets.push_back(total);
    total = align(total + p.data.size());
  }

  std::vector<std::byte> out(total, std::byte{0});
  std::memcpy(out.data(), fbfm::kMagic.data(), fbfm::kMagic.size());
  store<std::uint32_t>(out, fbfm::kOffVersion, fbfm::kFormatVersion);
  store<std::uint32_t>(out, fbfm::kOffSectionCount, static_cast<std::uint32_t>(pending.size()));
  store<std::uint64_t>(out, fbfm::kOffFileSize, total);
  store<std::uint32_t>(out, fbfm::kOffVertexCount, static_cast<std::uint32_t>(m.vertex_count));
  store<std::uint32_t>(out, fbfm::kOffFaceVertexCount,
                       static_cast<std::uint32_t>(m.face_vertex_count));
  store<std::uint32_t>(out, fbfm::kOffIdentityCount, static_cast<std::uint32_t>(m.identity_count));
  store<std::uint32_t>(out, fbfm::kOffExpressionCount,
                       static_cast<std::uint32_t>(m.expression_count));
  store<std::uint32_t>(out, fbfm::kOffFittingExpressionCount,
                       static_cast<std::uint32_t>(m.fitting_expression_count));
  store<std::uint32_t>(out, fbfm::kOffTriangleCount,
                       static_cast<std::uint32_t>(m.triangles.size() / 3));
  store<std::uint32_t>(out, fbfm::kOffLandmarkCount, 68u);
  for (std::size_t i = 0; i < pending.size(); ++i) {
    const std::size_t at = fbfm::kHeaderSize + i * fbfm::kSectionEntrySize;
    store<std::uint32_t>(out, at, static_cast<std::uint32_t>(pending[i].id));
    store<std::uint32_t>(out, at + 4, static_cast<std::uint32_t>(pending[i].type));
    store<std::uint64_t>(out, at + 8, offsets[i]);
    store<std::uint64_t>(out, at + 16, pending[i].data.size());
    if (!pending[i].data.empty()) {
      std::memcpy(out.data() + offsets[i], pending[i].data.data(), pending[i].data.size());
    }
  }
  fbfm::reseal_checksum(out);
  return out;
}

int FaceModel::uv_tiles() const {
  float max_u = 0.0f;
  for (const std::uint32_t i : triangle_uvs)
    if (2 * static_cast<std::size_t>(i) < uvs.size()) max_u = std::max(max_u, uvs[2 * i]);
  return std::max(1, static_cast<int>(std::ceil(max_u - 1e-6f)));
}

std::vector<float> FaceModel::atlas_uvs() const {
  std::vector<float> out = uvs;
  const auto tiles = static_cast<float>(uv_tiles());
  for (std::size_t i = 0; i < out.size(); i += 2) out[i] /= tiles;
  return out;
}

int FaceModel::expression_index(std::string_view name) const {
  for (std::size_t j = 0; j < expression_names.size(); ++j) {
    if (expression_names[j] == name) return static_cast<int>(j);
  }
  return -1;
}

std::span<const float> FaceModel::identity_mode(int k) const {
  const std::size_t n3 = static_cast<std::size_t>(vertex_count) * 3;
  return std::span<const float>(identity_basis).subspan(static_cast<std::size_t>(k) * n3, n3);
}

std::span<const float> FaceModel::expression_shape(int j) const {
  const std::size_t n3 = static_cast<std::size_t>(vertex_count) * 3;
  return std::span<const float>(expression_basis).subspan(static_cast<std::size_t>(j) * n3, n3);
}

namespace {

using VecMap = Eigen::Map<Eigen::VectorXf, Eigen::Unaligned>;
using ConstVecMap = Eigen::Map<const Eigen::VectorXf, Eigen::Unaligned>;

// result += sum_k coeffs[k] * basis block k, skipping zero coefficients. Eigen maps over the
// caller's memory: no allocation, and Eigen emits SIMD (SSE/AVX/NEON) for each axpy.
void accumulate(VecMap& result, std::span<const float> coeffs, std::size_t count,
                const std::vector<float>& basis, std::size_t stride) {
  const std::size_t n = std::min(coeffs.size(), count);
  for (std::size_t k = 0; k < n; ++k) {
    const float c = coeffs[k];
    if (c == 0.0f) continue;
    result += c * ConstVecMap(basis.data() + k * stride, result.size());
  }
}

}  // namespace

void FaceModel::evaluate(std::span<const float> identity_coeffs,
                         std::span<const float> expression_weights, std::span<float> out) const {
  // Each basis block is 3 * vertex_count floats; `n` may cover only a prefix of the vertices.
  const std::size_t stride = static_cast<std::size_t>(vertex_count) * 3;
  const std::size_t n = std::min(out.size(), std::min(stride, neutral.size()));
  if (n == 0) return;
  VecMap result(out.data(), static_cast<Eigen::Index>(n));
  result = ConstVecMap(neutral.data(), static_cast<Eigen::Index>(n));
  accumulate(result, identity_coeffs, static_cast<std::size_t>(identity_count), identity_basis,
             stride);
  accumulate(result, expression_weights, static_cast<std::size_t>(expression_count),
             expression_basis, stride);
}

void FaceModel::evaluate_expressions(std::span<const float> base,
                                     std::span<const float> expression_weights,
                                     std::span<float> out) const {
  const std::size_t stride = static_cast<std::size_t>(vertex_count) * 3;
  const std::size_t n = std::min({out.size(), base.size(), stride});
  if (n == 0) return;
  VecMap result(out.data(), static_cast<Eigen::Index>(n));
  if (base.data() != out.data()) result = ConstVecMap(base.data(), static_cast<Eigen::Index>(n));
  accumulate(result, expression_weights, static_cast<std::size_t>(expression_count),
             expression_basis, stride);
}

}  // namespace fb
