// A real OSC receiver (oscdump from Debian's liblo-tools, a child process on a free loopback
// UDP port) receives the VMC messages of a short synthetic take; the values must match what
// the tracker produced.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "algo/tracking/face_tracker.hpp"
#include "firmware/streaming/vmc_sender.hpp"
#include "sim/camera/synthetic_camera.hpp"
#include "storage/asset_files.hpp"
#include "tests/common/test_face_model.hpp"

namespace fb {
namespace {

int free_udp_port() {
  const int fd = ::socket(AF_INET, SOCK_DGRAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof(addr);
  int port = 0;
  if (::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) == 0 &&
      ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len) == 0) {
    port = ntohs(addr.sin_port);
  }
  ::close(fd);
  return port;
}

// oscdump as a child process with its stdout on a pipe; killed and reaped on destruction.
class OscDump {
 public:
  explicit OscDump(int port) {
    int fds[2];
    if (::pipe(fds) != 0) return;
    pid_ = ::fork();
    if (pid_ == 0) {
      ::dup2(fds[1], STDOUT_FILENO);
      ::close(fds[0]);
      ::close(fds[1]);
      const std::string p = std::to_string(port);
      ::execl(FB_OSCDUMP, "oscdump", "-L", p.c_str(), static_cast<char*>(nullptr));
      ::_exit(127);
    }
    ::close(fds[1]);
    fd_ = fds[0];
  }
  ~OscDump() {
    if (pid_ > 0) {
      ::kill(pid_, SIGTERM);
      ::waitpid(pid_, nullptr, 0);
    }
    if (fd_ >= 0) ::close(fd_);
  }
  OscDump(const OscDump&) = delete;
  OscDump& operator=(const OscDump&) = delete;
  bool running() const { return pid_ > 0 && fd_ >= 0; }

  // Reads whatever arrives within `ms`, appending complete lines.
  void read_for(int ms, std::vector<std::string>& lines) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(ms);
    while (std::chrono::steady_clock::now() < end) {
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, 20) <= 0) continue;
      char buffer[65536];
      const ssize_t n = ::read(fd_, buffer, sizeof(buffer));
      if (n <= 0) break;
      partial_.append(buffer, static_cast<std::size_t>(n));
      std::size_t nl;
      while ((nl = partial_.find('\n')) != std::string::npos) {
        lines.push_back(partial_.substr(0, nl));
        partial_.erase(0, nl + 1);
      }
    }
  }

 private:
  pid_t pid_ = -1;
  int fd_ = -1;
  std::string partial_;
};

struct Message {
  std::string path;
  std::vector<std::string> args;  // strings unquoted, numbers as text
};

// oscdump line: `<timetag> <path> <typetags> <args...>` with strings in double quotes.
Message parse_line(const std::string& line) {
  Message m;
  std::istringstream in(line);
  std::string timetag, types;
  in >> timetag >> m.path >> types;
  std::string token;
  while (in >> token) {
    if (token.size() >= 2 && token.front() == '"' && token.back() == '"') {
      token = token.substr(1, token.size() - 2);
    }
    m.args.push_back(token);
  }
  return m;
}

TEST(VmcOsc, OscdumpReceivesTheTakeValues) {
  ASSERT_TRUE(std::string(FB_OSCDUMP).find("oscdump") != std::string::npos)
      << "oscdump (liblo-tools) not found at configure time";
  const int port = free_udp_port();
  ASSERT_GT(port, 0);
  OscDump dump(port);
  ASSERT_TRUE(dump.running());

  VmcOptions options;
  options.port = port;
  auto sender = VmcSender::open(options);
  ASSERT_TRUE(sender.ok()) << sender.error().message;

  // Wait for the receiver: send an empty frame until it shows up (oscdump binds after fork).
  std::vector<std::string> lines;
  ArkitFrame probe;
  for (int attempt = 0; attempt < 50 && lines.empty(); ++attempt) {
    ASSERT_TRUE((*sender)->send(probe).ok());
    dump.read_for(100, lines);
  }
  ASSERT_FALSE(lines.empty()) << "oscdump received nothing on port " << port;
  dump.read_for(200, lines);
  lines.clear();

  // A short synthetic take: known identity, jawOpen + a smile, through the tracker.
  SyntheticOptions o;
  o.seed = 4;
  o.frame_count = 6;
  o.motion = SyntheticMotion::kStatic;
  o.expression_weights.assign(test::face_model().expression_count, 0.0f);
  o.expression_weights[test::face_model().expression_index("jawOpen")] = 0.5f;
  o.expression_weights[test::face_model().expression_index("mouthSmile_L")] = 0.6f;
  auto camera = make_synthetic_camera(test::face_model(), o);
  ASSERT_TRUE(camera.ok()) << camera.error().message;
  ASSERT_TRUE((*camera)->start().ok());
  auto tracker = FaceTracker::create(test::face_model(), (*camera)->info().depth_intrinsics);
  ASSERT_TRUE(tracker.ok()) << tracker.error().message;
  auto mapping = make_arkit_mapping(test::face_model());
  ASSERT_TRUE(mapping.ok());
  RgbdFrame frame;
  TrackReport report;
  std::vector<ArkitFrame> sent;
  bool identity_set = false;
  while (true) {
    auto status = (*camera)->next_frame(frame, std::chrono::milliseconds(100));
    ASSERT_TRUE(status.ok());
    if (*status != FrameStatus::kFrame) break;
    if (!identity_set) {
      ASSERT_TRUE((*tracker)->set_identity(frame_truth(**camera)->identity_coeffs).ok());
      identity_set = true;
    }
    (*tracker)->track(frame.depth_mm, frame.depth_host_time_s, nullptr, report);
    ArkitFrame out;
    out.index = frame.index;
    out.time_s = frame.depth_host_time_s;
    out.face_found = report.face_found;
    out.camera_from_model = report.camera_from_model;
    mapping->to_arkit(std::span<const float>(report.weights.data(), report.shape_count),
                      out.weights);
    ASSERT_TRUE((*sender)->send(out).ok());
    sent.push_back(out);
  }
  ASSERT_EQ(sent.size(), 6u);
  dump.read_for(1500, lines);

  // Group the received messages into frames at every Apply.
  std::vector<std::map<std::string, float>> blend(1);
  std::vector<std::vector<float>> head(1), root(1);
  for (const auto& line : lines) {
    const Message m = parse_line(line);
    if (m.path == "/VMC/Ext/Blend/Val" && m.args.size() == 2) {
      blend.back()[m.args[0]] = std::stof(m.args[1]);
    } else if (m.path == "/VMC/Ext/Bone/Pos" && m.args.size() == 8 && m.args[0] == "Head") {
      for (int i = 1; i < 8; ++i) head.back().push_back(std::stof(m.args[i]));
    } else if (m.path == "/VMC/Ext/Root/Pos" && m.args.size() == 8 && m.args[0] == "root") {
      for (int i = 1; i < 8; ++i) root.back().push_back(std::stof(m.args[i]));
    } else if (m.path == "/VMC/Ext/Blend/Apply") {
      blend.emplace_back();
      head.emplace_back();
      root.emplace_back();
    }
  }
  ASSERT_EQ(blend.size(), sent.size() + 1)
      << "expected one Apply per frame; got " << lines.size() << " lines";
  for (std::size_t f = 0; f < sent.size(); ++f) {
    ASSERT_EQ(blend[f].size(), static_cast<std::size_t>(kArkitShapeCount)) << "frame " << f;
    for (int i = 0; i < kArkitShapeCount; ++i) {
      const auto it = blend[f].find(std::string(kArkitNames[i]));
      ASSERT_NE(it, blend[f].end()) << kArkitNames[i];
      EXPECT_NEAR(it->second, sent[f].weights[i], 1e-5) << kArkitNames[i] << " frame " << f;
    }
    const VmcPosePayload expected = vmc_pose(sent[f].camera_from_model, sent[0].camera_from_model);
    ASSERT_EQ(head[f].size(), 7u);
    ASSERT_EQ(root[f].size(), 7u);
    for (int i = 0; i < 4; ++i) EXPECT_NEAR(head[f][3 + i], expected.head_rotation[i], 1e-5);
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(root[f][i], expected.root_position[i], 1e-5);
  }
  // The tracked values themselves are the take's: jawOpen ~0.5, mouthSmileLeft ~0.6.
  EXPECT_NEAR(blend[5]["jawOpen"], 0.5f, 0.1f);
  EXPECT_NEAR(blend[5]["mouthSmileLeft"], 0.6f, 0.1f);
  EXPECT_NEAR(blend[5]["tongueOut"], 0.0f, 1e-6f);
}

TEST(VmcOsc, DestinationParsing) {
  auto a = parse_osc_destination("192.168.1.5:39540");
  ASSERT_TRUE(a.ok());
  EXPECT_EQ(a->host, "192.168.1.5");
  EXPECT_EQ(a->port, 39540);
  auto b = parse_osc_destination("studio.local");
  ASSERT_TRUE(b.ok());
  EXPECT_EQ(b->port, kVmcDefaultPort);
  auto c = parse_osc_destination(":9000");
  ASSERT_TRUE(c.ok());
  EXPECT_EQ(c->host, "127.0.0.1");
  EXPECT_EQ(c->port, 9000);
  EXPECT_FALSE(parse_osc_destination("host:70000").ok());
  EXPECT_FALSE(parse_osc_destination("host:abc").ok());
}

}  // namespace
}  // namespace fb
