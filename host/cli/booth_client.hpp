// The host's HTTP client of a booth's offload API (cpp-httplib): the ready list, a session's
// bundle downloaded into a file (resumed after a cut with a Range request, as long as the booth
// still serves the same bundle: its ETag), and the rig upload. Used by `facebooth sync`.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "algo/core/result.hpp"

namespace httplib {
class Client;
}

namespace fb::cli {

struct BoothAddress {
  std::string url;     // as given, normalised to scheme://host:port
  std::string scheme;  // "http" or "https"
  std::string host;
  int port = 0;
  bool local = false;  // loopback: plain HTTP is fine
};

// Parses `http://HOST[:PORT]`, `https://HOST[:PORT]` or `HOST:PORT` (http). Plain HTTP to a
// booth that is not on this machine is refused unless `insecure` (the token and the captures
// would cross the network in the clear).
Result<BoothAddress> parse_booth_address(const std::string& url, bool insecure);

struct DownloadStats {
  std::uint64_t bytes = 0;         // received in this call
  std::uint64_t resumed_from = 0;  // bytes already in the file and kept (0: from the start)
  std::uint64_t total = 0;         // the file's size when complete
};

class BoothClient {
 public:
  BoothClient(const BoothAddress& address, std::string token);
  BoothClient(BoothClient&&) noexcept;
  ~BoothClient();

  const BoothAddress& address() const { return address_; }
  Result<nlohmann::json> get_json(const std::string& path);
  Result<nlohmann::json> post(const std::string& path, const std::string& body,
                              const std::string& content_type);
  // Downloads `path` into `part` (a partial file there is resumed when its tag, kept next to it
  // as `part`.etag, is still the booth's). `progress(received_so_far, total)`; `max_bytes_per_s`
  // > 0 limits the rate (a booth on a shared studio network).
  Result<DownloadStats> download(const std::string& path, const std::filesystem::path& part,
                                 const std::function<void(std::uint64_t, std::uint64_t)>& progress,
                                 double max_bytes_per_s);

 private:
  Result<DownloadStats> download_once(
      const std::string& path, const std::filesystem::path& part,
      const std::function<void(std::uint64_t, std::uint64_t)>& progress, double max_bytes_per_s,
      bool& restart);
  std::string what(const std::string& path) const;
  BoothAddress address_;
  std::string token_;
  std::unique_ptr<httplib::Client> http_;
};

}  // namespace fb::cli
