// A take's stored frames on disk instead of in memory while the take waits for its fit, its QA
// and (when rejected) a possible landmark correction. Two takes of 30 stored 640x480 frames are
// about 90 MB, a third of the device's 256 MB budget. The spool is a scratch file, deleted with
// the object and at daemon start: it is not the capture's durable copy (the session store writes
// that, reading the frames back one at a time), so a crash loses only a take not yet accepted.
#pragma once

#include <cstddef>
#include <filesystem>
#include <fstream>
#include <memory>
#include <vector>

#include "algo/core/frame.hpp"
#include "algo/core/result.hpp"

namespace fb {

class FrameSpool {
 public:
  // Creates an empty spool file in `folder` (made if missing).
  static Result<std::unique_ptr<FrameSpool>> create(const std::filesystem::path& folder);
  // Deletes every spool file left in `folder` by a process that did not stop cleanly.
  static void remove_stale(const std::filesystem::path& folder);
  ~FrameSpool();
  FrameSpool(const FrameSpool&) = delete;
  FrameSpool& operator=(const FrameSpool&) = delete;

  // Appends depth, colour and times as one frame record (storage/frame_record.hpp, the session
  // store's encoding); the raw disparity is not kept (derivable from depth).
  Result<void> append(const RgbdFrame& frame);
  // Reads frame `i` back into `out` (its images are resized; no allocation once sized).
  Result<void> read(std::size_t i, RgbdFrame& out);
  std::size_t size() const { return offsets_.size(); }
  const std::filesystem::path& path() const { return path_; }

 private:
  FrameSpool(std::filesystem::path path, std::fstream file);

  std::filesystem::path path_;
  std::fstream file_;
  std::uint64_t end_ = 0;
  std::vector<std::uint64_t> offsets_;  // where each frame's record starts
};

}  // namespace fb
