// Private: the HTTP API's route table (http_api.cpp) and its handlers, one function per route,
// grouped by area: the page and status (http_api.cpp), the kiosk's controls and the QA screen
// (http_session_routes.cpp), the stored sessions, their exports and the host's offload
// (http_store_routes.cpp), the camera, tracking and the simulated button
// (http_device_routes.cpp). A handler reads the daemon through Daemon::Impl and answers JSON;
// each takes the locks it needs itself.
#pragma once

#include <nlohmann/json.hpp>

#include "firmware/daemon/daemon_impl.hpp"

namespace fb::http {

using Request = httplib::Request;
using Response = httplib::Response;
using Handler = void (*)(Daemon::Impl& d, const Request& req, Response& res);

enum class Method { kGet, kPost };

struct Route {
  Method method;
  const char* pattern;  // a regular expression over the whole path (httplib's matching)
  Handler handler;
};

void send_json(Response& res, const nlohmann::json& body, int status = 200);
void send_error(Response& res, int status, const std::string& message);
// The path's i-th (\d{1,12}) group as an id.
Result<std::int64_t> id_param(const Request& req, std::size_t i);

// The page, status, guide, preview, config and the status stream (http_api.cpp).
void get_kiosk_html(Daemon::Impl& d, const Request& req, Response& res);
void get_kiosk_js(Daemon::Impl& d, const Request& req, Response& res);
void get_kiosk_css(Daemon::Impl& d, const Request& req, Response& res);
void get_status(Daemon::Impl& d, const Request& req, Response& res);
void get_guide(Daemon::Impl& d, const Request& req, Response& res);
void get_guide_picture(Daemon::Impl& d, const Request& req, Response& res);
void get_preview(Daemon::Impl& d, const Request& req, Response& res);
void get_config(Daemon::Impl& d, const Request& req, Response& res);
void get_status_events(Daemon::Impl& d, const Request& req, Response& res);

// The kiosk's controls and the QA screen (http_session_routes.cpp).
void get_qa_capture_picture(Daemon::Impl& d, const Request& req, Response& res);
void post_landmark_corrections(Daemon::Impl& d, const Request& req, Response& res);
void post_session_start(Daemon::Impl& d, const Request& req, Response& res);
void post_session_next(Daemon::Impl& d, const Request& req, Response& res);
void post_session_retry(Daemon::Impl& d, const Request& req, Response& res);
void post_session_cancel(Daemon::Impl& d, const Request& req, Response& res);
void post_session_resume(Daemon::Impl& d, const Request& req, Response& res);
void post_mode(Daemon::Impl& d, const Request& req, Response& res);

// The stored sessions, their exports and the host's offload (http_store_routes.cpp).
void get_sessions(Daemon::Impl& d, const Request& req, Response& res);
void get_session(Daemon::Impl& d, const Request& req, Response& res);
void get_session_captures(Daemon::Impl& d, const Request& req, Response& res);
void get_offload_ready(Daemon::Impl& d, const Request& req, Response& res);
void get_session_bundle(Daemon::Impl& d, const Request& req, Response& res);
void post_rig_upload(Daemon::Impl& d, const Request& req, Response& res);
void post_session_export(Daemon::Impl& d, const Request& req, Response& res);

// Tracking's live weights, the camera's registration, the simulated button
// (http_device_routes.cpp).
void get_tracking_live(Daemon::Impl& d, const Request& req, Response& res);
void get_tracking_events(Daemon::Impl& d, const Request& req, Response& res);
void get_camera_registration(Daemon::Impl& d, const Request& req, Response& res);
void post_self_calibrate(Daemon::Impl& d, const Request& req, Response& res);
void post_sim_button(Daemon::Impl& d, const Request& req, Response& res);

}  // namespace fb::http
