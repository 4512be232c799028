// SessionStore: wrinkle detail maps (schema v6, `facebooth wrinkles`). Each row names two data
// files in the session's folder: the displacement map (FBDSP001: magic, width, height as
// little-endian int32, then width * height float32 mm) and the normal map (PNG).
#include <algorithm>
#include <cmath>
#include <cstring>

#include "storage/session_store_impl.hpp"

namespace fb {

namespace {

constexpr char kDisplacementMagic[8] = {'F', 'B', 'D', 'S', 'P', '0', '0', '1'};

std::vector<std::uint8_t> encode_displacement(const WrinkleDetailData& d) {
  std::vector<std::uint8_t> out(16 + 4 * d.displacement_mm.size());
  std::memcpy(out.data(), kDisplacementMagic, 8);
  const std::int32_t size[2] = {d.width, d.height};
  std::memcpy(out.data() + 8, size, 8);  // little-endian hosts only, like the other codecs
  std::memcpy(out.data() + 16, d.displacement_mm.data(), 4 * d.displacement_mm.size());
  return out;
}

Result<void> decode_displacement(const std::vector<std::uint8_t>& bytes, WrinkleDetailData& d) {
  if (bytes.size() < 16 || std::memcmp(bytes.data(), kDisplacementMagic, 8) != 0)
    return fail("a stored displacement map is not an FBDSP001 file");
  std::int32_t size[2];
  std::memcpy(size, bytes.data() + 8, 8);
  const std::size_t n = static_cast<std::size_t>(std::max(0, size[0])) *
                        static_cast<std::size_t>(std::max(0, size[1]));
  if (size[0] <= 0 || size[1] <= 0 || bytes.size() != 16 + 4 * n)
    return fail("a stored displacement map has a size that does not match its data");
  d.width = size[0];
  d.height = size[1];
  d.displacement_mm.resize(n);
  std::memcpy(d.displacement_mm.data(), bytes.data() + 16, 4 * n);
  return success();
}

}  // namespace

Result<WrinkleDetailId> SessionStore::add_wrinkle_detail(SessionId session, int capture_index,
                                                         std::optional<RigId> rig,
                                                         const WrinkleDetailData& detail,
                                                         const std::string& params_json) {
  if (auto r = impl_->require_writer(); !r) return r.failure();
  if (impl_->schema_version < 6)
    return fail("this store's schema is too old for wrinkle detail; open it with a writer");
  static constexpr std::uint8_t kPngMagic[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (detail.width <= 0 || detail.height <= 0 ||
      detail.displacement_mm.size() !=
          static_cast<std::size_t>(detail.width) * static_cast<std::size_t>(detail.height) ||
      detail.normal_png.size() < 8 ||
      !std::equal(kPngMagic, kPngMagic + 8, detail.normal_png.begin()))
    return fail("wrinkle detail needs a displacement map of its size and a PNG normal map");
  if (!std::all_of(detail.displacement_mm.begin(), detail.displacement_mm.end(),
                   [](float v) { return std::isfinite(v); }))
    return fail("a wrinkle displacement map holds a non-finite height; nothing was stored");
  auto folder = impl_->session_folder(session);
  if (!folder) return folder.failure();
  auto disp =
      impl_->write_data_file(*folder, "wrinkle_displacement.fbdsp", encode_displacement(detail));
  if (!disp) return disp.failure();
  auto normal = impl_->write_data_file(*folder, "wrinkle_normal.png", detail.normal_png);
  if (!normal) {
    impl_->discard({*disp});
    return normal.failure();
  }
  return impl_->insert_with_files(
      {*disp, *normal},
      "INSERT INTO wrinkle_details(session_id, capture_idx, rig_id, width, "
      "height, params_json, displacement_file_id, normal_file_id) "
      "VALUES(?,?,?,?,?,?,?,?)",
      [&](sql::Statement& stmt, const std::vector<std::int64_t>& ids) {
        stmt.bind_all(session, capture_index, rig, detail.width, detail.height, params_json, ids[0],
                      ids[1]);
      });
}

Result<std::vector<WrinkleDetailInfo>> SessionStore::wrinkle_details(SessionId session) const {
  if (impl_->schema_version < 6) return std::vector<WrinkleDetailInfo>{};
  return impl_->rows<WrinkleDetailInfo>(
      "SELECT id, session_id, capture_idx, rig_id, width, height, params_json, created_at FROM "
      "wrinkle_details WHERE session_id=? ORDER BY id",
      session, [](sql::Statement& stmt) {
        WrinkleDetailInfo w;
        w.id = stmt.int64(0);
        w.session = stmt.int64(1);
        w.capture_index = stmt.int32(2);
        if (!stmt.is_null(3)) w.rig = stmt.int64(3);
        w.width = stmt.int32(4);
        w.height = stmt.int32(5);
        w.params_json = stmt.text(6);
        w.created_at = stmt.text(7);
        return w;
      });
}

Result<WrinkleDetailData> SessionStore::read_wrinkle_detail(WrinkleDetailId id) const {
  if (impl_->schema_version < 6) return fail("this store has no wrinkle detail (schema before v6)");
  auto stmt = sql::prepare(impl_->db.get(),
                           "SELECT displacement_file_id, normal_file_id FROM wrinkle_details "
                           "WHERE id=?");
  if (!stmt) return stmt.failure();
  stmt->bind(1, id);
  auto row = stmt->step();
  if (!row) return row.failure();
  if (!*row) return fail("there is no wrinkle detail " + std::to_string(id) + " in this store");
  const std::int64_t disp_file = stmt->int64(0), normal_file = stmt->int64(1);
  auto disp = impl_->load_file(disp_file);
  if (!disp) return disp.failure();
  WrinkleDetailData out;
  if (auto r = decode_displacement(*disp, out); !r) return r.failure();
  auto normal = impl_->load_file(normal_file);
  if (!normal) return normal.failure();
  out.normal_png = std::move(*normal);
  return out;
}

}  // namespace fb
