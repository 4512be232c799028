#include "storage/export/export_folder.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <ctime>
#include <nlohmann/json.hpp>
#include <system_error>

#include "storage/durable_file.hpp"
#include "storage/session_store.hpp"

#ifndef FB_VERSION
#define FB_VERSION "unknown"
#endif

namespace fb {

namespace fs = std::filesystem;

namespace {

std::string utc_now() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

}  // namespace

Result<ExportFolder> ExportFolder::create(const fs::path& destination, bool overwrite) {
  if (destination.empty()) return fail("no output path given (--out PATH)");
  const fs::path dest = fs::absolute(destination).lexically_normal();
  std::error_code ec;
  if (fs::exists(dest, ec) && !overwrite) {
    return fail(dest.string() +
                " already exists: choose another --out, or pass --force to "
                "replace it");
  }
  const fs::path parent = dest.parent_path();
  if (!fs::is_directory(parent, ec)) {
    fs::create_directories(parent, ec);
    if (ec) return fail("cannot create " + parent.string() + ": " + ec.message());
  }
  ExportFolder folder;
  folder.destination_ = dest;
  folder.overwrite_ = overwrite;
  folder.temp_ =
      parent / (std::string(kDurableTempPrefix) + dest.filename().string() + "-" + random_token(8));
  fs::create_directory(folder.temp_, ec);
  if (ec) return fail("cannot create " + folder.temp_.string() + ": " + ec.message());
  return folder;
}

ExportFolder::ExportFolder(ExportFolder&& o) noexcept
    : destination_(std::move(o.destination_)),
      temp_(std::move(o.temp_)),
      overwrite_(o.overwrite_),
      finished_(o.finished_),
      files_(std::move(o.files_)) {
  o.temp_.clear();
}

ExportFolder::~ExportFolder() {
  if (!finished_ && !temp_.empty()) {
    std::error_code ec;
    fs::remove_all(temp_, ec);
  }
}

std::uint64_t ExportFolder::total_bytes() const {
  std::uint64_t n = 0;
  for (const auto& f : files_) n += f.bytes;
  return n;
}

Result<void> ExportFolder::write_file(const std::string& relative_path,
                                      std::span<const std::uint8_t> bytes) {
  const fs::path path = temp_ / relative_path;
  std::error_code ec;
  fs::create_directories(path.parent_path(), ec);
  if (ec) return fail("cannot create " + path.parent_path().string() + ": " + ec.message());
  // No per-file fsync: the whole folder is still temporary, and finish() makes it durable with
  // one syncfs() before the rename publishes it (one journal commit instead of one per file).
  UniqueFd fd(::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644));
  if (!fd.valid()) return fail("cannot create " + path.string() + ": " + std::strerror(errno));
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd.get(), bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      const int err = errno;
      return fail("cannot write " + path.string() + ": " + std::strerror(err) +
                  (err == ENOSPC ? " (free space and export again; nothing was published)" : ""));
    }
    done += static_cast<std::size_t>(n);
  }
  if (const int err = fd.close(); err != 0) {
    return fail("cannot write " + path.string() + ": " + std::strerror(err));
  }
  files_.push_back({relative_path, bytes.size(), sha256_hex(bytes)});
  return success();
}

Result<void> ExportFolder::finish(const ExportManifest& manifest) {
  nlohmann::json j;
  j["facebooth_export"] = kExportManifestVersion;
  j["what"] = manifest.what;
  j["created_at"] = utc_now();
  j["versions"] = {{"facebooth", FB_VERSION},
                   {"store_schema", kSessionStoreSchemaVersion},
                   {"manifest", kExportManifestVersion}};
  j["source"] = manifest.source;
  j["details"] = manifest.details;
  j["units"] = "millimetres unless the format says otherwise (glTF: metres)";
  nlohmann::json files = nlohmann::json::array();
  for (const auto& f : files_) {
    files.push_back({{"path", f.path}, {"bytes", f.bytes}, {"sha256", f.sha256}});
  }
  j["files"] = files;
  const std::string text = j.dump(2) + "\n";
  const std::size_t listed = files_.size();
  if (auto r = write_text("manifest.json", text); !r) return r;
  files_.resize(listed);  // the manifest does not list itself
  // Every file and folder entry must be on disk before the rename publishes the export.
  {
    UniqueFd dir(::open(temp_.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC));
    if (!dir.valid() || ::syncfs(dir.get()) != 0) {
      return fail("cannot sync the export in " + temp_.string() + ": " + std::strerror(errno));
    }
  }
  std::error_code ec;
  fs::path old;
  if (fs::exists(destination_, ec)) {
    if (!overwrite_) return fail(destination_.string() + " appeared while exporting; not replaced");
    old = destination_.parent_path() / (std::string(kDurableTempPrefix) + "old-" +
                                        destination_.filename().string() + "-" + random_token(8));
    fs::rename(destination_, old, ec);
    if (ec) return fail("cannot move the old " + destination_.string() + " aside: " + ec.message());
  }
  fs::rename(temp_, destination_, ec);
  if (ec)
    return fail("cannot rename the finished export to " + destination_.string() + ": " +
                ec.message());
  finished_ = true;
  if (auto r = fsync_directory(destination_.parent_path()); !r) return r;
  if (!old.empty()) fs::remove_all(old, ec);
  return success();
}

Result<std::vector<ExportedFile>> verify_export_folder(const fs::path& folder) {
  auto bytes = read_file_bytes(folder / "manifest.json");
  if (!bytes)
    return fail(folder.string() + " has no readable manifest.json: not a facebooth export");
  auto j = nlohmann::json::parse(bytes->begin(), bytes->end(), nullptr, false);
  if (j.is_discarded() || !j.contains("files")) return fail("manifest.json is not valid");
  std::vector<ExportedFile> files;
  for (const auto& f : j["files"]) {
    ExportedFile e{f.value("path", ""), f.value("bytes", std::uint64_t{0}), f.value("sha256", "")};
    auto sha = sha256_file(folder / e.path);
    if (!sha) return sha.failure();
    if (*sha != e.sha256) return fail(e.path + ": SHA-256 differs from the manifest");
    files.push_back(std::move(e));
  }
  return files;
}

}  // namespace fb
