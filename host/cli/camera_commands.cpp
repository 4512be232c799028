// facebooth camera list | record | view
#include <chrono>
#include <cstdio>
#include <iostream>

#include "algo/sensor/self_calibration.hpp"
#include "drivers/camera/camera_backend.hpp"
#include "drivers/camera/camera_plugin.hpp"
#include "drivers/camera/recorder/recorder.hpp"
#include "host/cli/commands.hpp"
#include "host/cli/frame_open.hpp"
#include "host/cli/frame_png.hpp"
#include "host/cli/progress.hpp"

namespace fb::cli {
namespace {

int run_list(const ParsedOptions&) {
  std::cout << "backends in this build:\n";
  for (const auto& backend : camera_backends()) std::cout << "  " << backend.usage << "\n";
  // Loadable modules (drivers/camera/camera_plugin.hpp), e.g. the synthetic camera.
  for (const auto& backend : camera_plugins()) std::cout << "  " << backend.usage << "  [module]\n";
  std::cout << "\nsources available now:\n";
  const auto cameras = list_cameras();
  for (const auto& camera : cameras)
    std::cout << "  " << camera.uri << "  " << camera.description << "\n";
  if (cameras.empty()) std::cout << "  (none)\n";
  return kExitOk;
}

int run_record(const ParsedOptions& options) {
  const auto out = options.get("out");
  if (out.empty())
    return report_failure({"camera record needs --out DIR (a new or empty directory)"});
  auto frames = options.get_int("frames");
  if (!frames) return report_failure(frames.error());
  if (*frames <= 0) return report_failure({"--frames must be at least 1"});
  auto camera = open_camera(options.get("camera"));
  if (!camera) return report_failure(camera.error());

  RecorderOptions record_options;
  record_options.overwrite = options.flag("force");
  auto summary = [&] {
    Progress progress("recording frames", *frames);
    return record_camera(
        **camera, out, *frames, [&](long long written) { progress.update(written); },
        record_options);
  }();
  if (!summary) return report_failure(summary.error());
  std::cout << "wrote " << summary->depth_frames << " frames to " << out << " (fakenect format)"
            << (summary->end_of_stream ? "; the source ended there" : "") << "\n";
  return kExitOk;
}

int run_view(const ParsedOptions& options) {
  const auto out = options.get("out");
  if (out.empty()) return report_failure({"camera view needs --out FILE.png"});
  auto index = options.get_int("frame");
  if (!index) return report_failure(index.error());
  auto camera = open_started_camera(options.get("camera"));
  if (!camera) return report_failure(camera.error());
  RgbdFrame frame;
  auto got = read_frame_at(**camera, *index, frame);
  if (!got) return report_failure(got.error());
  const KinectRegistration registration((*camera)->info().calibration);
  FramePngOptions png;
  if (options.flag("overlay")) png.registration = &registration;
  if (auto written = write_frame_png(frame, out, png); !written)
    return report_failure(written.error());
  std::cout << "wrote frame " << frame.index << " of " << (*camera)->info().uri << " to " << out
            << "\n";
  if (options.flag("overlay")) {
    // The same measure as `camera self-calibrate`, on this one frame.
    SelfCalibrator calibrator((*camera)->info().calibration);
    calibrator.add_frame(frame.depth_mm, frame.color);
    auto r = calibrator.estimate();
    if (!r) {
      std::cout << "registration residual: not measurable (" << r.error().message << ")\n";
    } else if (!r->ok) {
      std::cout << "registration residual: not measurable on this frame (" << r->why << ")\n";
    } else {
      char text[200];
      std::snprintf(text, sizeof text,
                    "registration residual: the depth edges are %.1f px off the colour edges "
                    "(best correction dx %.1f, dy %.1f px)%s\n",
                    r->misregistration_px, r->correction.dx_px, r->correction.dy_px,
                    r->misregistration_px > 3.0 ? "; calibrate this camera: facebooth camera "
                                                  "self-calibrate --camera URI --save"
                                                : "");
      std::cout << text;
    }
  }
  return kExitOk;
}

const std::string kCameraDetails =
    "Camera URIs: synthetic:[seed=N,expr=NAME[:W][+NAME[:W]],motion=headturn|static,frames=N,...]\n"
    "             replay:DIR (a fakenect dump), freenect:N (Kinect N over USB; runs under\n"
    "             Debian's `fakenect DIR` too), openni2:FILE.oni or openni2: (first device).\n"
    "`facebooth camera list` shows the backends of this build.";

}  // namespace

std::vector<Command> camera_commands() {
  return {
      {{"camera list",
        "list camera backends and the sources that can be opened now",
        kCameraDetails,
        {}},
       run_list},
      {{"camera record",
        "record frames from a camera into a fakenect-format dump (INDEX.txt, d-/r-/a- files, "
        "device.json)",
        kCameraDetails,
        {{"camera", "URI", "camera to record from", "synthetic:"},
         {"frames", "N", "number of frames to record", "90"},
         {"out", "DIR", "output directory (must be new or empty)", ""},
         {"force", "", "allow writing into a non-empty directory", ""}}},
       run_record},
      {{"camera view",
        "write one frame as a PNG: false-colour depth beside the colour image",
        kCameraDetails,
        {{"camera", "URI", "camera to read from", "synthetic:"},
         {"frame", "K", "0-based index of the frame to draw", "0"},
         {"out", "FILE", "PNG to write", ""},
         {"overlay", "",
          "add a third panel: registered depth edges over the colour image, and print the "
          "registration residual",
          ""}}},
       run_view},
  };
}

}  // namespace fb::cli
