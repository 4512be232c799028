// The HTTP API and the kiosk page (cpp-httplib). JSON everywhere. Only numeric ids reach the
// store; files are only ever served from folders the daemon wrote, by names it chose (no
// request string becomes a path). Clients that are not on loopback need the token.
#include <sys/socket.h>

#include <algorithm>
#include <cmath>
#include <ctime>
#include <fstream>
#include <nlohmann/json.hpp>

#include "firmware/daemon/daemon_impl.hpp"
#include "firmware/daemon/http_requests.hpp"
#include "firmware/kiosk/kiosk_assets.hpp"
#include "storage/export/facewarehouse.hpp"
#include "storage/sha256.hpp"

namespace fb {
namespace {

using nlohmann::json;

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

void send_json(httplib::Response& res, const json& body, int status = 200) {
  res.status = status;
  res.set_content(body.dump(), "application/json");
}

void send_error(httplib::Response& res, int status, const std::string& message) {
  send_json(res, {{"error", message}}, status);
}

Result<std::int64_t> id_param(const httplib::Request& req, std::size_t i) {
  return parse_path_id(req.matches[i].str());
}

// Seconds since the epoch of an ISO 8601 UTC time ("2026-12-06T06:30:00.123Z"); 0 if unreadable.
std::int64_t iso_seconds(const std::string& iso) {
  std::tm tm{};
  if (!strptime(iso.c_str(), "%Y-%m-%dT%H:%M:%S", &tm)) return 0;
  return static_cast<std::int64_t>(timegm(&tm));
}

// A bundle's identity: the SHA-256 of its manifest's file list (paths, sizes, digests), which,
// unlike the manifest file itself, has no creation time in it.
std::string bundle_etag(const std::filesystem::path& folder) {
  std::ifstream in(folder / "manifest.json");
  auto j = json::parse(in, nullptr, false);
  if (j.is_discarded() || !j.contains("files")) return {};
  const std::string files = j["files"].dump();
  return "\"" +
         sha256_hex(std::span(reinterpret_cast<const std::uint8_t*>(files.data()), files.size()))
             .substr(0, 32) +
         "\"";
}

json session_json(const RecordSession& s) {
  return {{"id", s.id},
          {"subject", s.subject},
          {"subject_name", s.subject_name},
          {"created_at", s.created_at},
          {"complete", s.complete},
          {"capture_count", s.capture_count},
          {"done_count", s.done_count},
          {"folder", s.folder.string()}};
}

json capture_json(const RecordCapture& c) {
  return {{"index", c.index},
          {"expression", c.expression},
          {"state", to_string(c.state)},
          {"attempts", c.attempts},
          {"qa", c.qa_scores},
          {"frame_count", c.frame_count},
          {"completed_at", c.completed_at}};
}

}  // namespace

Result<void> Daemon::Impl::setup_http() {
  http = std::make_unique<httplib::Server>();
  auto& srv = *http;
  const int threads = config.http.threads;
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
  // Bodies are small JSON, except a rig uploaded by the host (FaceWarehouse shape.bs, ~8 MB for
  // the face model); the pre-routing handler refuses big bodies on every other route.
  constexpr std::size_t kSmallBody = 64 * 1024;
  constexpr std::size_t kRigBody = 32 * 1024 * 1024;
  srv.set_payload_max_length(kRigBody);

  srv.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
    const std::size_t length = req.get_header_value<uint64_t>("Content-Length");
    const bool rig_upload = req.method == "POST" && req.path.rfind("/api/offload/", 0) == 0 &&
                            req.path.size() > 4 && req.path.substr(req.path.size() - 4) == "/rig";
    if (length > (rig_upload ? kRigBody : kSmallBody)) {
      send_error(res, 413, "request body too large");
      return httplib::Server::HandlerResponse::Handled;
    }
    if (is_loopback(req.remote_addr)) return httplib::Server::HandlerResponse::Unhandled;
    std::string presented;
    const std::string auth = req.get_header_value("Authorization");
    if (auth.rfind("Bearer ", 0) == 0) presented = auth.substr(7);
    if (presented.empty() && req.has_param("token")) presented = req.get_param_value("token");
    if (token.empty()) {
      send_error(res, 403, "remote access is disabled: set [http] token in the config");
      return httplib::Server::HandlerResponse::Handled;
    }
    if (!same_secret(presented, token)) {
      res.set_header("WWW-Authenticate", "Bearer");
      send_error(res, 401, "missing or wrong token (Authorization: Bearer TOKEN)");
      return httplib::Server::HandlerResponse::Handled;
    }
    return httplib::Server::HandlerResponse::Unhandled;
  });
  srv.set_exception_handler(
      [](const httplib::Request&, httplib::Response& res, std::exception_ptr ep) {
        std::string what = "internal error";
        try {
          if (ep) std::rethrow_exception(ep);
        } catch (const std::exception& e) {
          what = std::string("internal error: ") + e.what();
        } catch (...) {
        }
        send_error(res, 500, what);
      });
  srv.set_error_handler([](const httplib::Request&, httplib::Response& res) {
    if (res.body.empty())
      send_error(res, res.status,
                 "HTTP " + std::to_string(res.status) + (res.status == 404 ? " not found" : ""));
  });

  // --- kiosk page (embedded; see firmware/kiosk/)
  srv.Get("/", [](const httplib::Request&, httplib::Response& res) {
    res.set_content(std::string(kiosk_html()), "text/html; charset=utf-8");
  });
  srv.Get("/kiosk.js", [](const httplib::Request&, httplib::Response& res) {
    res.set_content(std::string(kiosk_js()), "application/javascript");
  });
  srv.Get("/kiosk.css", [](const httplib::Request&, httplib::Response& res) {
    res.set_content(std::string(kiosk_css()), "text/css");
  });

  // --- status, guide, preview
  srv.Get("/api/status", [this](const httplib::Request&, httplib::Response& res) {
    send_json(res, status_json());
  });
  srv.Get("/api/guide", [this](const httplib::Request&, httplib::Response& res) {
    json list = json::array();
    for (std::size_t i = 0; i < guide.size(); ++i)
      list.push_back({{"index", i}, {"name", guide[i].name}, {"label", guide[i].label}});
    send_json(res, {{"expressions", list}});
  });
  srv.Get(R"(/api/guide/(\d{1,3})\.bmp)",
          [this](const httplib::Request& req, httplib::Response& res) {
            auto i = id_param(req, 1);
            if (!i || *i < 0 || *i >= static_cast<std::int64_t>(guide.size()))
              return send_error(res, 404, "no such guide expression");
            auto bmp = guide_picture(static_cast<int>(*i));
            if (!bmp) return send_error(res, 500, bmp.error().message);
            res.set_header("Cache-Control", "max-age=3600");
            res.set_content(*bmp, "image/bmp");
          });
  srv.Get("/api/preview.bmp", [this](const httplib::Request&, httplib::Response& res) {
    ColorImage picture;  // copied under the lock, encoded outside it (see status_json)
    {
      std::lock_guard lock(preview_mutex);
      picture = preview;
    }
    if (picture.empty()) return send_error(res, 503, "no preview frame yet");
    const std::string bmp = encode_bmp(picture);
    res.set_header("Cache-Control", "no-store");
    res.set_content(bmp, "image/bmp");
  });
  srv.Get("/api/config", [this](const httplib::Request&, httplib::Response& res) {
    DaemonConfig shown = config;
    shown.http.token = shown.http.token.empty() ? "" : "(set)";
    res.set_content(to_toml(shown), "application/toml");
  });

  // --- live events (Server-Sent Events): the status whenever it changes, at most ~20/s.
  srv.Get("/api/events", [this](const httplib::Request&, httplib::Response& res) {
    res.set_header("Cache-Control", "no-store");
    auto seen = std::make_shared<std::uint64_t>(~0ull);
    res.set_chunked_content_provider(
        "text/event-stream", [this, seen](size_t, httplib::DataSink& sink) {
          if (stopping) return false;
          std::uint64_t version;
          {
            std::unique_lock lock(status_mutex);
            status_cv.wait_for(lock, std::chrono::milliseconds(250),
                               [&] { return status_version != *seen || stopping.load(); });
            version = status_version;
          }
          if (stopping) return false;
          if (version == *seen) {
            static const char kPing[] = ": keep-alive\n\n";
            return sink.write(kPing, sizeof kPing - 1);
          }
          *seen = version;
          const std::string msg = "event: status\ndata: " + status_json().dump() + "\n\n";
          std::this_thread::sleep_for(std::chrono::milliseconds(50));  // coalesce bursts
          return sink.write(msg.data(), msg.size());
        });
  });

  // --- sessions and captures
  srv.Get("/api/sessions", [this](const httplib::Request&, httplib::Response& res) {
    std::lock_guard lock(records_mutex);
    auto all = records->sessions();
    if (!all) return send_error(res, 500, all.error().message);
    json list = json::array();
    for (const auto& s : *all) list.push_back(session_json(s));
    send_json(
        res,
        {{"store", records->backend()}, {"root", records->root().string()}, {"sessions", list}});
  });
  srv.Get(R"(/api/sessions/(\d{1,12}))",
          [this](const httplib::Request& req, httplib::Response& res) {
            auto id = id_param(req, 1);
            if (!id) return send_error(res, 400, id.error().message);
            std::lock_guard lock(records_mutex);
            auto s = records->session(*id);
            if (!s) return send_error(res, 404, s.error().message);
            auto caps = records->captures(*id);
            if (!caps) return send_error(res, 500, caps.error().message);
            json j = session_json(*s);
            j["captures"] = json::array();
            for (const auto& c : *caps) j["captures"].push_back(capture_json(c));
            send_json(res, j);
          });
  srv.Get(R"(/api/sessions/(\d{1,12})/captures)",
          [this](const httplib::Request& req, httplib::Response& res) {
            auto id = id_param(req, 1);
            if (!id) return send_error(res, 400, id.error().message);
            std::lock_guard lock(records_mutex);
            auto caps = records->captures(*id);
            if (!caps) return send_error(res, 404, caps.error().message);
            json list = json::array();
            for (const auto& c : *caps) list.push_back(capture_json(c));
            send_json(res, {{"session", *id}, {"captures", list}});
          });
  // The host tool's offload endpoints: the sessions ready for rigging (complete, every capture
  // fitted), a session's bundle (streamed ustar of its export), and a rig uploaded back.
  srv.Get("/api/offload/ready", [this](const httplib::Request&, httplib::Response& res) {
    std::lock_guard lock(records_mutex);
    auto all = records->sessions();
    if (!all) return send_error(res, 500, all.error().message);
    json list = json::array();
    for (const auto& s : *all) {
      if (!s.complete) continue;
      auto info = records->offload_info(s.id);
      if (!info) return send_error(res, 500, info.error().message);
      json j = session_json(s);
      j["fitted_captures"] = info->fitted_captures;
      j["ready_for_rigging"] = info->fitted_captures == s.capture_count;
      j["rigs"] = info->rigs;
      j["bundle"] = "/api/offload/sessions/" + std::to_string(s.id) + "/bundle.tar";
      j["rig_upload"] = "/api/offload/sessions/" + std::to_string(s.id) + "/rig";
      list.push_back(j);
    }
    send_json(res, {{"booth_id", booth_id}, {"sessions", list}});
  });
  auto send_bundle = [this](const httplib::Request& req, httplib::Response& res) {
    auto id = id_param(req, 1);
    if (!id) return send_error(res, 400, id.error().message);
    Result<std::filesystem::path> out = fail("");
    std::string created_at;
    {
      std::lock_guard lock(records_mutex);
      out = records->export_session(*id, config.storage.data_dir / "exports",
                                    [this] { return stopping.load(); });
      if (auto s = records->session(*id)) created_at = s->created_at;
    }
    if (!out) return send_error(res, 404, out.error().message);
    const std::string prefix = "session-" + std::to_string(*id);
    auto tar = TarStream::open(*out, prefix, iso_seconds(created_at));
    if (!tar) return send_error(res, 500, tar.error().message);
    auto stream = std::make_shared<TarStream>(std::move(*tar));
    res.set_header("Content-Disposition", "attachment; filename=\"" + prefix + ".tar\"");
    // The same files give the same archive: a host resumes a cut transfer with a Range request
    // and compares this tag to know that the rest is of the same bundle.
    if (auto tag = bundle_etag(*out); !tag.empty()) res.set_header("ETag", tag);
    res.set_content_provider(static_cast<size_t>(stream->size()), "application/x-tar",
                             [stream](size_t offset, size_t length, httplib::DataSink& sink) {
                               auto bytes =
                                   stream->read(offset, std::min<size_t>(length, 256 * 1024));
                               if (!bytes) return false;
                               return sink.write(bytes->data(), bytes->size());
                             });
  };
  srv.Get(R"(/api/offload/sessions/(\d{1,12})/bundle\.tar)", send_bundle);
  srv.Get(R"(/api/sessions/(\d{1,12})/export\.tar)", send_bundle);
  // A rig from the host: FaceWarehouse's shape.bs (int32 shapes, vertices, faces; float32
  // xyz of the neutral then of each shape) in the face model's topology. Optional query
  // `names=a,b,...` names the shapes (default: the model's expression names in order).
  srv.Post(R"(/api/offload/sessions/(\d{1,12})/rig)", [this](const httplib::Request& req,
                                                             httplib::Response& res) {
    auto id = id_param(req, 1);
    if (!id) return send_error(res, 400, id.error().message);
    if (!fitter) return send_error(res, 409, "rig upload needs the face model: " + fitter_error);
    const FaceModel& model = fitter->model();
    auto rig = decode_shape_bs(std::span<const std::uint8_t>(
        reinterpret_cast<const std::uint8_t*>(req.body.data()), req.body.size()));
    if (!rig) return send_error(res, 400, "not a FaceWarehouse shape.bs: " + rig.error().message);
    const auto names = req.has_param("names")
                           ? std::optional<std::string>(req.get_param_value("names"))
                           : std::nullopt;
    if (auto ok = check_rig_upload(*rig, model.vertex_count, names, model.expression_names); !ok)
      return send_error(res, 422, ok.error().message);
    rig->triangles = model.triangles;
    std::lock_guard lock(records_mutex);
    auto s = records->session(*id);
    if (!s) return send_error(res, 404, s.error().message);
    if (!s->complete)
      return send_error(res, 409, "session " + std::to_string(*id) + " is not complete");
    auto rid = records->add_rig(*id, *rig);
    if (!rid) return send_error(res, 500, rid.error().message);
    send_json(res,
              {{"session", *id},
               {"rig", *rid},
               {"shapes", rig->shape_count()},
               {"vertices", rig->vertex_count()}},
              201);
  });
  // --- QA screen: the processed capture's frontal colour frame and landmark corrections.
  srv.Get("/api/qa/capture.bmp", [this](const httplib::Request&, httplib::Response& res) {
    std::string bmp;
    {
      std::lock_guard lock(preview_mutex);
      bmp = last_capture_bmp;
    }
    if (bmp.empty()) return send_error(res, 404, "no processed capture yet");
    res.set_header("Cache-Control", "no-store");
    res.set_content(bmp, "image/bmp");
  });
  srv.Post(R"(/api/sessions/(\d{1,12})/captures/(\d{1,3})/landmarks)",
           [this](const httplib::Request& req, httplib::Response& res) {
             auto id = id_param(req, 1);
             auto index = id_param(req, 2);
             if (!id || !index) return send_error(res, 400, "bad id");
             auto corrections = parse_landmark_corrections(req.body);
             if (!corrections) return send_error(res, 400, corrections.error().message);
             auto r = correct_landmarks(*id, static_cast<int>(*index), *corrections);
             if (!r) return send_error(res, 409, r.error().message);
             send_json(res, *r);
           });
  // --- tracking mode's live weights: the latest frame, and as Server-Sent Events.
  srv.Get("/api/tracking/live", [this](const httplib::Request&, httplib::Response& res) {
    std::string body;
    {
      std::lock_guard lock(live_mutex);
      body = live_json;
    }
    if (body.empty()) return send_error(res, 404, "no tracked frame yet (switch to tracking mode)");
    res.set_header("Cache-Control", "no-store");
    res.set_content(body, "application/json");
  });
  srv.Get("/api/tracking/events", [this](const httplib::Request&, httplib::Response& res) {
    res.set_header("Cache-Control", "no-store");
    auto seen = std::make_shared<std::uint64_t>(0);
    res.set_chunked_content_provider(
        "text/event-stream", [this, seen](size_t, httplib::DataSink& sink) {
          if (stopping) return false;
          std::string msg;
          {
            std::unique_lock lock(live_mutex);
            live_cv.wait_for(lock, std::chrono::milliseconds(250),
                             [&] { return live_version != *seen || stopping.load(); });
            if (stopping) return false;
            if (live_version == *seen) {
              msg = ": keep-alive\n\n";
            } else {
              *seen = live_version;
              msg = "event: face\ndata: " + live_json + "\n\n";
            }
          }
          // At most ~15 events/s per client: the page draws bars, not every frame.
          std::this_thread::sleep_for(std::chrono::milliseconds(60));
          return sink.write(msg.data(), msg.size());
        });
  });
  srv.Post(R"(/api/sessions/(\d{1,12})/export)",
           [this](const httplib::Request& req, httplib::Response& res) {
             auto id = id_param(req, 1);
             if (!id) return send_error(res, 400, id.error().message);
             std::lock_guard lock(records_mutex);
             auto out = records->export_session(*id, config.storage.data_dir / "exports",
                                                [this] { return stopping.load(); });
             if (!out) return send_error(res, 404, out.error().message);
             send_json(res, {{"session", *id},
                             {"folder", out->string()},
                             {"download", "/api/sessions/" + std::to_string(*id) + "/export.tar"}});
           });
  // --- controls: the page's buttons and the simulated GPIO
  auto control = [this](const char* path, KioskInput input) {
    http->Post(path, [this, input](const httplib::Request& req, httplib::Response& res) {
      auto subject = parse_control_request(req.body);
      if (!subject) return send_error(res, 400, subject.error().message);
      {
        std::lock_guard lock(queue_mutex);
        queue.push_back({input, *subject, 0});
      }
      queue_cv.notify_all();
      send_json(res, {{"accepted", to_string(input)}}, 202);
    });
  };
  control("/api/session/start", KioskInput::kStart);
  control("/api/session/next", KioskInput::kPress);
  control("/api/session/retry", KioskInput::kPress);
  control("/api/session/cancel", KioskInput::kCancel);
  srv.Post(R"(/api/sessions/(\d{1,12})/resume)",
           [this](const httplib::Request& req, httplib::Response& res) {
             auto id = id_param(req, 1);
             if (!id) return send_error(res, 400, id.error().message);
             {
               std::lock_guard lock(queue_mutex);
               queue.push_back({KioskInput::kResume, {}, *id});
             }
             queue_cv.notify_all();
             send_json(res, {{"accepted", "resume"}, {"session", *id}}, 202);
           });
  srv.Post("/api/mode", [this](const httplib::Request& req, httplib::Response& res) {
    auto want_tracking = parse_mode_request(req.body);
    if (!want_tracking) return send_error(res, 400, want_tracking.error().message);
    const std::string mode = *want_tracking ? "tracking" : "capture";
    bool tracking;
    {
      std::lock_guard lock(status_mutex);
      tracking = status.state == KioskState::kTracking;
    }
    if ((mode == "tracking") != tracking) {
      std::lock_guard lock(queue_mutex);
      queue.push_back({KioskInput::kMode, {}, 0});
    }
    queue_cv.notify_all();
    send_json(res, {{"accepted", mode}}, 202);
  });
  // --- camera registration: the health check, and self-calibration from the live frames.
  srv.Get("/api/camera/registration", [this](const httplib::Request&, httplib::Response& res) {
    std::lock_guard lock(status_mutex);
    send_json(res, registration_json(status));
  });
  srv.Post(
      "/api/camera/self-calibrate", [this](const httplib::Request& req, httplib::Response& res) {
        auto frames = parse_self_calibrate_request(req.body, config.camera.self_calibrate_frames);
        if (!frames) return send_error(res, 400, frames.error().message);
        auto report = request_self_calibration(*frames);
        if (!report) return send_error(res, 409, report.error().message);
        // 422: the estimate was not good enough to use; the report says why and what to do.
        send_json(res, *report, (*report)["applied"].get<bool>() ? 200 : 422);
      });
  srv.Post("/api/sim/button", [this](const httplib::Request& req, httplib::Response& res) {
    auto request = parse_button_request(req.body);
    if (!request) return send_error(res, 400, request.error().message);
    const auto button = parse_button(request->button);
    if (!button) return send_error(res, 400, "button must be \"main\" or \"mode\"");
    auto ok = simulate_press(*gpio,
                             {*button, request->long_press ? PressKind::kLong : PressKind::kShort});
    if (!ok) return send_error(res, 409, ok.error().message);
    send_json(res,
              {{"pressed", to_string(*button)}, {"kind", request->long_press ? "long" : "short"}},
              202);
  });

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
