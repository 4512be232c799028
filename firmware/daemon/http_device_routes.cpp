// The HTTP API's device routes: tracking mode's live weights (the latest frame, and as
// Server-Sent Events), the camera's registration health and self-calibration, and the
// simulated GPIO's button.
#include "firmware/daemon/http_requests.hpp"
#include "firmware/daemon/http_routes.hpp"

namespace fb::http {

void get_tracking_live(Daemon::Impl& d, const Request&, Response& res) {
  const std::string body = d.tracking.live().latest();
  if (body.empty()) return send_error(res, 404, "no tracked frame yet (switch to tracking mode)");
  res.set_header("Cache-Control", "no-store");
  res.set_content(body, "application/json");
}

void get_tracking_events(Daemon::Impl& d, const Request&, Response& res) {
  res.set_header("Cache-Control", "no-store");
  auto seen = std::make_shared<std::uint64_t>(0);
  res.set_chunked_content_provider(
      "text/event-stream", [&d, seen](size_t, httplib::DataSink& sink) {
        if (d.stopping) return false;
        const std::string json =
            d.tracking.live().wait_newer(*seen, std::chrono::milliseconds(250), d.stopping);
        if (d.stopping) return false;
        const std::string msg =
            json.empty() ? ": keep-alive\n\n" : "event: face\ndata: " + json + "\n\n";
        // At most ~15 events/s per client: the page draws bars, not every frame.
        std::this_thread::sleep_for(std::chrono::milliseconds(60));
        return sink.write(msg.data(), msg.size());
      });
}

void get_camera_registration(Daemon::Impl& d, const Request&, Response& res) {
  std::lock_guard lock(d.status_mutex);
  send_json(res, registration_json(d.status));
}

void post_self_calibrate(Daemon::Impl& d, const Request& req, Response& res) {
  auto frames = parse_self_calibrate_request(req.body, d.config.camera.self_calibrate_frames);
  if (!frames) return send_error(res, 400, frames.error().message);
  auto report = d.request_self_calibration(*frames);
  if (!report) return send_error(res, 409, report.error().message);
  // 422: the estimate was not good enough to use; the report says why and what to do.
  send_json(res, *report, (*report)["applied"].get<bool>() ? 200 : 422);
}

void post_sim_button(Daemon::Impl& d, const Request& req, Response& res) {
  auto request = parse_button_request(req.body);
  if (!request) return send_error(res, 400, request.error().message);
  const auto button = parse_button(request->button);
  if (!button) return send_error(res, 400, "button must be \"main\" or \"mode\"");
  auto ok = simulate_press(*d.gpio,
                           {*button, request->long_press ? PressKind::kLong : PressKind::kShort});
  if (!ok) return send_error(res, 409, ok.error().message);
  send_json(res,
            {{"pressed", to_string(*button)}, {"kind", request->long_press ? "long" : "short"}},
            202);
}

}  // namespace fb::http
