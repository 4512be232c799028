// Small encoders the API serves: BMP pictures, ustar archives, the guide pictures, the preview.
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <fstream>
#include <sstream>

#include "firmware/daemon/daemon_impl.hpp"
#include "storage/durable_file.hpp"

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

namespace {

std::string tar_header(const std::string& name, std::uint64_t size, std::int64_t mtime) {
  char header[512] = {};
  std::snprintf(header, 100, "%s", name.c_str());
  std::snprintf(header + 100, 8, "%07o", 0644);
  std::snprintf(header + 108, 8, "%07o", 0);
  std::snprintf(header + 116, 8, "%07o", 0);
  std::snprintf(header + 124, 12, "%011llo", static_cast<unsigned long long>(size));
  std::snprintf(header + 136, 12, "%011llo",
                static_cast<unsigned long long>(mtime > 0 ? mtime : std::time(nullptr)));
  std::memset(header + 148, ' ', 8);
  header[156] = '0';
  std::memcpy(header + 257, "ustar", 6);
  std::memcpy(header + 263, "00", 2);
  unsigned sum = 0;
  for (unsigned char c : header) sum += c;
  std::snprintf(header + 148, 8, "%06o", sum);
  header[155] = ' ';
  return std::string(header, 512);
}

}  // namespace

Result<TarStream> TarStream::open(const std::filesystem::path& folder, const std::string& prefix,
                                  std::int64_t mtime) {
  namespace fs = std::filesystem;
  TarStream t;
  std::error_code ec;
  std::vector<fs::path> files;
  // Regular files only; symlinks are never followed (the folder is the daemon's own export).
  for (fs::recursive_directory_iterator it(folder, fs::directory_options::none, ec), end;
       !ec && it != end; it.increment(ec))
    if (it->is_regular_file() && !it->is_symlink()) files.push_back(it->path());
  if (ec) return fail("cannot list '" + folder.string() + "': " + ec.message());
  std::sort(files.begin(), files.end());
  for (const auto& file : files) {
    Entry e;
    e.path = file;
    e.size = fs::file_size(file, ec);
    if (ec) return fail("cannot stat '" + file.string() + "'");
    const std::string name = prefix + "/" + fs::relative(file, folder).generic_string();
    if (name.size() > 99) return fail("file name too long for the archive: " + name);
    e.header = tar_header(name, e.size, mtime);
    e.offset = t.total_;
    t.total_ += 512 + e.size + (512 - e.size % 512) % 512;
    t.entries_.push_back(std::move(e));
  }
  t.total_ += 1024;
  return t;
}

Result<std::string> TarStream::read(std::uint64_t offset, std::uint64_t length) const {
  std::string out;
  out.reserve(static_cast<std::size_t>(length));
  while (length > 0 && offset < total_) {
    // The entry containing `offset` (or the end-of-archive zeros).
    auto it = std::upper_bound(entries_.begin(), entries_.end(), offset,
                               [](std::uint64_t o, const Entry& e) { return o < e.offset; });
    if (it == entries_.begin()) return fail("bad archive offset");
    const Entry& e = *std::prev(it);
    const std::uint64_t padded = 512 + e.size + (512 - e.size % 512) % 512;
    std::uint64_t in_entry = offset - e.offset;
    std::uint64_t n = 0;
    if (in_entry >= padded) {  // past the last entry: the two zero blocks
      n = std::min<std::uint64_t>(length, total_ - offset);
      out.append(static_cast<std::size_t>(n), '\0');
    } else if (in_entry < 512) {
      n = std::min<std::uint64_t>(length, 512 - in_entry);
      out.append(e.header, static_cast<std::size_t>(in_entry), static_cast<std::size_t>(n));
    } else if (in_entry < 512 + e.size) {
      n = std::min<std::uint64_t>(length, 512 + e.size - in_entry);
      std::ifstream in(e.path, std::ios::binary);
      in.seekg(static_cast<std::streamoff>(in_entry - 512));
      std::string chunk(static_cast<std::size_t>(n), '\0');
      if (!in.read(chunk.data(), static_cast<std::streamsize>(n)))
        return fail("cannot read '" + e.path.string() + "'");
      out += chunk;
    } else {
      n = std::min<std::uint64_t>(length, padded - in_entry);
      out.append(static_cast<std::size_t>(n), '\0');
    }
    offset += n;
    length -= n;
  }
  return out;
}

Result<std::string> tar_folder(const std::filesystem::path& folder, const std::string& prefix) {
  auto t = TarStream::open(folder, prefix);
  if (!t) return t.failure();
  return t->read(0, t->size());
}

void run_in_background(int nice_increment) {
  // Linux keeps a nice value per thread (setpriority on the thread id); threads started from
  // this one inherit it. Raising it needs no privilege; failure only costs the preference.
  const auto tid = static_cast<id_t>(::syscall(SYS_gettid));
  const int current = ::getpriority(PRIO_PROCESS, tid);
  ::setpriority(PRIO_PROCESS, tid, current + nice_increment);
}

Result<std::string> load_booth_id(const std::filesystem::path& data_dir) {
  const std::filesystem::path path = data_dir / "booth-id";
  std::error_code ec;
  if (std::filesystem::exists(path, ec)) {
    std::ifstream in(path);
    std::string id;
    std::getline(in, id);
    const bool valid =
        !id.empty() && id.size() <= 64 && std::all_of(id.begin(), id.end(), [](char c) {
          return std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_';
        });
    if (!valid)
      return fail(path.string() +
                  " is not a booth id (1..64 of [A-Za-z0-9_-]): restore it from a backup (hosts "
                  "know this booth's sessions by it), or delete it to start as a new booth");
    return id;
  }
  const std::string id = "booth-" + random_token(16);
  const std::string text = id + "\n";
  auto written = write_file_durably(
      path, std::span(reinterpret_cast<const std::uint8_t*>(text.data()), text.size()));
  if (!written) return fail("cannot write the booth id: " + written.error().message);
  return id;
}

Result<std::string> Daemon::Impl::guide_picture(int index) {
  std::lock_guard lock(guide_bmp_mutex);
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
  const PixelRect box = default_face_box(frame.color.width, frame.color.height)
                            .rect.clipped(frame.color.width, frame.color.height);
  ColorImage crop;
  crop.resize(box.width(), box.height());
  for (int y = 0; y < box.height(); ++y)
    for (int x = 0; x < box.width(); ++x) crop.at(x, y) = frame.color.at(box.x0 + x, box.y0 + y);
  auto bmp = encode_bmp(crop);
  guide_bmp_cache[index] = bmp;
  return bmp;
}

}  // namespace fb
