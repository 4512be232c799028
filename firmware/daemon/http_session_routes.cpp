// The HTTP API's session routes: the kiosk page's controls (start, next, retry, cancel, resume,
// the mode), queued for the worker, and the QA screen (the processed capture's picture and the
// operator's landmark corrections, answered by the fit worker).
#include "firmware/daemon/http_requests.hpp"
#include "firmware/daemon/http_routes.hpp"

namespace fb::http {
namespace {

// A button of the page: queued for the worker, answered at once (202).
void queue_control(Daemon::Impl& d, const Request& req, Response& res, KioskInput input) {
  auto subject = parse_control_request(req.body);
  if (!subject) return send_error(res, 400, subject.error().message);
  {
    std::lock_guard lock(d.queue_mutex);
    d.queue.push_back({input, *subject, 0});
  }
  d.queue_cv.notify_all();
  send_json(res, {{"accepted", to_string(input)}}, 202);
}

}  // namespace

void post_session_start(Daemon::Impl& d, const Request& req, Response& res) {
  queue_control(d, req, res, KioskInput::kStart);
}

void post_session_next(Daemon::Impl& d, const Request& req, Response& res) {
  queue_control(d, req, res, KioskInput::kPress);
}

void post_session_retry(Daemon::Impl& d, const Request& req, Response& res) {
  queue_control(d, req, res, KioskInput::kPress);
}

void post_session_cancel(Daemon::Impl& d, const Request& req, Response& res) {
  queue_control(d, req, res, KioskInput::kCancel);
}

void post_session_resume(Daemon::Impl& d, const Request& req, Response& res) {
  auto id = id_param(req, 1);
  if (!id) return send_error(res, 400, id.error().message);
  {
    std::lock_guard lock(d.queue_mutex);
    d.queue.push_back({KioskInput::kResume, {}, *id});
  }
  d.queue_cv.notify_all();
  send_json(res, {{"accepted", "resume"}, {"session", *id}}, 202);
}

void post_mode(Daemon::Impl& d, const Request& req, Response& res) {
  auto want_tracking = parse_mode_request(req.body);
  if (!want_tracking) return send_error(res, 400, want_tracking.error().message);
  const std::string mode = *want_tracking ? "tracking" : "capture";
  bool tracking;
  {
    std::lock_guard lock(d.status_mutex);
    tracking = d.status.state == KioskState::kTracking;
  }
  if ((mode == "tracking") != tracking) {
    std::lock_guard lock(d.queue_mutex);
    d.queue.push_back({KioskInput::kMode, {}, 0});
  }
  d.queue_cv.notify_all();
  send_json(res, {{"accepted", mode}}, 202);
}

void get_qa_capture_picture(Daemon::Impl& d, const Request&, Response& res) {
  const std::string bmp = d.preview.capture_bmp();
  if (bmp.empty()) return send_error(res, 404, "no processed capture yet");
  res.set_header("Cache-Control", "no-store");
  res.set_content(bmp, "image/bmp");
}

void post_landmark_corrections(Daemon::Impl& d, const Request& req, Response& res) {
  auto id = id_param(req, 1);
  auto index = id_param(req, 2);
  if (!id || !index) return send_error(res, 400, "bad id");
  auto corrections = parse_landmark_corrections(req.body);
  if (!corrections) return send_error(res, 400, corrections.error().message);
  auto r = d.correct_landmarks(*id, static_cast<int>(*index), *corrections);
  if (!r) return send_error(res, 409, r.error().message);
  send_json(res, *r);
}

}  // namespace fb::http
