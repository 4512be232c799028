// SessionStore: the subject's texture atlases (PNG files in the session's folder, rows in
// `textures`, schema v4).
#include <algorithm>

#include "storage/session_store_impl.hpp"

namespace fb {

Result<TextureId> SessionStore::add_texture(SessionId session, std::optional<int> capture_index,
                                            int width, int height,
                                            std::span<const std::uint8_t> png,
                                            const std::string& params_json) {
  if (auto r = impl_->require_writer(); !r) return r.failure();
  if (impl_->schema_version < 4)
    return fail("this store's schema is too old for textures; open it with a writer to migrate");
  static constexpr std::uint8_t kPngMagic[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (width <= 0 || height <= 0 || png.size() < 8 ||
      !std::equal(kPngMagic, kPngMagic + 8, png.begin()))
    return fail("a texture must be a PNG image with a size");
  auto folder = impl_->session_folder(session);
  if (!folder) return folder.failure();
  auto file = impl_->write_data_file(*folder, "texture.png", png);
  if (!file) return file.failure();
  sqlite3* db = impl_->db.get();
  auto insert = [&]() -> Result<TextureId> {
    auto tx = sql::Transaction::begin(db);
    if (!tx) return tx.failure();
    auto id = impl_->insert_file_row(*file);
    if (!id) return id.failure();
    auto stmt = sql::prepare(db,
                             "INSERT INTO textures(session_id, capture_idx, width, height, "
                             "params_json, file_id) VALUES(?,?,?,?,?,?)");
    if (!stmt) return stmt.failure();
    stmt->bind_all(session,
                   capture_index ? std::optional<std::int64_t>(*capture_index) : std::nullopt,
                   width, height, params_json, *id);
    if (auto r = stmt->run(); !r) return r.failure();
    const TextureId texture_id = sqlite3_last_insert_rowid(db);
    if (auto r = tx->commit(); !r) return r.failure();
    return texture_id;
  };
  auto id = insert();
  if (!id) impl_->discard({*file});
  return id;
}

Result<std::vector<TextureInfo>> SessionStore::textures(SessionId session) const {
  std::vector<TextureInfo> out;
  if (impl_->schema_version < 4) return out;
  auto stmt = sql::prepare(impl_->db.get(),
                           "SELECT t.id, t.session_id, t.capture_idx, t.width, t.height, "
                           "t.params_json, f.bytes, t.created_at FROM textures t JOIN files f ON "
                           "f.id=t.file_id WHERE t.session_id=? ORDER BY t.id");
  if (!stmt) return stmt.failure();
  stmt->bind(1, session);
  for (;;) {
    auto row = stmt->step();
    if (!row) return row.failure();
    if (!*row) break;
    TextureInfo t;
    t.id = stmt->int64(0);
    t.session = stmt->int64(1);
    if (!stmt->is_null(2)) t.capture_index = stmt->int32(2);
    t.width = stmt->int32(3);
    t.height = stmt->int32(4);
    t.params_json = stmt->text(5);
    t.bytes = stmt->int64(6);
    t.created_at = stmt->text(7);
    out.push_back(std::move(t));
  }
  return out;
}

Result<std::vector<std::uint8_t>> SessionStore::read_texture(TextureId id) const {
  if (impl_->schema_version < 4) return fail("this store has no textures (schema before v4)");
  auto file = sql::query_int(impl_->db.get(),
                             "SELECT file_id FROM textures WHERE id=" + std::to_string(id));
  if (!file) return file.failure();
  if (*file == 0) return fail("there is no texture " + std::to_string(id) + " in this store");
  return impl_->load_file(*file);
}

}  // namespace fb
