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
  return impl_->insert_with_files(
      {*file},
      "INSERT INTO textures(session_id, capture_idx, width, height, "
      "params_json, file_id) VALUES(?,?,?,?,?,?)",
      [&](sql::Statement& stmt, const std::vector<std::int64_t>& ids) {
        stmt.bind_all(session,
                      capture_index ? std::optional<std::int64_t>(*capture_index) : std::nullopt,
                      width, height, params_json, ids[0]);
      });
}

Result<std::vector<TextureInfo>> SessionStore::textures(SessionId session) const {
  if (impl_->schema_version < 4) return std::vector<TextureInfo>{};
  return impl_->rows<TextureInfo>(
      "SELECT t.id, t.session_id, t.capture_idx, t.width, t.height, t.params_json, f.bytes, "
      "t.created_at FROM textures t JOIN files f ON f.id=t.file_id WHERE t.session_id=? ORDER BY "
      "t.id",
      session, [](sql::Statement& stmt) {
        TextureInfo t;
        t.id = stmt.int64(0);
        t.session = stmt.int64(1);
        if (!stmt.is_null(2)) t.capture_index = stmt.int32(2);
        t.width = stmt.int32(3);
        t.height = stmt.int32(4);
        t.params_json = stmt.text(5);
        t.bytes = stmt.int64(6);
        t.created_at = stmt.text(7);
        return t;
      });
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
