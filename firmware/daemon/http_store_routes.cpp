// The HTTP API's store routes: the stored sessions and captures, a session's export (a folder,
// or streamed as ustar), and the host tool's offload (the sessions ready for rigging, a rig
// uploaded back). Only numeric ids from the path reach the store.
#include <algorithm>
#include <ctime>
#include <fstream>

#include "firmware/daemon/http_requests.hpp"
#include "firmware/daemon/http_routes.hpp"
#include "storage/export/facewarehouse.hpp"
#include "storage/sha256.hpp"

namespace fb::http {
namespace {

using nlohmann::json;

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

json detail_captures_json(const std::vector<RigDetailCapture>& detail) {
  json list = json::array();
  for (const auto& c : detail)
    list.push_back({{"capture", c.capture_index}, {"expression", c.expression}});
  return list;
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

void get_sessions(Daemon::Impl& d, const Request&, Response& res) {
  std::lock_guard lock(d.records_mutex);
  auto all = d.records->sessions();
  if (!all) return send_error(res, 500, all.error().message);
  json list = json::array();
  for (const auto& s : *all) list.push_back(session_json(s));
  send_json(
      res,
      {{"store", d.records->backend()}, {"root", d.records->root().string()}, {"sessions", list}});
}

void get_session(Daemon::Impl& d, const Request& req, Response& res) {
  auto id = id_param(req, 1);
  if (!id) return send_error(res, 400, id.error().message);
  std::lock_guard lock(d.records_mutex);
  auto s = d.records->session(*id);
  if (!s) return send_error(res, 404, s.error().message);
  auto caps = d.records->captures(*id);
  if (!caps) return send_error(res, 500, caps.error().message);
  json j = session_json(*s);
  j["captures"] = json::array();
  for (const auto& c : *caps) j["captures"].push_back(capture_json(c));
  send_json(res, j);
}

void get_session_captures(Daemon::Impl& d, const Request& req, Response& res) {
  auto id = id_param(req, 1);
  if (!id) return send_error(res, 400, id.error().message);
  std::lock_guard lock(d.records_mutex);
  auto caps = d.records->captures(*id);
  if (!caps) return send_error(res, 404, caps.error().message);
  json list = json::array();
  for (const auto& c : *caps) list.push_back(capture_json(c));
  send_json(res, {{"session", *id}, {"captures", list}});
}

// The sessions ready for rigging: complete, every capture fitted.
void get_offload_ready(Daemon::Impl& d, const Request&, Response& res) {
  std::lock_guard lock(d.records_mutex);
  auto all = d.records->sessions();
  if (!all) return send_error(res, 500, all.error().message);
  json list = json::array();
  for (const auto& s : *all) {
    if (!s.complete) continue;
    auto info = d.records->offload_info(s.id);
    if (!info) return send_error(res, 500, info.error().message);
    json j = session_json(s);
    j["fitted_captures"] = info->fitted_captures;
    j["ready_for_rigging"] = info->fitted_captures == s.capture_count;
    j["rigs"] = info->rigs;
    // The newest rig from this session's detail captures: the host uploads again when it has
    // built wrinkle detail since.
    j["rig_detail_captures"] = detail_captures_json(info->rig_detail_captures);
    j["bundle"] = "/api/offload/sessions/" + std::to_string(s.id) + "/bundle.tar";
    j["rig_upload"] = "/api/offload/sessions/" + std::to_string(s.id) + "/rig";
    list.push_back(j);
  }
  send_json(res, {{"booth_id", d.booth_id}, {"sessions", list}});
}

// The session's export (made again now), streamed as a ustar archive.
void get_session_bundle(Daemon::Impl& d, const Request& req, Response& res) {
  auto id = id_param(req, 1);
  if (!id) return send_error(res, 400, id.error().message);
  Result<std::filesystem::path> out = fail("");
  std::string created_at;
  {
    std::lock_guard lock(d.records_mutex);
    out = d.records->export_session(*id, d.config.storage.data_dir / "exports",
                                    [&d] { return d.stopping.load(); });
    if (auto s = d.records->session(*id)) created_at = s->created_at;
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
}

// The rig's detail captures against the session's captures and the booth's guide: each a
// capture of the session, with the expression the booth recorded, a guide expression with a
// recipe, not the neutral. The message says what is wrong and what to list instead.
Result<void> check_detail_captures(Daemon::Impl& d, std::int64_t session,
                                   const std::vector<RigDetailCapture>& detail) {
  if (detail.empty()) return success();
  auto caps = d.records->captures(session);
  if (!caps) return caps.failure();
  for (const auto& c : detail) {
    const auto cap = std::find_if(caps->begin(), caps->end(), [&](const RecordCapture& r) {
      return r.index == c.capture_index;
    });
    if (cap == caps->end())
      return fail("detail= names capture " + std::to_string(c.capture_index) + ", but session " +
                  std::to_string(session) + " has captures 0.." +
                  std::to_string(static_cast<int>(caps->size()) - 1) +
                  "; list the booth's capture indices of the captures with wrinkle detail");
    if (cap->expression != c.expression)
      return fail("detail= names capture " + std::to_string(c.capture_index) + " '" + c.expression +
                  "', but this booth recorded it as '" + cap->expression +
                  "'; list each capture with the expression the booth recorded");
  }
  auto recipes = detail_capture_recipes(detail, d.guide, d.fitter->model());
  if (!recipes) return fail("detail=: " + recipes.error().message);
  return success();
}

// A rig from the host: FaceWarehouse's shape.bs (int32 shapes, vertices, faces; float32
// xyz of the neutral then of each shape) in the face model's topology. Optional query
// `names=a,b,...` names the shapes (default: the model's expression names in order); optional
// `detail=CAPTURE:EXPRESSION,...` lists the session's captures with wrinkle detail (the
// tracking mode streams their map weights).
void post_rig_upload(Daemon::Impl& d, const Request& req, Response& res) {
  auto id = id_param(req, 1);
  if (!id) return send_error(res, 400, id.error().message);
  if (!d.fitter) return send_error(res, 409, "rig upload needs the face model: " + d.fitter_error);
  const FaceModel& model = d.fitter->model();
  auto rig = decode_shape_bs(std::span<const std::uint8_t>(
      reinterpret_cast<const std::uint8_t*>(req.body.data()), req.body.size()));
  if (!rig) return send_error(res, 400, "not a FaceWarehouse shape.bs: " + rig.error().message);
  const auto names = req.has_param("names")
                         ? std::optional<std::string>(req.get_param_value("names"))
                         : std::nullopt;
  if (auto ok = check_rig_upload(*rig, model.vertex_count, names, model.expression_names); !ok)
    return send_error(res, 422, ok.error().message);
  rig->triangles = model.triangles;
  if (req.has_param("detail")) {
    auto detail = parse_rig_detail_param(req.get_param_value("detail"));
    if (!detail) return send_error(res, 400, detail.error().message);
    rig->detail_captures = std::move(*detail);
  }
  std::lock_guard lock(d.records_mutex);
  auto s = d.records->session(*id);
  if (!s) return send_error(res, 404, s.error().message);
  if (!s->complete)
    return send_error(res, 409, "session " + std::to_string(*id) + " is not complete");
  if (auto ok = check_detail_captures(d, *id, rig->detail_captures); !ok)
    return send_error(res, 422, ok.error().message);
  auto rid = d.records->add_rig(*id, *rig);
  if (!rid) return send_error(res, 500, rid.error().message);
  send_json(res,
            {{"session", *id},
             {"rig", *rid},
             {"shapes", rig->shape_count()},
             {"vertices", rig->vertex_count()},
             {"detail_captures", detail_captures_json(rig->detail_captures)}},
            201);
}

void post_session_export(Daemon::Impl& d, const Request& req, Response& res) {
  auto id = id_param(req, 1);
  if (!id) return send_error(res, 400, id.error().message);
  std::lock_guard lock(d.records_mutex);
  auto out = d.records->export_session(*id, d.config.storage.data_dir / "exports",
                                       [&d] { return d.stopping.load(); });
  if (!out) return send_error(res, 404, out.error().message);
  send_json(res, {{"session", *id},
                  {"folder", out->string()},
                  {"download", "/api/sessions/" + std::to_string(*id) + "/export.tar"}});
}

}  // namespace fb::http
