#include "storage/export/mesh_files.hpp"

#include <charconv>
#include <cstring>

#include "storage/durable_file.hpp"

namespace fb {

namespace {

void append_float(std::string& out, float v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  out.append(buf, r.ptr);
}

void append_uint(std::string& out, std::uint64_t v) {
  char buf[24];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  out.append(buf, r.ptr);
}

}  // namespace

std::string encode_obj(const MeshData& mesh, std::string_view comment, const ObjExtras* extras) {
  std::string out;
  out.reserve(mesh.positions.size() * 20 + mesh.triangles.size() * 14 + 64);
  if (!comment.empty()) {
    out += "# ";
    out += comment;
    out += "\n";
  }
  const ObjExtras none;
  const ObjExtras& x = extras != nullptr ? *extras : none;
  if (!x.mtllib.empty()) out += "mtllib " + x.mtllib + "\n";
  auto append_vec3 = [&](const char* tag, const std::vector<float>& values) {
    for (std::size_t i = 0; i + 2 < values.size(); i += 3) {
      out += tag;
      append_float(out, values[i]);
      out += ' ';
      append_float(out, values[i + 1]);
      out += ' ';
      append_float(out, values[i + 2]);
      out += '\n';
    }
  };
  append_vec3("v ", mesh.positions);
  const bool uvs = x.uvs != nullptr && x.uvs->fits(mesh.triangles);
  if (uvs) {
    for (std::size_t i = 0; i + 1 < x.uvs->uvs.size(); i += 2) {
      out += "vt ";
      append_float(out, x.uvs->uvs[i]);
      out += ' ';
      append_float(out, x.uvs->uvs[i + 1]);
      out += '\n';
    }
  }
  if (x.normals) append_vec3("vn ", vertex_normals(mesh.positions, mesh.triangles));
  if (!x.material.empty()) out += "usemtl " + x.material + "\n";
  for (std::size_t i = 0; i + 2 < mesh.triangles.size(); i += 3) {
    out += 'f';
    for (std::size_t k = i; k < i + 3; ++k) {
      const std::uint64_t v = mesh.triangles[k] + std::uint64_t{1};
      out += ' ';
      append_uint(out, v);
      if (uvs || x.normals) {
        out += '/';
        if (uvs) append_uint(out, x.uvs->triangle_uvs[k] + std::uint64_t{1});
        if (x.normals) {
          out += '/';
          append_uint(out, v);
        }
      }
    }
    out += '\n';
  }
  return out;
}

std::vector<std::uint8_t> encode_ply(const MeshData& mesh, std::string_view comment) {
  std::string header = "ply\nformat binary_little_endian 1.0\n";
  if (!comment.empty()) header += "comment " + std::string(comment) + "\n";
  header += "element vertex " + std::to_string(mesh.vertex_count()) +
            "\nproperty float x\nproperty float y\nproperty float z\n"
            "element face " +
            std::to_string(mesh.triangle_count()) +
            "\nproperty list uchar uint vertex_indices\nend_header\n";
  std::vector<std::uint8_t> out(header.begin(), header.end());
  const std::size_t vbytes = mesh.positions.size() * sizeof(float);
  const std::size_t start = out.size();
  out.resize(start + vbytes + static_cast<std::size_t>(mesh.triangle_count()) * 13);
  std::memcpy(out.data() + start, mesh.positions.data(), vbytes);
  std::uint8_t* p = out.data() + start + vbytes;
  for (std::size_t i = 0; i + 2 < mesh.triangles.size(); i += 3) {
    *p++ = 3;
    std::memcpy(p, &mesh.triangles[i], 12);
    p += 12;
  }
  return out;
}

Result<ObjReadResult> parse_obj(std::string_view text, const std::string& name) {
  ObjReadResult result;
  std::vector<long> polygon;
  std::size_t line_no = 0;
  std::size_t pos = 0;
  while (pos < text.size()) {
    std::size_t end = text.find('\n', pos);
    if (end == std::string_view::npos) end = text.size();
    std::string_view line = text.substr(pos, end - pos);
    pos = end + 1;
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    auto bad = [&](const char* what) {
      return fail(name + " line " + std::to_string(line_no) + ": " + what);
    };
    const auto skip_space = [&](std::size_t i) {
      while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
      return i;
    };
    if (line.size() >= 2 && line[0] == 'v' && (line[1] == ' ' || line[1] == '\t')) {
      std::size_t i = 2;
      for (int k = 0; k < 3; ++k) {
        i = skip_space(i);
        float v = 0;
        const auto r = std::from_chars(line.data() + i, line.data() + line.size(), v);
        if (r.ec != std::errc()) return bad("a vertex needs three numbers");
        result.mesh.positions.push_back(v);
        i = static_cast<std::size_t>(r.ptr - line.data());
      }
    } else if (line.size() >= 2 && line[0] == 'f' && (line[1] == ' ' || line[1] == '\t')) {
      polygon.clear();
      std::size_t i = skip_space(2);
      while (i < line.size()) {
        long index = 0;
        const auto r = std::from_chars(line.data() + i, line.data() + line.size(), index);
        if (r.ec != std::errc()) return bad("a face index is not a number");
        i = static_cast<std::size_t>(r.ptr - line.data());
        while (i < line.size() && line[i] != ' ' && line[i] != '\t') ++i;  // skip /vt/vn
        const long count = static_cast<long>(result.mesh.positions.size() / 3);
        const long resolved = index < 0 ? count + index : index - 1;
        if (index == 0 || resolved < 0 || resolved >= count) {
          return bad("a face refers to a vertex that does not exist (yet)");
        }
        polygon.push_back(resolved);
        i = skip_space(i);
      }
      if (polygon.size() < 3) return bad("a face needs at least three vertices");
      ++result.face_count;
      for (std::size_t k = 1; k + 1 < polygon.size(); ++k) {
        result.mesh.triangles.push_back(static_cast<std::uint32_t>(polygon[0]));
        result.mesh.triangles.push_back(static_cast<std::uint32_t>(polygon[k]));
        result.mesh.triangles.push_back(static_cast<std::uint32_t>(polygon[k + 1]));
      }
    }
  }
  if (result.mesh.positions.empty()) return fail(name + " has no vertices (not an OBJ mesh?)");
  return result;
}

Result<ObjReadResult> read_obj(const std::filesystem::path& path) {
  auto bytes = read_file_bytes(path);
  if (!bytes) return bytes.failure();
  return parse_obj(std::string_view(reinterpret_cast<const char*>(bytes->data()), bytes->size()),
                   path.string());
}

}  // namespace fb
