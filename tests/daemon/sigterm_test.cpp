// SIGTERM to the real faceboothd in each phase of its work (issue 41, item 4): waiting for the
// button, recording a take, fitting it, tracking, exporting at the end of a session. Each time
// the process exits 0, the store verifies with no partial file, and the next start goes on
// where it stopped (a take interrupted is recorded again; a tracked take is stored).
#include <arpa/inet.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <thread>

#include "firmware/daemon/daemon.hpp"
#include "storage/durable_file.hpp"
#include "storage/session_store.hpp"
#include "tests/common/daemon_fixture.hpp"

// httplib last: its <resolv.h> defines `_res`, which breaks Eigen headers included after it.
#include <httplib.h>

namespace fb {
namespace {

namespace fs = std::filesystem;
using std::chrono::milliseconds;

// A port that was free a moment ago (the child daemon binds it). A plain socket, closed at
// once: an httplib::Server probe would keep its SO_REUSEPORT listener and steal connections.
int free_port() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof a;
  int port = -1;
  if (::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0 &&
      ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len) == 0)
    port = ntohs(a.sin_port);
  ::close(fd);
  return port;
}

// The real faceboothd as a child process, driven over HTTP; killed if a test ends early.
class DaemonProcess {
 public:
  DaemonProcess(const fs::path& config, int port) : http_("127.0.0.1", port), port_(port) {
    pid_ = ::fork();
    if (pid_ == 0) {
      ::execl(FB_FACEBOOTHD, FB_FACEBOOTHD, "--config", config.c_str(), nullptr);
      ::_exit(127);
    }
  }
  ~DaemonProcess() {
    if (pid_ > 0 && ::kill(pid_, SIGKILL) == 0) ::waitpid(pid_, nullptr, 0);
  }
  DaemonProcess(const DaemonProcess&) = delete;
  DaemonProcess& operator=(const DaemonProcess&) = delete;

  nlohmann::json status() {
    auto r = http_.Get("/api/status");
    return r && r->status == 200 ? nlohmann::json::parse(r->body) : nlohmann::json();
  }
  // Polls the status every 5 ms until `pred` holds; false after 60 s (a hang, not a timing
  // check).
  template <class P>
  bool wait_until(P pred) {
    for (int i = 0; i < 12000; ++i) {
      auto s = status();
      if (!s.is_null() && pred(s)) return true;
      std::this_thread::sleep_for(milliseconds(5));
    }
    return false;
  }
  int post(const std::string& path, const std::string& body) {
    httplib::Client fresh("127.0.0.1", port_);
    fresh.set_read_timeout(30, 0);
    auto r = fresh.Post(path, body, "application/json");
    return r ? r->status : -1;
  }
  int press() { return post("/api/sim/button", R"({"button": "main"})"); }
  // SIGTERM; the exit status, or -1 when it has not exited within 10 s (a hang).
  int terminate() {
    ::kill(pid_, SIGTERM);
    int wstatus = 0;
    for (int i = 0; i < 1000; ++i) {
      if (::waitpid(pid_, &wstatus, WNOHANG) == pid_) {
        pid_ = -1;
        return WIFEXITED(wstatus) ? WEXITSTATUS(wstatus) : 128 + WTERMSIG(wstatus);
      }
      std::this_thread::sleep_for(milliseconds(10));
    }
    return -1;
  }

 private:
  httplib::Client http_;
  int port_;
  pid_t pid_ = -1;
};

class DaemonSigterm : public test::DaemonFixture {
 protected:
  DaemonSigterm() : DaemonFixture("fb-sigterm-test-", test::kThreeStepGuide) {}

  // A process on this test's folder; `frames` a take, real time when asked.
  std::unique_ptr<DaemonProcess> spawn(int frames = 8, bool realtime = false) {
    DaemonConfig c = config();
    c.camera.capture_frames = frames;
    c.camera.realtime = realtime;
    c.http.port = free_port();
    EXPECT_GT(c.http.port, 0);
    std::ofstream(dir_ / "faceboothd.toml") << to_toml(c);
    auto p = std::make_unique<DaemonProcess>(dir_ / "faceboothd.toml", c.http.port);
    EXPECT_TRUE(p->wait_until([](auto& s) { return s["ready"] == true; }));
    return p;
  }
};

// SIGTERM during a take: the committed capture stays, the interrupted one is recorded again.
TEST_F(DaemonSigterm, MidTakeStopsCleanlyAndLosesNothing) {
  auto p = spawn(30, /*realtime=*/true);  // a paced 1 s take, so the signal lands inside one
  ASSERT_EQ(p->post("/api/session/start", R"({"subject": "Sig"})"), 202);
  ASSERT_TRUE(p->wait_until([](auto& s) { return s["state"] == "guide"; }));
  ASSERT_EQ(p->press(), 202);
  ASSERT_TRUE(
      p->wait_until([](auto& s) { return s["state"] == "guide" && s["capture_index"] == 1; }));
  ASSERT_EQ(p->press(), 202);
  ASSERT_TRUE(p->wait_until([](auto& s) {
    return s["state"] == "recording" && s["take_frames"].template get<int>() > 3;
  }));
  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_EQ(p->terminate(), 0);
  std::printf(
      "faceboothd stopped %.0f ms after SIGTERM (budget 2000 ms)\n",
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  expect_store_consistent();
  auto d = make(config());
  ASSERT_TRUE(d);
  ASSERT_TRUE(d->start());
  auto s = wait_for(*d, [](auto& s) { return s["state"] == "guide"; });
  EXPECT_TRUE(s["resumed"].get<bool>());
  EXPECT_EQ(s["done_count"], 1);
  EXPECT_EQ(s["capture_index"], 1);
  EXPECT_EQ(s["attempts"], 1);  // the interrupted attempt is counted, not committed
}

// SIGTERM while the button is awaited, while a take is fitted, after the last capture while
// the session exports, and in tracking mode.
TEST_F(DaemonSigterm, EachOtherPhaseStopsCleanlyAndTheNextStartGoesOn) {
  // Waiting for the button: nothing in flight.
  {
    auto p = spawn();
    ASSERT_EQ(p->post("/api/session/start", R"({"subject": "Sig"})"), 202);
    ASSERT_TRUE(p->wait_until([](auto& s) { return s["state"] == "guide"; }));
    EXPECT_EQ(p->terminate(), 0) << "waiting for the button";
    expect_store_consistent();
  }
  // Fitting the first take (the neutral's fit takes hundreds of ms: the 5 ms poll lands in it).
  {
    auto p = spawn();
    ASSERT_TRUE(
        p->wait_until([](auto& s) { return s["state"] == "guide" && s["resumed"] == true; }));
    ASSERT_EQ(p->press(), 202);
    ASSERT_TRUE(p->wait_until([](auto& s) { return s["state"] == "processing"; }));
    EXPECT_EQ(p->terminate(), 0) << "fitting";
    expect_store_consistent();
  }
  // The rest of the session, then SIGTERM as soon as it is complete (its export running).
  {
    auto p = spawn();
    ASSERT_TRUE(p->wait_until([](auto& s) { return s["state"] == "guide"; }));
    std::string acted;
    for (int step = 0; step < 12; ++step) {
      nlohmann::json now;
      ASSERT_TRUE(p->wait_until([&](auto& s) {
        now = s;
        const std::string key = s["state"].template get<std::string>() + "/" +
                                s["capture_index"].dump() + "/" + s["attempts"].dump();
        return key != acted &&
               (s["state"] == "guide" || s["state"] == "retry" || s["state"] == "complete");
      }));
      if (now["state"] == "complete") break;
      acted = now["state"].get<std::string>() + "/" + now["capture_index"].dump() + "/" +
              now["attempts"].dump();
      ASSERT_EQ(p->press(), 202);
    }
    EXPECT_EQ(p->terminate(), 0) << "exporting at the end of the session";
    expect_store_consistent();
  }
  ASSERT_NO_FATAL_FAILURE(expect_one_session(true, 3));
  // Tracking mode (the session's subject): the take tracked so far is stored.
  {
    auto p = spawn();
    ASSERT_EQ(p->post("/api/mode", R"({"mode": "tracking"})"), 202);
    ASSERT_TRUE(p->wait_until([](auto& s) {
      return s["state"] == "tracking" && s["tracking"]["frames"].template get<int>() >= 40;
    }));
    EXPECT_EQ(p->terminate(), 0) << "tracking";
    expect_store_consistent();
    auto store = open_store();
    ASSERT_TRUE(store);
    auto subjects = store->subjects();
    ASSERT_TRUE(subjects);
    std::size_t takes = 0;
    for (const auto& subject : *subjects)
      if (auto t = store->takes(subject.id)) takes += t->size();
    EXPECT_EQ(takes, 1u);
  }
}

}  // namespace
}  // namespace fb
