#include "drivers/camera/openni2/oni_writer.hpp"

#include <bit>
#include <cstring>
#include <string_view>

namespace fb {
namespace {

static_assert(std::endian::native == std::endian::little,
              "the .oni format is little-endian; add byte swapping for big-endian hosts");
static_assert(sizeof(Rgb8) == 3, "colour payloads are written straight from Rgb8 pixels");

// Record types (OpenNI2 Source/Drivers/OniFile/DataRecords.h).
constexpr std::uint32_t kRecordIntProperty = 0x03;
constexpr std::uint32_t kRecordGeneralProperty = 0x06;
constexpr std::uint32_t kRecordNodeRemoved = 0x07;
constexpr std::uint32_t kRecordNodeDataBegin = 0x08;
constexpr std::uint32_t kRecordNodeStateReady = 0x09;
constexpr std::uint32_t kRecordNewData = 0x0A;
constexpr std::uint32_t kRecordEnd = 0x0B;
constexpr std::uint32_t kRecordNodeAdded = 0x0D;
constexpr std::uint32_t kRecordSeekTable = 0x0E;

constexpr std::uint32_t kRecordMagic = 0x0052494E;  // "NIR\0"
constexpr std::size_t kRecordHeaderSize = 4 * 5 + 8;
constexpr std::size_t kFileHeaderSize = 4 + 8 + 8 + 4;
constexpr std::size_t kSeekEntrySize = 8 + 4 + 8;  // timestamp, configuration id, position

constexpr std::uint32_t kNodeTypeDepth = 2;
constexpr std::uint32_t kNodeTypeImage = 3;

constexpr std::uint32_t codec_id(char a, char b, char c, char d) {
  return static_cast<std::uint32_t>(a) | (static_cast<std::uint32_t>(b) << 8) |
         (static_cast<std::uint32_t>(c) << 16) | (static_cast<std::uint32_t>(d) << 24);
}
// "NONE": frames are stored raw. The player creates its XnUncompressedCodec for it.
constexpr std::uint32_t kCodecUncompressed = codec_id('N', 'O', 'N', 'E');

// OpenNI 1.x pixel formats (xnPixelFormat) and OpenNI 2 ones (oniPixelFormat).
constexpr std::uint64_t kXnPixelFormatRgb24 = 1;
constexpr std::uint64_t kXnPixelFormatGray16 = 4;
constexpr std::uint64_t kOniPixelFormatDepth1mm = 100;
constexpr std::uint64_t kOniPixelFormatRgb888 = 200;

std::string_view node_name(std::uint32_t type) {
  return type == kNodeTypeDepth ? "Depth" : "Image";
}

void put_bytes(std::vector<std::uint8_t>& out, const void* data, std::size_t size) {
  const auto* bytes = static_cast<const std::uint8_t*>(data);
  out.insert(out.end(), bytes, bytes + size);
}
template <class T>
void put(std::vector<std::uint8_t>& out, T value) {
  put_bytes(out, &value, sizeof(value));
}
// Strings are a 32-bit length that counts the terminating NUL, then the characters and the NUL.
void put_string(std::vector<std::uint8_t>& out, std::string_view text) {
  put<std::uint32_t>(out, static_cast<std::uint32_t>(text.size() + 1));
  put_bytes(out, text.data(), text.size());
  out.push_back(0);
}

// Starts a record; the fields size is fixed up by finish_fields().
void begin_record(std::vector<std::uint8_t>& out, std::uint32_t type, std::uint32_t node_id,
                  std::uint64_t undo_position = 0) {
  out.clear();
  put(out, kRecordMagic);
  put(out, type);
  put(out, node_id);
  put<std::uint32_t>(out, 0);  // fields size, set by finish_fields
  put<std::uint32_t>(out, 0);  // payload size
  put(out, undo_position);
}
void finish_fields(std::vector<std::uint8_t>& out, std::uint32_t payload_size = 0) {
  const auto fields = static_cast<std::uint32_t>(out.size());
  std::memcpy(out.data() + 12, &fields, 4);
  std::memcpy(out.data() + 16, &payload_size, 4);
}

void general_property(std::vector<std::uint8_t>& out, std::uint32_t node, std::string_view name,
                      const void* data, std::size_t size) {
  begin_record(out, kRecordGeneralProperty, node);
  put_string(out, name);
  put<std::uint32_t>(out, static_cast<std::uint32_t>(size));
  put_bytes(out, data, size);
  finish_fields(out);
}
void int_property(std::vector<std::uint8_t>& out, std::uint32_t node, std::string_view name,
                  std::uint64_t value) {
  general_property(out, node, name, &value, sizeof(value));
  const std::uint32_t type = kRecordIntProperty;
  std::memcpy(out.data() + 4, &type, 4);
}

void node_added(std::vector<std::uint8_t>& out, std::uint32_t node, std::uint32_t type,
                std::uint32_t frames, std::uint64_t max_timestamp, std::uint64_t seek_table) {
  begin_record(out, kRecordNodeAdded, node);
  put_string(out, node_name(type));
  put(out, type);
  put(out, kCodecUncompressed);
  put(out, frames);
  put<std::uint64_t>(out, 0);  // min timestamp
  put(out, max_timestamp);
  put(out, seek_table);
  finish_fields(out);
}

}  // namespace

OniWriter::OniWriter(std::filesystem::path path, const OniWriterOptions& options)
    : path_(std::move(path)), options_(options) {
  depth_node_.id = 1;
  depth_node_.type = kNodeTypeDepth;
  color_node_.id = 2;
  color_node_.type = kNodeTypeImage;
}

Result<std::unique_ptr<OniWriter>> OniWriter::create(const std::filesystem::path& path,
                                                     const OniWriterOptions& options) {
  if (options.width <= 0 || options.height <= 0 || options.fps <= 0) {
    return fail("oni writer: invalid stream size " + std::to_string(options.width) + "x" +
                std::to_string(options.height) + "@" + std::to_string(options.fps) +
                "; width, height and fps must be positive");
  }
  // The OniFile player reads each frame into a fixed 1600x1200x3 byte buffer.
  if (static_cast<long long>(options.width) * options.height * 3 > 1600LL * 1200 * 3) {
    return fail("oni writer: " + std::to_string(options.width) + "x" +
                std::to_string(options.height) +
                " frames are larger than libOniFile can play (at most 1600x1200 RGB)");
  }
  std::unique_ptr<OniWriter> writer(new OniWriter(path, options));
  writer->file_.open(path, std::ios::binary | std::ios::trunc | std::ios::out);
  if (!writer->file_) {
    return fail("oni writer: cannot create '" + path.string() +
                "'; check that the directory exists and is writable");
  }
  auto ok = writer->write_preamble();
  if (!ok) return ok.failure();
  return writer;
}

OniWriter::~OniWriter() {
  if (!closed_ && file_.is_open()) (void)close();
}

Result<void> OniWriter::check_stream(const char* what) {
  if (file_) return success();
  return fail(std::string("oni writer: writing ") + what + " to '" + path_.string() +
              "' failed; the disk may be full or the file was removed");
}

Result<void> OniWriter::emit(std::uint64_t* position) {
  file_.seekp(0, std::ios::end);
  if (position != nullptr) *position = static_cast<std::uint64_t>(file_.tellp());
  file_.write(reinterpret_cast<const char*>(record_.data()),
              static_cast<std::streamsize>(record_.size()));
  return check_stream("a record");
}

Result<void> OniWriter::write_preamble() {
  // Header; max timestamp and max node id are patched in close().
  record_.clear();
  put_bytes(record_, "NI10", 4);
  put<std::uint8_t>(record_, 1);   // major
  put<std::uint8_t>(record_, 0);   // minor
  put<std::uint16_t>(record_, 1);  // maintenance: 1.0.1.0 is the first version with 64-bit offsets
  put<std::uint32_t>(record_, 0);  // build
  put<std::uint64_t>(record_, 0);  // max timestamp
  put<std::uint32_t>(record_, 0);  // max node id
  if (auto ok = emit(); !ok) return ok;

  if (auto ok = write_node_description(depth_node_); !ok) return ok;
  if (options_.with_color) {
    if (auto ok = write_node_description(color_node_); !ok) return ok;
  }
  // As the real recorder does on Recorder::start(): every node becomes ready, then data begins.
  for (Node* node : {&depth_node_, &color_node_}) {
    if (node == &color_node_ && !options_.with_color) continue;
    begin_record(record_, kRecordNodeStateReady, node->id);
    finish_fields(record_);
    if (auto ok = emit(); !ok) return ok;
    begin_record(record_, kRecordNodeDataBegin, node->id);
    put<std::uint32_t>(record_, 0xFFFFFFFFu);  // frame count: unknown while recording
    put<std::uint64_t>(record_, ~std::uint64_t{0});
    finish_fields(record_);
    if (auto ok = emit(); !ok) return ok;
  }
  return success();
}

Result<void> OniWriter::write_node_description(Node& node) {
  const bool depth = node.type == kNodeTypeDepth;
  const std::uint32_t id = node.id;
  const auto w = static_cast<std::uint32_t>(options_.width);
  const auto h = static_cast<std::uint32_t>(options_.height);
  const auto fps = static_cast<std::uint32_t>(options_.fps);

  // Placeholder counts; close() rewrites this record in place (same size).
  node_added(record_, id, node.type, 0xFFFFFFFFu, ~std::uint64_t{0}, 0);
  if (auto ok = emit(&node.node_added_position); !ok) return ok;

  auto emit_general = [&](std::string_view name, const void* data, std::size_t size) {
    general_property(record_, id, name, data, size);
    return emit();
  };
  auto emit_int = [&](std::string_view name, std::uint64_t value) {
    int_property(record_, id, name, value);
    return emit();
  };

  // The same properties and order as OpenNI's FileRecorder::onAttach. The player needs:
  // xnMapOutputMode before the pixel formats (it edits the previously stored video mode),
  // oniPixelFormat, oniRequiredFrameSize, xnFOV, and xnCropping (without a cropping property
  // PlayerStream silently drops every frame). xnDeviceMaxDepth becomes the depth MAX_VALUE.
  std::string device(options_.original_device);
  device.resize(256, '\0');  // ONI_MAX_STR, as OniDeviceInfo::name is recorded
  if (auto ok = emit_general("oniOriginalDevice", device.data(), device.size()); !ok) return ok;
  const std::uint64_t bytes_per_pixel = depth ? 2 : 3;
  if (auto ok = emit_int("oniRequiredFrameSize", std::uint64_t{w} * h * bytes_per_pixel); !ok)
    return ok;
  if (auto ok = emit_int("xnIsGenerating", 1); !ok) return ok;
  if (depth) {
    if (auto ok = emit_int("xnDeviceMaxDepth", options_.max_depth_mm); !ok) return ok;
  }
  const std::uint32_t mode[3] = {w, h, fps};
  if (auto ok = emit_int("xnSupportedMapOutputModesCount", 1); !ok) return ok;
  if (auto ok = emit_general("xnSupportedMapOutputModes", mode, sizeof(mode)); !ok) return ok;
  if (auto ok = emit_general("xnMapOutputMode", mode, sizeof(mode)); !ok) return ok;
  // XnSupportedPixelFormats is a bit field: bit 0 RGB24, bit 3 grayscale 16.
  const std::uint32_t supported_formats = depth ? 0x08u : 0x01u;
  if (auto ok = emit_general("xnSupportedPixelFormats", &supported_formats, 4); !ok) return ok;
  if (auto ok = emit_int("xnPixelFormat", depth ? kXnPixelFormatGray16 : kXnPixelFormatRgb24); !ok)
    return ok;
  if (auto ok = emit_int("oniPixelFormat", depth ? kOniPixelFormatDepth1mm : kOniPixelFormatRgb888);
      !ok)
    return ok;
  const double fov[2] = {depth ? options_.depth_hfov : options_.color_hfov,
                         depth ? options_.depth_vfov : options_.color_vfov};
  if (auto ok = emit_general("xnFOV", fov, sizeof(fov)); !ok) return ok;
  if (auto ok = emit_int("Cropping", 1); !ok) return ok;
  // XnCropping: XnBool enabled (4 bytes), then x offset, y offset, x size, y size (uint16).
  const std::uint8_t cropping[12] = {};
  if (auto ok = emit_general("xnCropping", cropping, sizeof(cropping)); !ok) return ok;
  return success();
}

Result<void> OniWriter::write_new_data(Node& node, const void* data, std::uint32_t size,
                                       std::uint64_t timestamp_us) {
  // The undo position links each frame to the node's previous one (used for backward seeks).
  begin_record(record_, kRecordNewData, node.id, node.last_new_data_position);
  put<std::uint64_t>(record_, timestamp_us);
  put<std::uint32_t>(record_, static_cast<std::uint32_t>(frame_count_ + 1));  // 1-based
  finish_fields(record_, size);
  std::uint64_t position = 0;
  if (auto ok = emit(&position); !ok) return ok;
  file_.write(static_cast<const char*>(data), static_cast<std::streamsize>(size));
  if (auto ok = check_stream("a frame"); !ok) return ok;
  node.last_new_data_position = position;
  node.seek_table.push_back({timestamp_us, position});
  return success();
}

Result<void> OniWriter::write_frame(const DepthImage& depth, const ColorImage* color,
                                    std::uint64_t timestamp_us) {
  if (closed_) return fail("oni writer: '" + path_.string() + "' is already closed");
  const std::string expected =
      std::to_string(options_.width) + "x" + std::to_string(options_.height);
  if (depth.width != options_.width || depth.height != options_.height ||
      depth.pixels.size() != static_cast<std::size_t>(depth.width) * depth.height) {
    return fail("oni writer: depth frame is " + std::to_string(depth.width) + "x" +
                std::to_string(depth.height) + " but the recording is " + expected);
  }
  if (options_.with_color) {
    if (color == nullptr) {
      return fail("oni writer: the recording has a colour stream; pass a colour image");
    }
    if (color->width != options_.width || color->height != options_.height ||
        color->pixels.size() != static_cast<std::size_t>(color->width) * color->height) {
      return fail("oni writer: colour frame is " + std::to_string(color->width) + "x" +
                  std::to_string(color->height) + " but the recording is " + expected);
    }
  }
  if (frame_count_ > 0 && timestamp_us < max_timestamp_) {
    return fail("oni writer: timestamp " + std::to_string(timestamp_us) +
                " us goes backwards (previous " + std::to_string(max_timestamp_) + " us)");
  }
  auto ok = write_new_data(depth_node_, depth.pixels.data(),
                           static_cast<std::uint32_t>(depth.pixels.size() * 2), timestamp_us);
  if (!ok) return ok;
  if (options_.with_color) {
    ok = write_new_data(color_node_, color->pixels.data(),
                        static_cast<std::uint32_t>(color->pixels.size() * 3), timestamp_us);
    if (!ok) return ok;
  }
  max_timestamp_ = timestamp_us;
  ++frame_count_;
  return success();
}

Result<void> OniWriter::write(const DepthImage& depth, const ColorImage& color,
                              std::uint64_t timestamp_us) {
  return write_frame(depth, &color, timestamp_us);
}

Result<void> OniWriter::write(const DepthImage& depth, std::uint64_t timestamp_us) {
  return write_frame(depth, nullptr, timestamp_us);
}

Result<void> OniWriter::close() {
  if (closed_) return success();
  closed_ = true;
  std::uint32_t max_node_id = 0;
  for (Node* node : {&depth_node_, &color_node_}) {
    if (node == &color_node_ && !options_.with_color) continue;
    max_node_id = node->id;
    begin_record(record_, kRecordNodeRemoved, node->id, node->node_added_position);
    finish_fields(record_);
    if (auto ok = emit(); !ok) return ok;

    // Seek table: entry 0 is empty (frames are 1-based), then one entry per frame.
    std::uint64_t seek_table_position = 0;
    const auto entries = node->seek_table.size() + 1;
    begin_record(record_, kRecordSeekTable, node->id);
    finish_fields(record_, static_cast<std::uint32_t>(entries * kSeekEntrySize));
    record_.resize(record_.size() + kSeekEntrySize, 0);
    for (const SeekEntry& entry : node->seek_table) {
      put(record_, entry.timestamp);
      put<std::uint32_t>(record_, 0);  // configuration id: properties never change mid-file
      put(record_, entry.position);
    }
    if (auto ok = emit(&seek_table_position); !ok) return ok;

    // Rewrite NodeAdded in place, now with the frame count and the seek table.
    node_added(record_, node->id, node->type, static_cast<std::uint32_t>(frame_count_),
               max_timestamp_, node->seek_table.empty() ? 0 : seek_table_position);
    file_.seekp(static_cast<std::streamoff>(node->node_added_position));
    file_.write(reinterpret_cast<const char*>(record_.data()),
                static_cast<std::streamsize>(record_.size()));
    if (auto ok = check_stream("the stream description"); !ok) return ok;
  }
  begin_record(record_, kRecordEnd, 0);
  finish_fields(record_);
  if (auto ok = emit(); !ok) return ok;

  // Header: the player rejects frames whose timestamp exceeds the global max timestamp.
  file_.seekp(12);
  file_.write(reinterpret_cast<const char*>(&max_timestamp_), 8);
  file_.write(reinterpret_cast<const char*>(&max_node_id), 4);
  file_.close();
  if (file_.fail()) {
    return fail("oni writer: finishing '" + path_.string() +
                "' failed; the disk may be full or the file was removed");
  }
  static_assert(kFileHeaderSize == 24 && kRecordHeaderSize == 28);
  return success();
}

}  // namespace fb
