// The on-disk layout of the compact face model asset (`.fbfm`), shared by the parser, the
// writer (used by the converter) and the tests. data/README.md documents the same layout for
// people; keep both in sync and bump kFormatVersion on any incompatible change.
//
// Summary: a 64-byte header, a section table (24 bytes per entry), then the sections, each
// starting at a 16-byte aligned absolute offset. Little-endian throughout. A CRC-32 (IEEE,
// the zlib/PNG polynomial) covers every byte from offset 16 to the end of the file, so the
// sizes, counts, the section table and the payload are all protected.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include "algo/facemodel/face_model.hpp"

namespace fb::fbfm {

// PNG-style magic: the CR LF, ^Z and LF bytes make text-mode copies and truncated transfers
// fail loudly at the magic check instead of somewhere deep in the payload.
inline constexpr std::array<std::uint8_t, 8> kMagic = {'F', 'B', 'F', 'M', '\r', '\n', 0x1A, '\n'};
inline constexpr std::uint32_t kFormatVersion = 1;

inline constexpr std::size_t kHeaderSize = 64;
inline constexpr std::size_t kSectionEntrySize = 24;
inline constexpr std::size_t kSectionAlignment = 16;
inline constexpr std::uint32_t kMaxSections = 256;

// Header field offsets (bytes from the start of the file). The CRC covers everything after
// itself, so every field but magic and version (each validated first, on its own) is protected.
inline constexpr std::size_t kOffMagic = 0;                    // 8 bytes
inline constexpr std::size_t kOffVersion = 8;                  // u32
inline constexpr std::size_t kOffChecksum = 12;                // u32, CRC-32 of [16, file_size)
inline constexpr std::size_t kChecksumBegin = 16;              // first byte the CRC covers
inline constexpr std::size_t kOffFileSize = 16;                // u64, total bytes of the file
inline constexpr std::size_t kOffSectionCount = 24;            // u32
inline constexpr std::size_t kOffFlags = 28;                   // u32, must be 0 in version 1
inline constexpr std::size_t kOffVertexCount = 32;             // u32
inline constexpr std::size_t kOffFaceVertexCount = 36;         // u32
inline constexpr std::size_t kOffIdentityCount = 40;           // u32
inline constexpr std::size_t kOffExpressionCount = 44;         // u32
inline constexpr std::size_t kOffFittingExpressionCount = 48;  // u32
inline constexpr std::size_t kOffTriangleCount = 52;           // u32
inline constexpr std::size_t kOffLandmarkCount = 56;           // u32, must be 68
inline constexpr std::size_t kOffReserved = 60;                // u32, must be 0

// Section table entry: u32 id, u32 element type, u64 absolute offset, u64 byte length.
enum class SectionId : std::uint32_t {
  kNeutral = 1,                // f32[3V]
  kIdentityBasis = 2,          // f32[I * 3V]
  kExpressionBasis = 3,        // f32[E * 3V]
  kExpressionNames = 4,        // bytes: E times (u32 length, UTF-8 bytes without terminator)
  kTriangles = 5,              // u32[3T]
  kLandmarks = 6,              // u32[68]
  kRigidLandmarks = 7,         // u32[n], positions in the 68-list
  kRightJawline = 8,           // u32[n]
  kLeftJawline = 9,            // u32[n]
  kRightExtendedJawline = 10,  // u32[n]
  kLeftExtendedJawline = 11,   // u32[n]
  kFittingVertices = 12,       // u32[n]
  kRigidVertices = 13,         // u32[n]
  kProvenance = 14,            // bytes: UTF-8 text, optional
  kUvs = 15,                   // f32[2U]: texture coordinates (u, v), optional (with 16)
  kTriangleUvs = 16,           // u32[3T]: the UV of each triangle corner, optional (with 15)
};

enum class ElementType : std::uint32_t { kFloat32 = 1, kUint32 = 2, kBytes = 3 };

// Human-readable section name for error messages ("NEUTRAL", "TRIANGLES", ...).
std::string_view section_name(std::uint32_t id);

// CRC-32 (IEEE 802.3, reflected, init and final xor 0xFFFFFFFF): the same value as zlib's
// crc32(), so `python3 -c "import zlib; ..."` can check a file independently.
std::uint32_t crc32(std::span<const std::byte> bytes, std::uint32_t crc = 0);

// Recomputes the checksum field of a complete file in place. Used by the writer and by tests
// that build deliberately inconsistent files which must fail on their content, not the CRC.
void reseal_checksum(std::span<std::byte> file);

}  // namespace fb::fbfm

namespace fb {

// Serialises a model into the `.fbfm` layout (the inverse of parse_face_model). Pure: returns
// bytes, the caller writes them. The model must be internally consistent (vector sizes match
// the counts); inconsistencies are reported as errors rather than written.
Result<std::vector<std::byte>> serialize_face_model(const FaceModel& model);

}  // namespace fb
