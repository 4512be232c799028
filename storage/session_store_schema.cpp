// The session store's schema: one SQL script per version step. Never edit a released step: add
// a new one, so every store upgrades along the same path.
#include "storage/session_store_impl.hpp"

namespace fb::store_detail {

// v5: sessions and subjects imported from booths (`facebooth sync`) keep the booth's id and
// their id there, so several booths' ids never collide in one host store.
constexpr const char* kV5ImportedFromBooths = R"sql(
ALTER TABLE subjects ADD COLUMN origin_booth TEXT;
ALTER TABLE subjects ADD COLUMN origin_id INTEGER;
ALTER TABLE sessions ADD COLUMN origin_booth TEXT;
ALTER TABLE sessions ADD COLUMN origin_id INTEGER;
CREATE UNIQUE INDEX subjects_by_origin ON subjects(origin_booth, origin_id)
  WHERE origin_booth IS NOT NULL;
CREATE UNIQUE INDEX sessions_by_origin ON sessions(origin_booth, origin_id)
  WHERE origin_booth IS NOT NULL;
)sql";

// v6: wrinkle detail (`facebooth wrinkles`, issue 40): per capture of a session, a
// displacement map (mm, float32 file) and a tangent-space normal map (PNG) in the face model's UV
// layout, tied to the rig that served the session when it was built.
constexpr const char* kV6WrinkleDetail = R"sql(
CREATE TABLE wrinkle_details(
  id INTEGER PRIMARY KEY,
  session_id INTEGER NOT NULL REFERENCES sessions(id),
  capture_idx INTEGER NOT NULL,
  rig_id INTEGER REFERENCES rigs(id),
  width INTEGER NOT NULL CHECK(width > 0),
  height INTEGER NOT NULL CHECK(height > 0),
  params_json TEXT NOT NULL DEFAULT '{}',
  displacement_file_id INTEGER NOT NULL REFERENCES files(id),
  normal_file_id INTEGER NOT NULL REFERENCES files(id),
  created_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now')));
CREATE INDEX wrinkle_details_by_session ON wrinkle_details(session_id);
)sql";

// v7: a rig says which captures of its session have wrinkle detail (issue 40 item 5: the
// booth's tracking streams one map weight per such capture), as [{"capture":I,"expression":E}].
constexpr const char* kV7RigDetailCaptures = R"sql(
ALTER TABLE rigs ADD COLUMN detail_json TEXT NOT NULL DEFAULT '[]';
)sql";

// Each migration moves the schema from version (index) to version (index + 1). Never edit a
// released migration: add a new one, so every store upgrades along the same path.
const std::vector<std::string>& migrations() {
  static const std::vector<std::string> list = {
      // v1: capture sessions and their products.
      R"sql(
CREATE TABLE files(
  id INTEGER PRIMARY KEY,
  relpath TEXT NOT NULL UNIQUE,        -- relative to the store root
  bytes INTEGER NOT NULL,
  sha256 TEXT NOT NULL,
  created_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now')));
CREATE TABLE subjects(
  id INTEGER PRIMARY KEY,
  name TEXT NOT NULL,
  created_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now')));
CREATE TABLE sessions(
  id INTEGER PRIMARY KEY,
  subject_id INTEGER NOT NULL REFERENCES subjects(id),
  state TEXT NOT NULL DEFAULT 'open' CHECK(state IN ('open','complete')),
  folder TEXT NOT NULL,                -- relative to the store root
  created_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now')));
CREATE TABLE captures(
  id INTEGER PRIMARY KEY,
  session_id INTEGER NOT NULL REFERENCES sessions(id),
  idx INTEGER NOT NULL,
  expression TEXT NOT NULL,
  state TEXT NOT NULL DEFAULT 'pending'
    CHECK(state IN ('pending','capturing','rejected','done')),
  attempts INTEGER NOT NULL DEFAULT 0,
  qa_json TEXT NOT NULL DEFAULT '{}',
  frame_count INTEGER NOT NULL DEFAULT 0,
  frames_file_id INTEGER REFERENCES files(id),
  fused_file_id INTEGER REFERENCES files(id),
  completed_at TEXT,
  UNIQUE(session_id, idx),
  CHECK(state <> 'done' OR frames_file_id IS NOT NULL));
CREATE TABLE frames(
  id INTEGER PRIMARY KEY,
  capture_id INTEGER NOT NULL REFERENCES captures(id),
  seq INTEGER NOT NULL,
  depth_host_time_s REAL NOT NULL,
  color_host_time_s REAL NOT NULL,
  depth_device_ts INTEGER NOT NULL,
  color_device_ts INTEGER NOT NULL,
  file_id INTEGER NOT NULL REFERENCES files(id),
  offset INTEGER NOT NULL,             -- byte offset of the frame record in the file
  UNIQUE(capture_id, seq));
CREATE TABLE landmarks(
  id INTEGER PRIMARY KEY,
  capture_id INTEGER NOT NULL REFERENCES captures(id),
  source TEXT NOT NULL CHECK(source IN ('automatic','operator')),
  points_json TEXT NOT NULL,
  created_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now')),
  UNIQUE(capture_id, source));
CREATE TABLE meshes(
  id INTEGER PRIMARY KEY,
  session_id INTEGER NOT NULL REFERENCES sessions(id),
  capture_idx INTEGER,
  role TEXT NOT NULL CHECK(role IN ('fitted','neutral','scan')),
  name TEXT NOT NULL,
  vertex_count INTEGER NOT NULL,
  triangle_count INTEGER NOT NULL,
  file_id INTEGER NOT NULL REFERENCES files(id),
  created_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now')));
CREATE TABLE rigs(
  id INTEGER PRIMARY KEY,
  subject_id INTEGER NOT NULL REFERENCES subjects(id),
  session_id INTEGER REFERENCES sessions(id),
  shape_names_json TEXT NOT NULL,
  vertex_count INTEGER NOT NULL,
  triangle_count INTEGER NOT NULL,
  file_id INTEGER NOT NULL REFERENCES files(id),
  created_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now')));
CREATE TABLE models(
  id INTEGER PRIMARY KEY,
  kind TEXT NOT NULL,
  params_json TEXT NOT NULL DEFAULT '{}',
  file_id INTEGER NOT NULL REFERENCES files(id),
  created_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now')));
CREATE INDEX captures_by_session ON captures(session_id, idx);
CREATE INDEX meshes_by_session ON meshes(session_id);
)sql",
      // v2: tracking takes (the standalone tracking box records them per subject).
      R"sql(
CREATE TABLE takes(
  id INTEGER PRIMARY KEY,
  subject_id INTEGER NOT NULL REFERENCES subjects(id),
  session_id INTEGER REFERENCES sessions(id),
  fps REAL NOT NULL CHECK(fps > 0),
  shape_names_json TEXT NOT NULL,
  frame_count INTEGER NOT NULL,
  file_id INTEGER NOT NULL REFERENCES files(id),
  created_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now')));
)sql",
      // v3: takes keep each frame's time (TakeWriter, FBTAK002 files). time_source says where
      // an older take's times are: 'frame_rate' (frame / fps: the device's takes) or
      // 'last_column' (the host appended a "timestamp_s" pseudo-shape; its name is dropped here,
      // the column is read from the FBTAK001 file).
      R"sql(
ALTER TABLE takes ADD COLUMN time_source TEXT NOT NULL DEFAULT 'frame_rate'
  CHECK(time_source IN ('frame_rate','last_column','file'));
UPDATE takes SET time_source='last_column',
  shape_names_json=json_remove(shape_names_json, '$[#-1]')
  WHERE )sql" +
          std::string(kHostTimestampColumn) + ";",
      // v4: the subject's texture atlases (per session, and per capture for FaceWarehouse's
      // per-expression textures), and the unit calibration a session's frames were taken with
      // (device.json text), which the host needs to map depth to colour.
      R"sql(
ALTER TABLE sessions ADD COLUMN calibration_json TEXT;
CREATE TABLE textures(
  id INTEGER PRIMARY KEY,
  session_id INTEGER NOT NULL REFERENCES sessions(id),
  capture_idx INTEGER,
  width INTEGER NOT NULL CHECK(width > 0),
  height INTEGER NOT NULL CHECK(height > 0),
  params_json TEXT NOT NULL DEFAULT '{}',
  file_id INTEGER NOT NULL REFERENCES files(id),
  created_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now')));
CREATE INDEX textures_by_session ON textures(session_id);
)sql",
      kV5ImportedFromBooths,
      kV6WrinkleDetail,
      kV7RigDetailCaptures,
  };
  return list;
}

}  // namespace fb::store_detail
