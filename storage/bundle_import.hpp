// A session bundle as a booth serves it (GET /api/offload/sessions/N/bundle.tar, written by the
// daemon's export): a ustar archive of one folder `session-N/` holding manifest.json (every other
// file's size and SHA-256), session.json (the session, its captures, QA, file names),
// calibration.json (the unit's device.json) and per done capture fused_depth.pgm, color.png,
// landmarks.json and mesh.obj. Reading one is pure parsing: nothing is written and no name from
// the archive ever becomes a path; the files are looked up by name in the archive itself.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "algo/core/result.hpp"
#include "storage/session_store.hpp"

namespace fb {

struct TarEntry {
  std::string name;          // as in the archive, '/' separated
  std::uint64_t offset = 0;  // of the file's first byte in the archive
  std::uint64_t size = 0;
};

// The regular files of a ustar archive. Refuses, naming the entry, anything that could land
// outside a folder when extracted or that is not a plain file: absolute names, `..`, `.` or
// empty components, symbolic and hard links, devices, FIFOs, GNU/pax extensions, a wrong
// header checksum, a truncated archive, the same name twice.
Result<std::vector<TarEntry>> list_tar(std::span<const std::uint8_t> archive);

// Checks a bundle and decodes it into what SessionStore::import_session stores for booth
// `booth`: one top folder, every file listed in manifest.json with the listed size and SHA-256
// and nothing unlisted, session.json naming only files of the bundle. `expected_session` is the
// booth's session id the bundle was asked for (0: any). The errors say which file and why.
Result<SessionImport> read_session_bundle(std::span<const std::uint8_t> archive,
                                          const std::string& booth, std::int64_t expected_session);

}  // namespace fb
