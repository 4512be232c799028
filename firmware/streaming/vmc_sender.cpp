#include "firmware/streaming/vmc_sender.hpp"

#include <lo/lo.h>

#include <charconv>
#include <string>

namespace fb {
namespace {

// RAII owners of liblo handles.
struct AddressDeleter {
  void operator()(lo_address a) const { lo_address_free(a); }
};
using Address = std::unique_ptr<std::remove_pointer_t<lo_address>, AddressDeleter>;
struct BundleDeleter {
  void operator()(lo_bundle b) const { lo_bundle_free_recursive(b); }
};
using Bundle = std::unique_ptr<std::remove_pointer_t<lo_bundle>, BundleDeleter>;

}  // namespace

struct VmcSender::State {
  VmcOptions options;
  Address address;
  RigidPose reference;
  bool have_reference = false;
  long long datagrams = 0;
  long long messages = 0;
};

Result<VmcOptions> parse_osc_destination(std::string_view text) {
  VmcOptions options;
  const auto colon = text.rfind(':');
  std::string_view host = text, port;
  if (colon != std::string_view::npos) {
    host = text.substr(0, colon);
    port = text.substr(colon + 1);
  }
  if (!host.empty()) options.host = std::string(host);
  if (!port.empty()) {
    int value = 0;
    const auto [end, ec] = std::from_chars(port.data(), port.data() + port.size(), value);
    if (ec != std::errc() || end != port.data() + port.size() || value < 1 || value > 65535) {
      return fail("bad OSC destination '" + std::string(text) +
                  "': expected HOST:PORT with a port in 1-65535, e.g. 127.0.0.1:39539");
    }
    options.port = value;
  }
  return options;
}

VmcPosePayload vmc_pose(const RigidPose& camera_from_model, const RigidPose& reference) {
  VmcPosePayload p;
  // Model frame -> Unity: mirror X (right-handed -> left-handed): q -> (qx, -qy, -qz, qw).
  const Eigen::Quaterniond head = head_rotation(camera_from_model);
  p.head_rotation = Eigen::Vector4f(static_cast<float>(head.x()), static_cast<float>(-head.y()),
                                    static_cast<float>(-head.z()), static_cast<float>(head.w()));
  // Camera (x right, y down, z forward, mm) -> Unity facing the camera: (-x, -y, -z) m.
  const Eigen::Vector3d d = camera_from_model.translation - reference.translation;
  p.root_position = (-d / 1000.0).cast<float>();
  return p;
}

VmcSender::VmcSender(std::unique_ptr<State> state) : state_(std::move(state)) {}
VmcSender::~VmcSender() = default;

Result<std::unique_ptr<VmcSender>> VmcSender::open(const VmcOptions& options) {
  if (options.port < 1 || options.port > 65535) return fail("VMC: port must be in 1-65535");
  if (options.max_bundle_bytes < 256) return fail("VMC: max_bundle_bytes must be >= 256");
  const std::string port = std::to_string(options.port);
  Address address(lo_address_new_with_proto(LO_UDP, options.host.c_str(), port.c_str()));
  if (!address) {
    return fail("VMC: cannot create an OSC/UDP address for " + options.host + ":" + port);
  }
  auto state = std::make_unique<State>();
  state->options = options;
  state->address = std::move(address);
  return std::unique_ptr<VmcSender>(new VmcSender(std::move(state)));
}

void VmcSender::set_reference(const RigidPose& camera_from_model) {
  state_->reference = camera_from_model;
  state_->have_reference = true;
}

const VmcOptions& VmcSender::options() const {
  return state_->options;
}
long long VmcSender::datagrams_sent() const {
  return state_->datagrams;
}
long long VmcSender::messages_sent() const {
  return state_->messages;
}

Result<void> VmcSender::send(const ArkitFrame& frame) {
  State& s = *state_;
  if (!s.have_reference && frame.face_found) set_reference(frame.camera_from_model);
  const VmcPosePayload pose = vmc_pose(frame.camera_from_model, s.reference);

  Bundle bundle(lo_bundle_new(LO_TT_IMMEDIATE));
  if (!bundle) return fail("VMC: out of memory building a bundle");
  auto flush = [&]() -> Result<void> {
    if (lo_bundle_count(bundle.get()) == 0) return success();
    if (lo_send_bundle(s.address.get(), bundle.get()) < 0) {
      return fail(std::string("VMC: sending to ") + s.options.host + ":" +
                  std::to_string(s.options.port) + " failed: " +
                  (lo_address_errstr(s.address.get()) ? lo_address_errstr(s.address.get()) : "?"));
    }
    ++s.datagrams;
    bundle.reset(lo_bundle_new(LO_TT_IMMEDIATE));
    if (!bundle) return fail("VMC: out of memory building a bundle");
    return success();
  };
  // Adds one message, sending the bundle first when the message would overflow it.
  auto add = [&](const char* path, lo_message message) -> Result<void> {
    if (!message) return fail("VMC: out of memory building a message");
    const std::size_t extra = lo_message_length(message, path) + 4;
    if (lo_bundle_count(bundle.get()) > 0 &&
        lo_bundle_length(bundle.get()) + extra >
            static_cast<std::size_t>(s.options.max_bundle_bytes)) {
      if (auto sent = flush(); !sent) {
        lo_message_free(message);
        return sent;
      }
    }
    // The bundle keeps a pointer to `path` (string literals here) and owns the message.
    if (lo_bundle_add_message(bundle.get(), path, message) != 0) {
      lo_message_free(message);
      return fail("VMC: cannot add a message to the bundle");
    }
    ++s.messages;
    return success();
  };
  auto pose_message = [](const char* name, const Eigen::Vector3f& p, const Eigen::Vector4f& q) {
    lo_message m = lo_message_new();
    if (!m) return m;
    lo_message_add_string(m, name);
    for (int i = 0; i < 3; ++i) lo_message_add_float(m, p[i]);
    for (int i = 0; i < 4; ++i) lo_message_add_float(m, q[i]);
    return m;
  };
  if (s.options.send_root) {
    if (auto r =
            add("/VMC/Ext/Root/Pos", pose_message("root", pose.root_position, pose.root_rotation));
        !r) {
      return r;
    }
  }
  if (auto r =
          add("/VMC/Ext/Bone/Pos", pose_message("Head", pose.head_position, pose.head_rotation));
      !r) {
    return r;
  }
  for (int i = 0; i < kArkitShapeCount; ++i) {
    lo_message m = lo_message_new();
    if (m) {
      lo_message_add_string(m, kArkitNames[i].data());  // literals: NUL-terminated
      lo_message_add_float(m, frame.weights[static_cast<std::size_t>(i)]);
    }
    if (auto r = add("/VMC/Ext/Blend/Val", m); !r) return r;
  }
  if (auto r = add("/VMC/Ext/Blend/Apply", lo_message_new()); !r) return r;
  return flush();
}

}  // namespace fb
