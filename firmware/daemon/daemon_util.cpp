// Small encoders the API serves: BMP pictures, ustar archives, and the guide pictures.
#include <fstream>
#include <sstream>

#include "firmware/daemon/daemon_impl.hpp"

namespace fb {

std::string encode_bmp(const ColorImage& image) {
  const int w = image.width, h = image.height;
  const int row = (w * 3 + 3) & ~3;
  const std::uint32_t data_size = static_cast<std::uint32_t>(row * h);
  std::string out(54 + data_size, '\0');
  auto put32 = [&](std::size_t at, std::uint32_t v) {
    for (int i = 0; i < 4; ++i) out[at + i] = static_cast<char>((v >> (8 * i)) & 0xff);
  };
  auto put16 = [&](std::size_t at, std::uint16_t v) {
    out[at] = static_cast<char>(v & 0xff);
    out[at + 1] = static_cast<char>(v >> 8);
  };
  out[0] = 'B';
  out[1] = 'M';
  put32(2, 54 + data_size);
  put32(10, 54);
  put32(14, 40);
  put32(18, static_cast<std::uint32_t>(w));
  put32(22, static_cast<std::uint32_t>(h));
  put16(26, 1);
  put16(28, 24);
  put32(34, data_size);
  for (int y = 0; y < h; ++y) {
    char* dst = out.data() + 54 + static_cast<std::size_t>(h - 1 - y) * row;  // bottom-up
    for (int x = 0; x < w; ++x) {
      const Rgb8& p = image.at(x, y);
      dst[3 * x] = static_cast<char>(p.b);
      dst[3 * x + 1] = static_cast<char>(p.g);
      dst[3 * x + 2] = static_cast<char>(p.r);
    }
  }
  return out;
}

Result<std::string> tar_folder(const std::filesystem::path& folder, const std::string& prefix) {
  std::vector<std::filesystem::path> files;
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(folder, ec))
    if (entry.is_regular_file() && !entry.is_symlink()) files.push_back(entry.path());
  if (ec) return fail("cannot list '" + folder.string() + "': " + ec.message());
  std::sort(files.begin(), files.end());
  std::string out;
  for (const auto& file : files) {
    std::ifstream in(file, std::ios::binary);
    if (!in) return fail("cannot read '" + file.string() + "'");
    std::ostringstream data;
    data << in.rdbuf();
    const std::string bytes = data.str();
    const std::string name = prefix + "/" + file.filename().string();
    if (name.size() > 99) return fail("file name too long for the archive: " + name);
    char header[512] = {};
    std::snprintf(header, 100, "%s", name.c_str());
    std::snprintf(header + 100, 8, "%07o", 0644);
    std::snprintf(header + 108, 8, "%07o", 0);
    std::snprintf(header + 116, 8, "%07o", 0);
    std::snprintf(header + 124, 12, "%011llo", static_cast<unsigned long long>(bytes.size()));
    std::snprintf(header + 136, 12, "%011llo", static_cast<unsigned long long>(std::time(nullptr)));
    std::memset(header + 148, ' ', 8);
    header[156] = '0';
    std::memcpy(header + 257, "ustar", 6);
    std::memcpy(header + 263, "00", 2);
    unsigned sum = 0;
    for (unsigned char c : header) sum += c;
    std::snprintf(header + 148, 8, "%06o", sum);
    header[155] = ' ';
    out.append(header, 512);
    out += bytes;
    out.append((512 - bytes.size() % 512) % 512, '\0');
  }
  out.append(1024, '\0');
  return out;
}

Result<std::string> Daemon::Impl::guide_picture(int index) {
  std::lock_guard lock(preview_mutex);
  if (auto it = guide_bmp_cache.find(index); it != guide_bmp_cache.end()) return it->second;
  const std::string uri =
      "synthetic:seed=0,identity=neutral,motion=static,frames=1,noise=off,expr=" +
      guide[static_cast<std::size_t>(index)].synthetic_expr;
  auto camera = open_camera(uri);
  if (!camera) return camera.failure();
  if (auto ok = (*camera)->start(); !ok) return ok.failure();
  RgbdFrame frame;
  auto got = (*camera)->next_frame(frame, std::chrono::milliseconds(1000));
  if (!got) return got.failure();
  if (*got != FrameStatus::kFrame) return fail("the guide renderer produced no frame");
  // Crop the face box out of the colour image.
  const FaceBox box = default_face_box(frame.color.width, frame.color.height)
                          .clipped(frame.color.width, frame.color.height);
  ColorImage crop;
  crop.resize(box.width, box.height);
  for (int y = 0; y < box.height; ++y)
    for (int x = 0; x < box.width; ++x) crop.at(x, y) = frame.color.at(box.x + x, box.y + y);
  auto bmp = encode_bmp(crop);
  guide_bmp_cache[index] = bmp;
  return bmp;
}

}  // namespace fb
