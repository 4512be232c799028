// facebooth camera calibrate: checkerboard calibration of a Kinect v1 unit's registration and
// depth law (algo/calibration) into a device.json that the pipeline reads.
#include <cmath>
#include <cstdio>
#include <iostream>
#include <string>

#include "algo/calibration/checkerboard_calibrator.hpp"
#include "drivers/camera/common/device_json.hpp"
#include "drivers/camera/depth_camera.hpp"
#include "host/cli/commands.hpp"

namespace fb::cli {
namespace {

std::string fixed(double value, int digits) {
  if (!std::isfinite(value)) return "undefined";
  char text[64];
  std::snprintf(text, sizeof text, "%.*f", digits, value);
  return text;
}

void print_progress(const CheckerboardCalibrator& c, long long frame, const std::string& outcome) {
  std::cerr << "calibrate: frame " << frame << ": " << outcome << "; boards " << c.views();
  if (c.views() > 0) {
    std::cerr << ", depth " << fixed(c.min_depth_mm(), 0) << "-" << fixed(c.max_depth_mm(), 0)
              << " mm, coverage";
    const auto cells = c.coverage();
    for (int row = 0; row < CheckerboardCalibrator::kGridRows; ++row) {
      std::cerr << (row == 0 ? " [" : " / ");
      for (int col = 0; col < CheckerboardCalibrator::kGridCols; ++col) {
        std::cerr << cells[static_cast<std::size_t>(row * CheckerboardCalibrator::kGridCols + col)];
      }
    }
    std::cerr << "]";
  }
  const std::string hint = c.hint();
  if (!hint.empty()) std::cerr << "; next: " << hint;
  std::cerr << "\n";
}

int run_calibrate(const ParsedOptions& options) {
  const std::string out = options.get("out");
  if (out.empty()) return report_failure({"camera calibrate needs --out device.json"});
  auto board = parse_board_spec(options.get("board"));
  if (!board) return report_failure(board.error());
  auto frames = options.get_int("frames");
  if (!frames || *frames < 1) {
    return report_failure({"--frames must be a positive whole number of frames to read"});
  }
  auto camera = open_camera(options.get("camera"));
  if (!camera) return report_failure(camera.error());
  if (auto started = (*camera)->start(); !started) return report_failure(started.error());
  CheckerboardCalibrator calibrator(*board, (*camera)->info().calibration);
  RgbdFrame frame;
  long long read = 0;
  int timeouts = 0;
  while (read < *frames) {
    auto status = (*camera)->next_frame(frame, std::chrono::milliseconds(2000));
    if (!status) return report_failure(status.error());
    if (*status == FrameStatus::kEndOfStream) break;
    if (*status == FrameStatus::kTimeout) {
      if (++timeouts > 5) return report_failure({"the camera stopped delivering frames"});
      continue;
    }
    auto added = calibrator.add_frame(frame.color, frame.raw_disparity, frame.depth_mm);
    print_progress(calibrator, read, added ? "board used" : added.error().message);
    ++read;
  }
  (*camera)->stop();
  if (calibrator.views() == 0) {
    return report_failure({"no " + board->to_string() + " checkerboard was found in any of the " +
                           std::to_string(read) +
                           " frames; check --board (inner corners, "
                           "e.g. 9x6 for 10x7 squares) and hold the whole board, with its white "
                           "margin, in view at 0.6-1.5 m"});
  }
  auto solved = calibrator.solve();
  if (!solved) return report_failure(solved.error());
  const auto cells = calibrator.coverage();
  int empty = 0;
  for (int n : cells) empty += n == 0 ? 1 : 0;
  if (empty > 4) {
    std::cerr << "calibrate: warning: poor coverage (" << empty << " of " << cells.size()
              << " image regions have no board); the calibration may be off at the image edges\n";
  }
  for (std::size_t v = 0; v < solved->views.size(); ++v) {
    const auto& r = solved->views[v];
    std::cout << "view " << v << ": colour " << fixed(r.color_px_rms, 3) << " px rms, depth "
              << fixed(r.depth_mm_rms, 2) << " mm rms, outline " << fixed(r.edge_px_rms, 2)
              << " px rms, board at " << fixed(r.camera_from_board.translation.z(), 0) << " mm\n";
  }
  const auto& c = solved->correction;
  std::cout << "overall: colour reprojection " << fixed(solved->color_px_rms, 3)
            << " px rms, depth " << fixed(solved->depth_mm_rms, 2) << " mm rms, outline "
            << fixed(solved->edge_px_rms, 2) << " px rms over " << solved->views.size()
            << " views\n"
            << "correction: shift (" << fixed(c.dx_px, 2) << ", " << fixed(c.dy_px, 2)
            << ") px, rotation " << fixed(c.rotation_deg, 3) << " deg, depth scale "
            << fixed(c.depth_scale, 4) << ", inverse depth offset "
            << fixed(c.inverse_depth_offset_per_m, 4) << " /m\n";
  if (auto written = write_device_json(out, calibrator.calibrated(c)); !written) {
    return report_failure(written.error());
  }
  std::cout << "wrote " << out << "\n";
  return kExitOk;
}

}  // namespace

std::vector<Command> camera_calibrate_commands() {
  return {{{"camera calibrate",
            "calibrate a Kinect unit's registration and depth law with a checkerboard",
            "Hold a printed checkerboard on a flat plate (with a white margin of one square) "
            "in front of the camera at 0.6-1.5 m, tilted and moved over the whole image. Each "
            "frame where the whole board is found in colour and its plate in depth is used; "
            "progress shows the boards used, image coverage (boards per region, 4x3), the "
            "depth range and where to hold the board next. The solve gives the colour shift and "
            "rotation and the depth-law scale and offset relative to the camera's tables, prints "
            "per-view and overall residuals and writes device.json with the correction. Try "
            "it with --camera synthetic:target=checkerboard,unit=7.",
            {{"camera", "URI", "camera to read from", "synthetic:target=checkerboard"},
             {"board", "COLSxROWS:SIZEmm", "inner corners and square size", "9x6:25mm"},
             {"frames", "N", "frames to read (at most)", "20"},
             {"out", "FILE", "device.json to write", ""}}},
           &run_calibrate}};
}

}  // namespace fb::cli
