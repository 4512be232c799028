#include "storage/data_codec.hpp"

namespace fb::store_detail {

bool decode_fused_depth(std::span<const std::uint8_t> bytes, DepthImage& out) {
  ByteReader r(bytes);
  std::int32_t w = 0, h = 0;
  return r.magic(kDepthMagic) && r.get(w) && r.get(h) && read_image(r, w, h, out) && r.at_end();
}

bool decode_mesh(std::span<const std::uint8_t> bytes, MeshData& mesh) {
  ByteReader r(bytes);
  std::uint32_t nv = 0, nt = 0;
  if (!r.magic(kMeshMagic) || !r.get(nv) || !r.get(nt) ||
      !r.get_array(mesh.positions, std::size_t{3} * nv) ||
      !r.get_array(mesh.triangles, std::size_t{3} * nt) || !r.at_end())
    return false;
  // What add_mesh refuses to write must not come back either: readers index with these.
  return std::all_of(mesh.triangles.begin(), mesh.triangles.end(),
                     [nv](std::uint32_t t) { return t < nv; });
}

bool decode_rig(std::span<const std::uint8_t> bytes, RigData& rig) {
  ByteReader r(bytes);
  std::uint32_t nv = 0, nt = 0, ns = 0;
  if (!r.magic(kRigMagic) || !r.get(nv) || !r.get(nt) || !r.get(ns) ||
      ns != rig.shape_names.size() || !r.get_array(rig.neutral, std::size_t{3} * nv))
    return false;
  rig.shapes.resize(ns);
  for (auto& s : rig.shapes) {
    if (!r.get_array(s, std::size_t{3} * nv)) return false;
  }
  if (!r.get_array(rig.triangles, std::size_t{3} * nt) || !r.at_end()) return false;
  return std::all_of(rig.triangles.begin(), rig.triangles.end(),
                     [nv](std::uint32_t t) { return t < nv; });
}

bool decode_take(std::span<const std::uint8_t> bytes, const std::string& time_source,
                 TakeData& take) {
  ByteReader r(bytes);
  std::uint32_t frames = 0, stride = 0;
  const auto want = static_cast<std::uint32_t>(take.info.stride());
  if (time_source == "file") {
    return r.magic(kTakeMagic) && r.get(frames) && r.get(stride) && stride == want &&
           static_cast<std::int64_t>(frames) == take.info.frame_count &&
           r.get_array(take.times_s, frames) &&
           r.get_array(take.values, std::size_t{frames} * stride) && r.at_end();
  }
  const bool last_column = time_source == "last_column";
  std::vector<float> stored;
  if (!r.magic(kTakeMagicV1) || !r.get(frames) || !r.get(stride) ||
      stride != want + (last_column ? 1 : 0) ||
      static_cast<std::int64_t>(frames) != take.info.frame_count ||
      !r.get_array(stored, std::size_t{frames} * stride) || !r.at_end())
    return false;
  take.times_s.resize(frames);
  take.values.clear();
  take.values.reserve(std::size_t{frames} * want);
  for (std::uint32_t f = 0; f < frames; ++f) {
    const float* row = stored.data() + std::size_t{f} * stride;
    take.values.insert(take.values.end(), row, row + want);
    take.times_s[f] = last_column ? row[want] : f / take.info.fps;
  }
  return true;
}

}  // namespace fb::store_detail
