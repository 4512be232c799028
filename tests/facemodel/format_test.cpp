// The .fbfm format: round trip, CRC, and that every kind of damage gives a clear error
// instead of a crash or an out-of-bounds read.
#include <gtest/gtest.h>

#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "algo/facemodel/face_model.hpp"
#include "algo/facemodel/face_model_format.hpp"
#include "tests/facemodel/test_util.hpp"

namespace fb {
namespace {

std::vector<std::byte> tiny_bytes() {
  auto r = serialize_face_model(test::make_tiny_model());
  EXPECT_TRUE(r.ok()) << r.error().message;
  return std::move(r).value();
}

template <class T>
void put(std::vector<std::byte>& b, std::size_t offset, T v) {
  std::memcpy(b.data() + offset, &v, sizeof v);
}
template <class T>
T get(const std::vector<std::byte>& b, std::size_t offset) {
  T v;
  std::memcpy(&v, b.data() + offset, sizeof v);
  return v;
}

// Byte offset of a section's data, from the table.
std::size_t section_offset(const std::vector<std::byte>& b, fbfm::SectionId id) {
  const auto count = get<std::uint32_t>(b, fbfm::kOffSectionCount);
  for (std::uint32_t i = 0; i < count; ++i) {
    const std::size_t at = fbfm::kHeaderSize + i * fbfm::kSectionEntrySize;
    if (get<std::uint32_t>(b, at) == static_cast<std::uint32_t>(id)) {
      return static_cast<std::size_t>(get<std::uint64_t>(b, at + 8));
    }
  }
  ADD_FAILURE() << "no section " << static_cast<int>(id);
  return 0;
}

// Parses and expects an error whose message contains `needle`.
void expect_error(std::span<const std::byte> bytes, const std::string& needle) {
  auto r = parse_face_model(bytes);
  ASSERT_FALSE(r.ok()) << "expected an error containing \"" << needle << "\"";
  EXPECT_NE(r.error().message.find(needle), std::string::npos) << r.error().message;
  // Every message tells the user what to do.
  EXPECT_NE(r.error().message.find("facebooth"), std::string::npos) << r.error().message;
}

TEST(facemodel_format, Crc32MatchesTheStandardCheckValue) {
  const char* s = "123456789";
  EXPECT_EQ(fbfm::crc32(std::as_bytes(std::span(s, 9))), 0xCBF43926u);
  EXPECT_EQ(fbfm::crc32({}), 0u);
  // Incremental use gives the same value as one call.
  const auto all = std::as_bytes(std::span(s, 9));
  EXPECT_EQ(fbfm::crc32(all.subspan(4), fbfm::crc32(all.first(4))), 0xCBF43926u);
}

TEST(facemodel_format, TinyModelRoundTripsExactly) {
  const FaceModel a = test::make_tiny_model();
  const auto bytes = tiny_bytes();
  EXPECT_EQ(bytes.size() % fbfm::kSectionAlignment, 0u);
  auto r = parse_face_model(bytes);
  ASSERT_TRUE(r.ok()) << r.error().message;
  const FaceModel& b = *r;
  EXPECT_EQ(b.vertex_count, a.vertex_count);
  EXPECT_EQ(b.face_vertex_count, a.face_vertex_count);
  EXPECT_EQ(b.identity_count, a.identity_count);
  EXPECT_EQ(b.expression_count, a.expression_count);
  EXPECT_EQ(b.fitting_expression_count, a.fitting_expression_count);
  EXPECT_EQ(b.neutral, a.neutral);
  EXPECT_EQ(b.identity_basis, a.identity_basis);
  EXPECT_EQ(b.expression_basis, a.expression_basis);
  EXPECT_EQ(b.expression_names, a.expression_names);
  EXPECT_EQ(b.triangles, a.triangles);
  EXPECT_EQ(b.landmark_vertices, a.landmark_vertices);
  EXPECT_EQ(b.rigid_landmarks, a.rigid_landmarks);
  EXPECT_EQ(b.right_jawline, a.right_jawline);
  EXPECT_EQ(b.left_jawline, a.left_jawline);
  EXPECT_EQ(b.right_extended_jawline, a.right_extended_jawline);
  EXPECT_EQ(b.left_extended_jawline, a.left_extended_jawline);
  EXPECT_EQ(b.fitting_vertices, a.fitting_vertices);
  EXPECT_EQ(b.rigid_vertices, a.rigid_vertices);
  EXPECT_EQ(b.provenance, a.provenance);
  EXPECT_EQ(b.uvs, a.uvs);
  EXPECT_EQ(b.triangle_uvs, a.triangle_uvs);
  // Serialising the parsed model gives the same bytes: the format has one canonical form.
  auto again = serialize_face_model(b);
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(*again, bytes);
}

TEST(facemodel_format, SerializeRejectsInconsistentModels) {
  FaceModel m = test::make_tiny_model();
  m.neutral.pop_back();
  EXPECT_FALSE(serialize_face_model(m).ok());
  m = test::make_tiny_model();
  m.expression_names.pop_back();
  EXPECT_FALSE(serialize_face_model(m).ok());
}

TEST(facemodel_format, EveryTruncationIsReportedAsTruncated) {
  const auto bytes = tiny_bytes();
  expect_error(std::span(bytes).first(0), "empty");
  for (std::size_t n = 1; n < bytes.size(); ++n) {
    SCOPED_TRACE("prefix length " + std::to_string(n));
    expect_error(std::span(bytes).first(n), "truncated at byte " + std::to_string(n));
  }
}

TEST(facemodel_format, EverySingleByteFlipIsDetected) {
  const auto good = tiny_bytes();
  for (std::size_t i = 0; i < good.size(); ++i) {
    for (const unsigned mask : {0x01u, 0x80u, 0xFFu}) {
      auto bad = good;
      bad[i] ^= static_cast<std::byte>(mask);
      auto r = parse_face_model(bad);
      ASSERT_FALSE(r.ok()) << "flip of byte " << i << " with mask " << mask << " went unnoticed";
      const std::string& msg = r.error().message;
      if (i < 8) {
        EXPECT_NE(msg.find("bad magic"), std::string::npos) << msg;
      } else if (i >= fbfm::kChecksumBegin + 8) {  // past the file size field: only the CRC
        EXPECT_NE(msg.find("checksum mismatch"), std::string::npos) << "byte " << i << ": " << msg;
      }
    }
  }
}

TEST(facemodel_format, AppendedBytesAreReported) {
  auto bytes = tiny_bytes();
  bytes.push_back(std::byte{0});
  expect_error(bytes, "trailing bytes");
}

TEST(facemodel_format, NewerVersionIsReportedAsNewer) {
  auto bytes = tiny_bytes();
  put<std::uint32_t>(bytes, fbfm::kOffVersion, fbfm::kFormatVersion + 1);
  expect_error(bytes, "newer than this build supports");
  put<std::uint32_t>(bytes, fbfm::kOffVersion, 0);
  expect_error(bytes, "invalid format version 0");
}

TEST(facemodel_format, ForeignFileIsReportedAsBadMagic) {
  const std::string text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  expect_error(std::as_bytes(std::span(text)), "bad magic");
}

// The remaining cases have a valid CRC (resealed), so they exercise the structural checks
// that protect against a buggy writer rather than against random damage.
TEST(facemodel_format, CountsThatDoNotFitTheSizeAreRejected) {
  {
    auto b = tiny_bytes();
    put<std::uint32_t>(b, fbfm::kOffVertexCount, 6);
    fbfm::reseal_checksum(b);
    expect_error(b, "counts do not fit the data");
  }
  {
    auto b = tiny_bytes();
    put<std::uint32_t>(b, fbfm::kOffExpressionCount, 2);
    put<std::uint32_t>(b, fbfm::kOffFittingExpressionCount, 1);
    fbfm::reseal_checksum(b);
    expect_error(b, "counts do not fit the data");
  }
  {
    auto b = tiny_bytes();
    put<std::uint32_t>(b, fbfm::kOffTriangleCount, 4);
    fbfm::reseal_checksum(b);
    expect_error(b, "counts do not fit the data");
  }
  {
    auto b = tiny_bytes();
    put<std::uint32_t>(b, fbfm::kOffVertexCount, 0xFFFFFFFFu);
    fbfm::reseal_checksum(b);
    expect_error(b, "implausible vertex count");
  }
  {
    auto b = tiny_bytes();
    put<std::uint32_t>(b, fbfm::kOffSectionCount, 100000);
    fbfm::reseal_checksum(b);
    expect_error(b, "does not fit in the file");
  }
  {
    auto b = tiny_bytes();
    put<std::uint32_t>(b, fbfm::kOffLandmarkCount, 67);
    fbfm::reseal_checksum(b);
    expect_error(b, "expected the 68 iBUG points");
  }
}

TEST(facemodel_format, SectionTableDamageIsRejected) {
  const std::size_t entry0 = fbfm::kHeaderSize;
  {
    auto b = tiny_bytes();
    put<std::uint64_t>(b, entry0 + 8, b.size() - 4);  // NEUTRAL runs past the end
    fbfm::reseal_checksum(b);
    expect_error(b, "outside the payload");
  }
  {
    auto b = tiny_bytes();
    put<std::uint64_t>(b, entry0 + 16, ~std::uint64_t{0});  // huge length: no overflow
    fbfm::reseal_checksum(b);
    expect_error(b, "outside the payload");
  }
  {
    auto b = tiny_bytes();
    put<std::uint64_t>(b, entry0 + 8, 0);  // points into the header
    fbfm::reseal_checksum(b);
    expect_error(b, "outside the payload");
  }
  {
    auto b = tiny_bytes();
    put<std::uint32_t>(b, entry0 + fbfm::kSectionEntrySize, 1);  // second entry claims id 1 too
    fbfm::reseal_checksum(b);
    expect_error(b, "appears twice");
  }
  {
    auto b = tiny_bytes();
    put<std::uint32_t>(b, entry0, 999);  // NEUTRAL becomes an unknown (ignored) section
    fbfm::reseal_checksum(b);
    expect_error(b, "required section NEUTRAL is missing");
  }
  {
    auto b = tiny_bytes();
    put<std::uint32_t>(b, entry0 + 4, 2);  // NEUTRAL declared as u32
    fbfm::reseal_checksum(b);
    expect_error(b, "element type");
  }
}

TEST(facemodel_format, IndicesOutOfRangeAreRejected) {
  struct Case {
    fbfm::SectionId id;
    std::uint32_t value;
    const char* needle;
  };
  const Case cases[] = {
      {fbfm::SectionId::kTriangles, 5, "TRIANGLES entry 0 is 5, out of range"},
      {fbfm::SectionId::kLandmarks, 0xFFFFFFFFu, "LANDMARKS entry 0"},
      {fbfm::SectionId::kRigidLandmarks, 68, "RIGID_LANDMARKS entry 0 is 68"},
      {fbfm::SectionId::kRightJawline, 5, "RIGHT_JAWLINE"},
      {fbfm::SectionId::kLeftExtendedJawline, 7, "LEFT_EXTENDED_JAWLINE"},
      {fbfm::SectionId::kFittingVertices, 5, "FITTING_VERTICES"},
      {fbfm::SectionId::kRigidVertices, 5, "RIGID_VERTICES"},
  };
  for (const auto& c : cases) {
    auto b = tiny_bytes();
    put<std::uint32_t>(b, section_offset(b, c.id), c.value);
    fbfm::reseal_checksum(b);
    expect_error(b, c.needle);
  }
}

TEST(facemodel_format, NonFiniteValuesAndBadNamesAreRejected) {
  {
    auto b = tiny_bytes();
    put<float>(b, section_offset(b, fbfm::SectionId::kIdentityBasis) + 8,
               std::numeric_limits<float>::quiet_NaN());
    fbfm::reseal_checksum(b);
    expect_error(b, "non-finite value at element 2");
  }
  {
    auto b = tiny_bytes();
    put<std::uint32_t>(b, section_offset(b, fbfm::SectionId::kExpressionNames), 1000);
    fbfm::reseal_checksum(b);
    expect_error(b, "invalid length");
  }
  {
    auto b = tiny_bytes();
    // First character of the second name ("mouthSmile_L") becomes a control character.
    const std::size_t at = section_offset(b, fbfm::SectionId::kExpressionNames) + 4 + 7 + 4;
    b[at] = std::byte{'\n'};
    fbfm::reseal_checksum(b);
    expect_error(b, "non-printable");
  }
}

// The same checks on the real asset: a sampled set of prefix lengths and flips in the
// header, the section table and the payload.
TEST(facemodel_format, CommittedAssetCorruptionIsDetected) {
  const auto& good = test::asset_bytes();
  ASSERT_GT(good.size(), 1000u) << "data/facemodel.fbfm is missing; run the converter";
  std::vector<std::size_t> prefixes;
  for (std::size_t n = 1; n < 512; ++n) prefixes.push_back(n);
  std::mt19937_64 rng(42);
  for (int i = 0; i < 200; ++i) prefixes.push_back(rng() % good.size());
  prefixes.push_back(good.size() - 1);
  for (const std::size_t n : prefixes) {
    if (n == 0) continue;
    auto r = parse_face_model(std::span(good).first(n));
    ASSERT_FALSE(r.ok()) << "prefix " << n;
    EXPECT_NE(r.error().message.find("truncated at byte " + std::to_string(n)), std::string::npos)
        << r.error().message;
  }
  // Flips: every header and table byte would cost one CRC pass each (~10 ms), so sample.
  std::vector<std::size_t> flips = {0, 7, 8, 12, 16, 23, 24, 31, 32, 40, 44, 52, 56, 63};
  for (int i = 0; i < 12; ++i) flips.push_back(64 + rng() % (14 * 24));
  for (int i = 0; i < 12; ++i) flips.push_back(rng() % good.size());
  std::vector<std::byte> bad = good;
  for (const std::size_t at : flips) {
    bad[at] ^= std::byte{0x10};
    auto r = parse_face_model(bad);
    bad[at] ^= std::byte{0x10};
    ASSERT_FALSE(r.ok()) << "flip at byte " << at << " went unnoticed";
    EXPECT_FALSE(r.error().message.empty());
  }
}

}  // namespace
}  // namespace fb

namespace fb {
namespace {

// Random structural damage behind a valid CRC (a buggy writer, not a bad copy): the parser
// must return either a model that is internally consistent or an error, never crash. Run
// this binary under -fsanitize=address,undefined to check the "never reads out of bounds" part.
TEST(facemodel_format, RandomDamageBehindAValidChecksumNeverCrashes) {
  const auto good = tiny_bytes();
  std::mt19937_64 rng(1234);
  int accepted = 0;
  for (int iter = 0; iter < 5000; ++iter) {
    auto b = good;
    const int edits = 1 + static_cast<int>(rng() % 4);
    for (int e = 0; e < edits; ++e) {
      // Bias towards the header and table, where the structure lives.
      const std::size_t limit =
          (rng() % 2) ? fbfm::kHeaderSize + 14 * fbfm::kSectionEntrySize : b.size();
      const std::size_t at = fbfm::kChecksumBegin + rng() % (std::min(limit, b.size()) - 16);
      b[at] = static_cast<std::byte>(rng() & 0xFF);
    }
    fbfm::reseal_checksum(b);
    auto r = parse_face_model(b);
    if (!r.ok()) {
      EXPECT_FALSE(r.error().message.empty());
      continue;
    }
    ++accepted;
    const FaceModel& m = *r;
    const std::size_t n3 = static_cast<std::size_t>(m.vertex_count) * 3;
    ASSERT_EQ(m.neutral.size(), n3);
    ASSERT_EQ(m.identity_basis.size(), n3 * m.identity_count);
    ASSERT_EQ(m.expression_basis.size(), n3 * m.expression_count);
    ASSERT_EQ(m.expression_names.size(), static_cast<std::size_t>(m.expression_count));
    for (const auto t : m.triangles) ASSERT_LT(t, static_cast<std::uint32_t>(m.vertex_count));
    std::vector<float> out(n3);
    std::vector<float> c(m.identity_count, 1.0f), w(m.expression_count, 1.0f);
    m.evaluate(c, w, out);
  }
  std::printf("random structural damage: %d of 5000 variants still parsed as consistent models\n",
              accepted);
}

}  // namespace
}  // namespace fb
