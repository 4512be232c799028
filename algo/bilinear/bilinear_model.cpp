#include "algo/bilinear/bilinear_model.hpp"

#include <bit>
#include <cstring>

#include "algo/facemodel/face_model_format.hpp"  // fbfm::crc32 (CRC-32, zlib polynomial)

namespace fb {
namespace {

static_assert(std::endian::native == std::endian::little,
              "the model file is little-endian; add byte swapping for this host");

constexpr std::array<std::uint8_t, 8> kMagic = {'F', 'B', 'B', 'M', '\r', '\n', 0x1A, '\n'};
constexpr std::uint32_t kVersion = 1;
constexpr std::size_t kHeaderSize = 64;
constexpr std::size_t kChecksumBegin = 16;
constexpr std::uint32_t kLimit = 1u << 26;  // sanity bound on every count

struct Header {
  std::uint64_t file_size = 0;
  std::uint32_t vertex_count = 0, face_vertex_count = 0, id_knobs = 0, exp_knobs = 0,
                identity_count = 0, expression_count = 0, triangle_count = 0, landmark_count = 0,
                names_bytes = 0, metadata_bytes = 0;
};

template <class T>
void put(std::vector<std::byte>& out, std::size_t at, T value) {
  std::memcpy(out.data() + at, &value, sizeof(T));
}
template <class T>
void append(std::vector<std::byte>& out, std::span<const T> values) {
  const auto* p = reinterpret_cast<const std::byte*>(values.data());
  out.insert(out.end(), p, p + values.size_bytes());
}
template <class T>
T load(std::span<const std::byte> bytes, std::size_t at) {
  T v;
  std::memcpy(&v, bytes.data() + at, sizeof(T));
  return v;
}

std::string rebuild_hint() {
  return "; rebuild it with `facebooth model build --from-face-model --out FILE`";
}

}  // namespace

std::span<const float> BilinearModel::identity_row(int i) const {
  return std::span<const float>(identity_factors)
      .subspan(static_cast<std::size_t>(i) * id_knobs, static_cast<std::size_t>(id_knobs));
}
std::span<const float> BilinearModel::expression_row(int e) const {
  return std::span<const float>(expression_factors)
      .subspan(static_cast<std::size_t>(e) * exp_knobs, static_cast<std::size_t>(exp_knobs));
}

void BilinearModel::evaluate(std::span<const float> w_id, std::span<const float> w_exp,
                             std::span<float> out) const {
  const std::size_t n = static_cast<std::size_t>(coordinate_count());
  std::fill(out.begin(), out.end(), 0.0f);
  for (int b = 0; b < exp_knobs && b < static_cast<int>(w_exp.size()); ++b) {
    if (w_exp[b] == 0.0f) continue;
    for (int a = 0; a < id_knobs && a < static_cast<int>(w_id.size()); ++a) {
      const float w = w_id[a] * w_exp[b];
      if (w == 0.0f) continue;
      const float* block = core.data() + (static_cast<std::size_t>(b) * id_knobs + a) * n;
      for (std::size_t x = 0; x < n && x < out.size(); ++x) out[x] += w * block[x];
    }
  }
}

std::vector<std::byte> serialize_bilinear_model(const BilinearModel& m) {
  std::vector<std::byte> names;
  for (const auto& name : m.expression_names) {
    const std::uint32_t len = static_cast<std::uint32_t>(name.size());
    const auto* p = reinterpret_cast<const std::byte*>(&len);
    names.insert(names.end(), p, p + 4);
    const auto* s = reinterpret_cast<const std::byte*>(name.data());
    names.insert(names.end(), s, s + name.size());
  }
  std::vector<std::byte> out(kHeaderSize);
  std::memcpy(out.data(), kMagic.data(), kMagic.size());
  put<std::uint32_t>(out, 8, kVersion);
  put<std::uint32_t>(out, 24, static_cast<std::uint32_t>(m.vertex_count));
  put<std::uint32_t>(out, 28, static_cast<std::uint32_t>(m.face_vertex_count));
  put<std::uint32_t>(out, 32, static_cast<std::uint32_t>(m.id_knobs));
  put<std::uint32_t>(out, 36, static_cast<std::uint32_t>(m.exp_knobs));
  put<std::uint32_t>(out, 40, static_cast<std::uint32_t>(m.identity_count));
  put<std::uint32_t>(out, 44, static_cast<std::uint32_t>(m.expression_count));
  put<std::uint32_t>(out, 48, static_cast<std::uint32_t>(m.triangles.size() / 3));
  put<std::uint32_t>(out, 52, 68u);
  put<std::uint32_t>(out, 56, static_cast<std::uint32_t>(names.size()));
  put<std::uint32_t>(out, 60, static_cast<std::uint32_t>(m.metadata.size()));
  out.reserve(kHeaderSize +
              4 * (m.core.size() + m.identity_factors.size() + m.expression_factors.size() +
                   m.triangles.size() + 256) +
              names.size() + m.metadata.size());
  append<float>(out, m.core);
  append<float>(out, m.identity_factors);
  append<float>(out, m.expression_factors);
  append<float>(out, m.identity_spectrum);
  append<float>(out, m.expression_spectrum);
  append<std::uint32_t>(out, m.triangles);
  append<std::uint32_t>(out, m.landmark_vertices);
  append<std::byte>(out, names);
  const auto* meta = reinterpret_cast<const std::byte*>(m.metadata.data());
  out.insert(out.end(), meta, meta + m.metadata.size());
  put<std::uint64_t>(out, 16, static_cast<std::uint64_t>(out.size()));
  put<std::uint32_t>(out, 12, fbfm::crc32(std::span<const std::byte>(out).subspan(kChecksumBegin)));
  return out;
}

Result<BilinearModel> parse_bilinear_model(std::span<const std::byte> bytes) {
  if (bytes.size() < kHeaderSize)
    return fail("bilinear model: file too short for the header (" + std::to_string(bytes.size()) +
                " bytes, need " + std::to_string(kHeaderSize) + ")" + rebuild_hint());
  if (std::memcmp(bytes.data(), kMagic.data(), kMagic.size()) != 0)
    return fail("bilinear model: bad magic (not a facebooth bilinear model file)" + rebuild_hint());
  const auto version = load<std::uint32_t>(bytes, 8);
  if (version != kVersion)
    return fail("bilinear model: unsupported format version " + std::to_string(version) +
                " (this facebooth reads version " + std::to_string(kVersion) + ")" +
                rebuild_hint());
  Header h;
  h.file_size = load<std::uint64_t>(bytes, 16);
  if (h.file_size != bytes.size())
    return fail("bilinear model: truncated or padded: the header says " +
                std::to_string(h.file_size) + " bytes, the file has " +
                std::to_string(bytes.size()) + rebuild_hint());
  const auto stored = load<std::uint32_t>(bytes, 12);
  const auto computed = fbfm::crc32(bytes.subspan(kChecksumBegin));
  if (stored != computed)
    return fail("bilinear model: checksum mismatch (the file is corrupted)" + rebuild_hint());
  h.vertex_count = load<std::uint32_t>(bytes, 24);
  h.face_vertex_count = load<std::uint32_t>(bytes, 28);
  h.id_knobs = load<std::uint32_t>(bytes, 32);
  h.exp_knobs = load<std::uint32_t>(bytes, 36);
  h.identity_count = load<std::uint32_t>(bytes, 40);
  h.expression_count = load<std::uint32_t>(bytes, 44);
  h.triangle_count = load<std::uint32_t>(bytes, 48);
  h.landmark_count = load<std::uint32_t>(bytes, 52);
  h.names_bytes = load<std::uint32_t>(bytes, 56);
  h.metadata_bytes = load<std::uint32_t>(bytes, 60);
  for (std::uint32_t c : {h.vertex_count, h.id_knobs, h.exp_knobs, h.identity_count,
                          h.expression_count, h.triangle_count})
    if (c == 0 || c > kLimit)
      return fail("bilinear model: a count in the header is out of range" + rebuild_hint());
  if (h.landmark_count != 68 || h.face_vertex_count > h.vertex_count ||
      h.id_knobs > h.identity_count || h.exp_knobs > h.expression_count)
    return fail("bilinear model: inconsistent header counts" + rebuild_hint());
  // Each count is below 2^26, so the core's 3 V Kid Kexp floats can pass 2^64 and wrap into a
  // size that matches the file; no file that size exists, so bound it by the file first.
  const std::uint64_t core_per_vertex = 3ull * h.id_knobs * h.exp_knobs;  // < 2^54
  if (core_per_vertex * h.vertex_count / h.vertex_count != core_per_vertex ||
      core_per_vertex * h.vertex_count > bytes.size() / 4)
    return fail("bilinear model: the header's core (" + std::to_string(h.vertex_count) +
                " vertices x " + std::to_string(h.id_knobs) + " x " + std::to_string(h.exp_knobs) +
                " knobs) is larger than the file" + rebuild_hint());
  const std::uint64_t core = core_per_vertex * h.vertex_count;
  const std::uint64_t expected =
      kHeaderSize +
      4 * (core + std::uint64_t{h.identity_count} * h.id_knobs +
           std::uint64_t{h.expression_count} * h.exp_knobs + h.identity_count + h.expression_count +
           3ull * h.triangle_count + 68) +
      h.names_bytes + h.metadata_bytes;
  if (expected != h.file_size)
    return fail("bilinear model: section sizes (" + std::to_string(expected) +
                " bytes) do not match the file size (" + std::to_string(h.file_size) + ")" +
                rebuild_hint());

  BilinearModel m;
  m.vertex_count = static_cast<int>(h.vertex_count);
  m.face_vertex_count = static_cast<int>(h.face_vertex_count);
  m.id_knobs = static_cast<int>(h.id_knobs);
  m.exp_knobs = static_cast<int>(h.exp_knobs);
  m.identity_count = static_cast<int>(h.identity_count);
  m.expression_count = static_cast<int>(h.expression_count);
  std::size_t at = kHeaderSize;
  auto take_floats = [&](std::vector<float>& v, std::uint64_t count) {
    v.resize(static_cast<std::size_t>(count));
    std::memcpy(v.data(), bytes.data() + at, v.size() * 4);
    at += v.size() * 4;
  };
  take_floats(m.core, core);
  take_floats(m.identity_factors, std::uint64_t{h.identity_count} * h.id_knobs);
  take_floats(m.expression_factors, std::uint64_t{h.expression_count} * h.exp_knobs);
  take_floats(m.identity_spectrum, h.identity_count);
  take_floats(m.expression_spectrum, h.expression_count);
  m.triangles.resize(3ull * h.triangle_count);
  std::memcpy(m.triangles.data(), bytes.data() + at, m.triangles.size() * 4);
  at += m.triangles.size() * 4;
  std::memcpy(m.landmark_vertices.data(), bytes.data() + at, 68 * 4);
  at += 68 * 4;
  for (auto v : m.triangles)
    if (v >= h.vertex_count)
      return fail("bilinear model: a triangle index is out of range" + rebuild_hint());
  for (auto v : m.landmark_vertices)
    if (v >= h.vertex_count)
      return fail("bilinear model: a landmark index is out of range" + rebuild_hint());
  const std::size_t names_end = at + h.names_bytes;
  while (at < names_end) {
    if (names_end - at < 4)
      return fail("bilinear model: broken expression name table" + rebuild_hint());
    const auto len = load<std::uint32_t>(bytes, at);
    at += 4;
    if (len > names_end - at)
      return fail("bilinear model: broken expression name table" + rebuild_hint());
    m.expression_names.emplace_back(reinterpret_cast<const char*>(bytes.data() + at), len);
    at += len;
  }
  if (m.expression_names.size() != h.expression_count)
    return fail("bilinear model: " + std::to_string(m.expression_names.size()) +
                " expression names for " + std::to_string(h.expression_count) + " expressions" +
                rebuild_hint());
  m.metadata.assign(reinterpret_cast<const char*>(bytes.data() + at), h.metadata_bytes);
  return m;
}

}  // namespace fb
