// The HTTP API and the kiosk page (cpp-httplib): the server's set-up, the route table and the
// page and status routes (the other areas' handlers: http_routes.hpp). JSON everywhere. Only
// numeric ids reach the store; files are only ever served from folders the daemon wrote, by
// names it chose (no request string becomes a path). Clients that are not on loopback need the
// token.
#include <sys/socket.h>

#include <nlohmann/json.hpp>

#include "firmware/daemon/http_requests.hpp"
#include "firmware/daemon/http_routes.hpp"
#include "firmware/kiosk/kiosk_assets.hpp"

namespace fb {
namespace http {

using nlohmann::json;

void send_json(Response& res, const json& body, int status) {
  res.status = status;
  res.set_content(body.dump(), "application/json");
}

void send_error(Response& res, int status, const std::string& message) {
  send_json(res, {{"error", message}}, status);
}

Result<std::int64_t> id_param(const Request& req, std::size_t i) {
  return parse_path_id(req.matches[i].str());
}

// --- kiosk page (embedded; see firmware/kiosk/)

void get_kiosk_html(Daemon::Impl&, const Request&, Response& res) {
  res.set_content(std::string(kiosk_html()), "text/html; charset=utf-8");
}

void get_kiosk_js(Daemon::Impl&, const Request&, Response& res) {
  res.set_content(std::string(kiosk_js()), "application/javascript");
}

void get_kiosk_css(Daemon::Impl&, const Request&, Response& res) {
  res.set_content(std::string(kiosk_css()), "text/css");
}

// --- status, guide, preview

void get_status(Daemon::Impl& d, const Request&, Response& res) {
  send_json(res, d.status_json());
}

void get_guide(Daemon::Impl& d, const Request&, Response& res) {
  json list = json::array();
  for (std::size_t i = 0; i < d.guide.size(); ++i)
    list.push_back({{"index", i}, {"name", d.guide[i].name}, {"label", d.guide[i].label}});
  send_json(res, {{"expressions", list}});
}

void get_guide_picture(Daemon::Impl& d, const Request& req, Response& res) {
  auto i = id_param(req, 1);
  if (!i || *i < 0 || *i >= static_cast<std::int64_t>(d.guide.size()))
    return send_error(res, 404, "no such guide expression");
  auto bmp = d.guide_picture(static_cast<int>(*i));
  if (!bmp) return send_error(res, 500, bmp.error().message);
  res.set_header("Cache-Control", "max-age=3600");
  res.set_content(*bmp, "image/bmp");
}

void get_preview(Daemon::Impl& d, const Request&, Response& res) {
  const ColorImage picture = d.preview.picture();  // a copy: encoded outside the lock
  if (picture.empty()) return send_error(res, 503, "no preview frame yet");
  const std::string bmp = encode_bmp(picture);
  res.set_header("Cache-Control", "no-store");
  res.set_content(bmp, "image/bmp");
}

void get_config(Daemon::Impl& d, const Request&, Response& res) {
  DaemonConfig shown = d.config;
  shown.http.token = shown.http.token.empty() ? "" : "(set)";
  res.set_content(to_toml(shown), "application/toml");
}

// --- live events (Server-Sent Events): the status whenever it changes, at most ~20/s.
void get_status_events(Daemon::Impl& d, const Request&, Response& res) {
  res.set_header("Cache-Control", "no-store");
  auto seen = std::make_shared<std::uint64_t>(~0ull);
  res.set_chunked_content_provider(
      "text/event-stream", [&d, seen](size_t, httplib::DataSink& sink) {
        if (d.stopping) return false;
        std::uint64_t version;
        {
          std::unique_lock lock(d.status_mutex);
          d.status_cv.wait_for(lock, std::chrono::milliseconds(250),
                               [&] { return d.status_version != *seen || d.stopping.load(); });
          version = d.status_version;
        }
        if (d.stopping) return false;
        if (version == *seen) {
          static const char kPing[] = ": keep-alive\n\n";
          return sink.write(kPing, sizeof kPing - 1);
        }
        *seen = version;
        const std::string msg = "event: status\ndata: " + d.status_json().dump() + "\n\n";
        std::this_thread::sleep_for(std::chrono::milliseconds(50));  // coalesce bursts
        return sink.write(msg.data(), msg.size());
      });
}

}  // namespace http

namespace {

using http::Method;
using http::Route;

// Every route of the API, in httplib's matching order (each pattern matches the whole path).
constexpr Route kRoutes[] = {
    {Method::kGet, "/", http::get_kiosk_html},
    {Method::kGet, "/kiosk.js", http::get_kiosk_js},
    {Method::kGet, "/kiosk.css", http::get_kiosk_css},
    {Method::kGet, "/api/status", http::get_status},
    {Method::kGet, "/api/guide", http::get_guide},
    {Method::kGet, R"(/api/guide/(\d{1,3})\.bmp)", http::get_guide_picture},
    {Method::kGet, "/api/preview.bmp", http::get_preview},
    {Method::kGet, "/api/config", http::get_config},
    {Method::kGet, "/api/events", http::get_status_events},
    {Method::kGet, "/api/sessions", http::get_sessions},
    {Method::kGet, R"(/api/sessions/(\d{1,12}))", http::get_session},
    {Method::kGet, R"(/api/sessions/(\d{1,12})/captures)", http::get_session_captures},
    // The host tool's offload: the sessions ready for rigging, a session's bundle (a streamed
    // ustar of its export), and a rig uploaded back.
    {Method::kGet, "/api/offload/ready", http::get_offload_ready},
    {Method::kGet, R"(/api/offload/sessions/(\d{1,12})/bundle\.tar)", http::get_session_bundle},
    {Method::kGet, R"(/api/sessions/(\d{1,12})/export\.tar)", http::get_session_bundle},
    {Method::kPost, R"(/api/offload/sessions/(\d{1,12})/rig)", http::post_rig_upload},
    // The QA screen: the processed capture's frontal colour frame and landmark corrections.
    {Method::kGet, "/api/qa/capture.bmp", http::get_qa_capture_picture},
    {Method::kPost, R"(/api/sessions/(\d{1,12})/captures/(\d{1,3})/landmarks)",
     http::post_landmark_corrections},
    // Tracking mode's live weights: the latest frame, and as Server-Sent Events.
    {Method::kGet, "/api/tracking/live", http::get_tracking_live},
    {Method::kGet, "/api/tracking/events", http::get_tracking_events},
    {Method::kPost, R"(/api/sessions/(\d{1,12})/export)", http::post_session_export},
    // The page's buttons.
    {Method::kPost, "/api/session/start", http::post_session_start},
    {Method::kPost, "/api/session/next", http::post_session_next},
    {Method::kPost, "/api/session/retry", http::post_session_retry},
    {Method::kPost, "/api/session/cancel", http::post_session_cancel},
    {Method::kPost, R"(/api/sessions/(\d{1,12})/resume)", http::post_session_resume},
    {Method::kPost, "/api/mode", http::post_mode},
    // Camera registration: the health check, and self-calibration from the live frames.
    {Method::kGet, "/api/camera/registration", http::get_camera_registration},
    {Method::kPost, "/api/camera/self-calibrate", http::post_self_calibrate},
    {Method::kPost, "/api/sim/button", http::post_sim_button},
};

bool is_loopback(const std::string& addr) {
  return addr.rfind("127.", 0) == 0 || addr == "::1" || addr.rfind("::ffff:127.", 0) == 0;
}

// Constant-time comparison: the token check must not leak how many leading bytes matched.
bool same_secret(const std::string& a, const std::string& b) {
  if (a.size() != b.size() || a.empty()) return false;
  unsigned char diff = 0;
  for (std::size_t i = 0; i < a.size(); ++i) diff |= static_cast<unsigned char>(a[i] ^ b[i]);
  return diff == 0;
}

// Bodies are small JSON, except a rig uploaded by the host (FaceWarehouse shape.bs, ~8 MB for
// the face model); the pre-routing handler refuses big bodies on every other route.
constexpr std::size_t kSmallBody = 64 * 1024;
constexpr std::size_t kRigBody = 32 * 1024 * 1024;

// Before any route: the body size, then the token for clients that are not on loopback.
httplib::Server::HandlerResponse check_request(const std::string& token,
                                               const httplib::Request& req,
                                               httplib::Response& res) {
  const std::size_t length = req.get_header_value<uint64_t>("Content-Length");
  const bool rig_upload = req.method == "POST" && req.path.rfind("/api/offload/", 0) == 0 &&
                          req.path.size() > 4 && req.path.substr(req.path.size() - 4) == "/rig";
  if (length > (rig_upload ? kRigBody : kSmallBody)) {
    http::send_error(res, 413, "request body too large");
    return httplib::Server::HandlerResponse::Handled;
  }
  if (is_loopback(req.remote_addr)) return httplib::Server::HandlerResponse::Unhandled;
  std::string presented;
  const std::string auth = req.get_header_value("Authorization");
  if (auth.rfind("Bearer ", 0) == 0) presented = auth.substr(7);
  if (presented.empty() && req.has_param("token")) presented = req.get_param_value("token");
  if (token.empty()) {
    http::send_error(res, 403, "remote access is disabled: set [http] token in the config");
    return httplib::Server::HandlerResponse::Handled;
  }
  if (!same_secret(presented, token)) {
    res.set_header("WWW-Authenticate", "Bearer");
    http::send_error(res, 401, "missing or wrong token (Authorization: Bearer TOKEN)");
    return httplib::Server::HandlerResponse::Handled;
  }
  return httplib::Server::HandlerResponse::Unhandled;
}

void answer_exception(const httplib::Request&, httplib::Response& res, std::exception_ptr ep) {
  std::string what = "internal error";
  try {
    if (ep) std::rethrow_exception(ep);
  } catch (const std::exception& e) {
    what = std::string("internal error: ") + e.what();
  } catch (...) {
  }
  http::send_error(res, 500, what);
}

void answer_error(const httplib::Request&, httplib::Response& res) {
  if (res.body.empty())
    http::send_error(
        res, res.status,
        "HTTP " + std::to_string(res.status) + (res.status == 404 ? " not found" : ""));
}

// Threads, socket options, timeouts, body limits, the token check and the error answers.
void configure_server(httplib::Server& srv, int threads, const std::string& token) {
  // httplib's API takes ownership of a raw TaskQueue pointer it deletes itself.
  srv.new_task_queue = [threads] { return new httplib::ThreadPool(static_cast<size_t>(threads)); };
  // httplib's default sets SO_REUSEPORT, which lets a second process bind the same port and
  // silently take half of the connections (two daemons, or a test's daemon and another's).
  // SO_REUSEADDR alone still allows a quick restart; a port in use is then a clear bind error.
  srv.set_socket_options([](socket_t sock) {
    int yes = 1;
    ::setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  });
  // Short keep-alive and read timeouts so stop() finishes well within systemd's 2 s budget.
  srv.set_keep_alive_timeout(1);
  srv.set_read_timeout(1, 0);
  srv.set_write_timeout(2, 0);
  srv.set_payload_max_length(kRigBody);
  // The token is read per request: Impl::token is set before setup_http and never changes.
  srv.set_pre_routing_handler([&token](const httplib::Request& req, httplib::Response& res) {
    return check_request(token, req, res);
  });
  srv.set_exception_handler(answer_exception);
  srv.set_error_handler(answer_error);
}

}  // namespace

Result<void> Daemon::Impl::setup_http() {
  http = std::make_unique<httplib::Server>();
  auto& srv = *http;
  configure_server(srv, config.http.threads, token);
  for (const Route& route : kRoutes) {
    auto handler = [this, h = route.handler](const httplib::Request& req, httplib::Response& res) {
      h(*this, req, res);
    };
    if (route.method == Method::kGet)
      srv.Get(route.pattern, handler);
    else
      srv.Post(route.pattern, handler);
  }

  // Bind now, so a busy port is a start-up error and not a silent background failure.
  bool bound = false;
  try {
    if (config.http.port == 0) {
      http_port = srv.bind_to_any_port(config.http.bind);
      bound = http_port > 0;
    } else {
      bound = srv.bind_to_port(config.http.bind, config.http.port);
      http_port = config.http.port;
    }
  } catch (const std::exception& e) {
    return fail("HTTP bind to " + config.http.bind + ":" + std::to_string(config.http.port) +
                " failed: " + e.what());
  }
  if (!bound)
    return fail("cannot listen on " + config.http.bind + ":" + std::to_string(config.http.port) +
                " (in use, or a bad address); change [http] port or bind");
  return success();
}

}  // namespace fb
