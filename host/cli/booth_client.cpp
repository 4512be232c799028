#include "host/cli/booth_client.hpp"

#include <httplib.h>

#include <sys/socket.h>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <thread>

namespace fb::cli {

namespace fs = std::filesystem;

namespace {

bool loopback_host(const std::string& host) {
  return host == "localhost" || host == "::1" || host.rfind("127.", 0) == 0;
}

std::string read_line(const fs::path& path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  return line;
}

// "bytes 100-199/200" -> 200 (0 when absent or unreadable).
std::uint64_t content_range_total(const std::string& value) {
  const auto slash = value.rfind('/');
  if (slash == std::string::npos) return 0;
  try {
    return std::stoull(value.substr(slash + 1));
  } catch (...) {
    return 0;
  }
}

std::string error_text(int status, const std::string& body) {
  auto j = nlohmann::json::parse(body, nullptr, false);
  if (!j.is_discarded() && j.is_object() && j["error"].is_string())
    return "HTTP " + std::to_string(status) + ": " + j["error"].get<std::string>();
  return "HTTP " + std::to_string(status);
}

}  // namespace

Result<BoothAddress> parse_booth_address(const std::string& url, bool insecure) {
  BoothAddress a;
  std::string rest = url;
  a.scheme = "http";
  if (const auto p = rest.find("://"); p != std::string::npos) {
    a.scheme = rest.substr(0, p);
    rest = rest.substr(p + 3);
  }
  if (a.scheme != "http" && a.scheme != "https")
    return fail("--booth " + url + ": use http://HOST:PORT or https://HOST:PORT");
  while (!rest.empty() && rest.back() == '/') rest.pop_back();
  if (rest.find('/') != std::string::npos || rest.find('@') != std::string::npos)
    return fail("--booth " + url + ": give the booth's address only (scheme://HOST:PORT)");
  std::string port;
  if (!rest.empty() && rest.front() == '[') {  // [IPv6]:port
    const auto close = rest.find(']');
    if (close == std::string::npos) return fail("--booth " + url + ": unbalanced '['");
    a.host = rest.substr(1, close - 1);
    if (close + 1 < rest.size() && rest[close + 1] == ':') port = rest.substr(close + 2);
  } else if (const auto colon = rest.rfind(':'); colon != std::string::npos) {
    a.host = rest.substr(0, colon);
    port = rest.substr(colon + 1);
  } else {
    a.host = rest;
  }
  if (a.host.empty()) return fail("--booth " + url + ": no host");
  a.port = a.scheme == "https" ? 443 : 8080;  // 8080: the daemon's default port
  if (!port.empty()) {
    try {
      std::size_t used = 0;
      a.port = std::stoi(port, &used);
      if (used != port.size() || a.port < 1 || a.port > 65535) throw 0;
    } catch (...) {
      return fail("--booth " + url + ": '" + port + "' is not a port");
    }
  }
  a.local = loopback_host(a.host);
  if (a.scheme == "http" && !a.local && !insecure)
    return fail("--booth " + url +
                ": plain HTTP to a booth on another machine sends the token and the captures "
                "unencrypted; use https:// (a TLS proxy in front of the booth), or pass "
                "--insecure on a network you trust");
  const bool v6 = a.host.find(':') != std::string::npos;
  a.url = a.scheme + "://" + (v6 ? "[" + a.host + "]" : a.host) + ":" + std::to_string(a.port);
  return a;
}

BoothClient::BoothClient(const BoothAddress& address, std::string token)
    : address_(address),
      token_(std::move(token)),
      http_(std::make_unique<httplib::Client>(address.url)) {
  http_->set_connection_timeout(5, 0);
  // The booth exports the bundle before the first byte (a second or two for a full session).
  http_->set_read_timeout(60, 0);
  http_->set_write_timeout(30, 0);
  if (!token_.empty()) http_->set_bearer_token_auth(token_.c_str());
}

BoothClient::BoothClient(BoothClient&&) noexcept = default;
BoothClient::~BoothClient() = default;

std::string BoothClient::what(const std::string& path) const {
  return address_.url + path;
}

Result<nlohmann::json> BoothClient::get_json(const std::string& path) {
  auto res = http_->Get(path.c_str());
  if (!res)
    return fail("cannot reach the booth at " + address_.url + " (" +
                httplib::to_string(res.error()) +
                "): is faceboothd running there, and the address right?");
  if (res->status != 200) {
    std::string hint;
    if (res->status == 401 || res->status == 403)
      hint = " (give the booth's [http] token with --token-file)";
    return fail(what(path) + ": " + error_text(res->status, res->body) + hint);
  }
  auto j = nlohmann::json::parse(res->body, nullptr, false);
  if (j.is_discarded() || !j.is_object()) return fail(what(path) + " did not answer JSON");
  return j;
}

Result<nlohmann::json> BoothClient::post(const std::string& path, const std::string& body,
                                         const std::string& content_type) {
  auto res = http_->Post(path.c_str(), body, content_type.c_str());
  if (!res)
    return fail("the booth at " + address_.url + " went away during " + path + " (" +
                httplib::to_string(res.error()) + ")");
  if (res->status / 100 != 2) return fail(what(path) + ": " + error_text(res->status, res->body));
  auto j = nlohmann::json::parse(res->body, nullptr, false);
  if (j.is_discarded()) return fail(what(path) + " did not answer JSON");
  return j;
}

Result<DownloadStats> BoothClient::download(
    const std::string& path, const fs::path& part,
    const std::function<void(std::uint64_t, std::uint64_t)>& progress, double max_bytes_per_s) {
  bool restart = false;
  auto got = download_once(path, part, progress, max_bytes_per_s, restart);
  if (!restart) return got;
  // The booth serves another bundle than the one partly fetched (or it ended): from the start.
  std::error_code ec;
  fs::remove(part, ec);
  fs::remove(fs::path(part.string() + ".etag"), ec);
  return download_once(path, part, progress, max_bytes_per_s, restart);
}

Result<DownloadStats> BoothClient::download_once(
    const std::string& path, const fs::path& part,
    const std::function<void(std::uint64_t, std::uint64_t)>& progress, double max_bytes_per_s,
    bool& restart) {
  restart = false;
  const fs::path tag_file = part.string() + ".etag";
  std::error_code ec;
  const std::uint64_t have = fs::exists(part, ec) ? fs::file_size(part, ec) : 0;
  const std::string tag = have > 0 ? read_line(tag_file) : std::string();
  httplib::Headers headers;
  if (have > 0 && !tag.empty()) headers.emplace("Range", "bytes=" + std::to_string(have) + "-");

  if (max_bytes_per_s > 0) {
    // A small receive window, so TCP slows the booth down: with the kernel's autotuning (tens of
    // MB on loopback) the booth would send everything at once and the limit would only buffer.
    const int window = static_cast<int>(std::clamp(max_bytes_per_s / 8, 16e3, 256e3));
    http_->set_socket_options([window](int sock) {
      ::setsockopt(sock, SOL_SOCKET, SO_RCVBUF, &window, sizeof window);
    });
  }
  DownloadStats stats;
  std::ofstream out;
  std::string error_body;
  int status = 0;
  const auto start = std::chrono::steady_clock::now();
  auto on_response = [&](const httplib::Response& r) {
    status = r.status;
    const std::string etag = r.get_header_value("ETag");
    if (r.status == 206 && have > 0 && !tag.empty() && etag == tag) {
      out.open(part, std::ios::binary | std::ios::app);
      stats.resumed_from = have;
      stats.total = content_range_total(r.get_header_value("Content-Range"));
    } else if (r.status == 200) {
      out.open(part, std::ios::binary | std::ios::trunc);
      stats.total = r.get_header_value<std::uint64_t>("Content-Length");
      std::ofstream(tag_file, std::ios::trunc) << etag << "\n";
    } else if (r.status == 206 || r.status == 416) {
      restart = have > 0;  // another bundle now, or the partial file is already too long
      return false;
    } else {
      return true;  // an error: its JSON body says why
    }
    return out.is_open();
  };
  auto on_data = [&](const char* data, size_t n) {
    if (status / 100 != 2) {
      error_body.append(data, n);
      return error_body.size() < 64 * 1024;
    }
    out.write(data, static_cast<std::streamsize>(n));
    stats.bytes += n;
    if (progress) progress(stats.resumed_from + stats.bytes, stats.total);
    if (max_bytes_per_s > 0) {
      const auto due =
          start + std::chrono::duration<double>(static_cast<double>(stats.bytes) / max_bytes_per_s);
      std::this_thread::sleep_until(due);
    }
    return out.good();
  };
  auto res = http_->Get(path.c_str(), headers, on_response, on_data);
  out.close();
  if (restart) return stats;
  const std::uint64_t kept = fs::exists(part, ec) ? fs::file_size(part, ec) : 0;
  if (!res)
    return fail("the booth at " + address_.url + " went away during the transfer of " + path +
                " (" + httplib::to_string(res.error()) + "; " + std::to_string(kept) + " of " +
                (stats.total ? std::to_string(stats.total) : std::string("?")) +
                " bytes kept to resume): the host store is unchanged; run sync again");
  if (status / 100 != 2) return fail(what(path) + ": " + error_text(status, error_body));
  if (stats.total > 0 && kept != stats.total)
    return fail("the transfer of " + what(path) + " ended after " + std::to_string(kept) + " of " +
                std::to_string(stats.total) + " bytes: run sync again to resume");
  stats.total = kept;
  return stats;
}

}  // namespace fb::cli
