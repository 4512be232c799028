// Session bundles as a booth serves them, written by hand for the tests that read them
// (tests/sync) and for the bundle fuzz target's seeds (tests/fuzz): ustar entries, a manifest
// with each listed file's size and SHA-256, a minimal session.json.
#pragma once

#include <cstdio>
#include <cstring>
#include <span>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "storage/sha256.hpp"

namespace fb::test {

// One ustar entry (header + content padded to 512); type '2' is a symbolic link to /etc/passwd.
inline std::string tar_entry(const std::string& name, const std::string& content, char type = '0') {
  char h[512] = {};
  std::snprintf(h, 100, "%s", name.c_str());
  std::snprintf(h + 100, 8, "%07o", 0644);
  std::snprintf(h + 108, 8, "%07o", 0);
  std::snprintf(h + 116, 8, "%07o", 0);
  std::snprintf(h + 124, 12, "%011llo", static_cast<unsigned long long>(content.size()));
  std::snprintf(h + 136, 12, "%011o", 0);
  std::memset(h + 148, ' ', 8);
  h[156] = type;
  if (type == '2') std::snprintf(h + 157, 100, "%s", "/etc/passwd");
  std::memcpy(h + 257, "ustar", 6);
  std::memcpy(h + 263, "00", 2);
  unsigned sum = 0;
  for (unsigned char c : h) sum += c;
  std::snprintf(h + 148, 8, "%06o", sum);
  h[155] = ' ';
  std::string out(h, 512);
  out += content;
  out.append((512 - content.size() % 512) % 512, '\0');
  return out;
}

inline std::string sha(const std::string& s) {
  return sha256_hex(std::span(reinterpret_cast<const std::uint8_t*>(s.data()), s.size()));
}

// A file of a bundle: its name in the archive and content, and how the manifest lists it
// (`manifest_path` empty: not listed; the digest is of `digest_content`).
struct BundleFile {
  std::string archive_name;
  std::string content;
  std::string manifest_path;
  std::string digest_content;
  char type = '0';
};

// The archive of `files` with session-1/manifest.json after them.
inline std::string bundle(const std::vector<BundleFile>& files) {
  nlohmann::json list = nlohmann::json::array();
  std::string tar;
  for (const auto& f : files) {
    tar += tar_entry(f.archive_name, f.content, f.type);
    if (!f.manifest_path.empty())
      list.push_back({{"path", f.manifest_path},
                      {"bytes", f.digest_content.size()},
                      {"sha256", sha(f.digest_content)}});
  }
  tar += tar_entry("session-1/manifest.json", nlohmann::json({{"files", list}}).dump());
  return tar + std::string(1024, '\0');
}

// session.json of booth session 1 with `captures`.
inline std::string session_json(const nlohmann::json& captures = nlohmann::json::array()) {
  return nlohmann::json({{"format", "facebooth-session-bundle"},
                         {"version", 3},
                         {"session", 1},
                         {"subject", "x"},
                         {"subject_id", 1},
                         {"captures", captures}})
      .dump();
}

}  // namespace fb::test
