// kill -9 of sculptd at random moments while a client streams strokes, 20 times: after every
// restart each acknowledged stroke is in the log, and the recovered state equals a replay of
// the log from scratch.
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <set>
#include <thread>

#include "integration/raw_client.h"
#include "scene/scene.h"
#include "store/edit_log.h"

extern char** environ;

namespace sculpt::server {
namespace {

namespace fs = std::filesystem;
using sculpt::testing::RawClient;

class Daemon {
 public:
  Daemon(const fs::path& data, const fs::path& port_file) : port_file_(port_file) {
    fs::remove(port_file_);
    const std::string bin = std::string(SCULPT_BIN_DIR) + "/sculptd";
    std::vector<std::string> args = {bin,      "serve",       "--listen",
                                     "127.0.0.1:0", "--data",  data.string(),
                                     "--port-file", port_file.string(), "--fsync",
                                     "group",   "--snapshot-every", "300"};
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
    posix_spawn_file_actions_addopen(&fa, 2, "/dev/null", O_WRONLY, 0);
    EXPECT_EQ(posix_spawn(&pid_, bin.c_str(), &fa, nullptr, argv.data(), environ), 0);
    posix_spawn_file_actions_destroy(&fa);
  }
  uint16_t WaitPort() {
    for (int i = 0; i < 500; ++i) {
      std::ifstream in(port_file_);
      unsigned p = 0;
      if (in >> p && p > 0) return static_cast<uint16_t>(p);
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return 0;
  }
  void Kill(int sig) {
    if (pid_ <= 0) return;
    kill(pid_, sig);
    int status = 0;
    waitpid(pid_, &status, 0);
    pid_ = -1;
  }
  ~Daemon() { Kill(SIGKILL); }

 private:
  fs::path port_file_;
  pid_t pid_ = -1;
};

TEST(CrashTest, KillNineTwentyTimesLosesNoAcknowledgedEdit) {
  const fs::path dir = fs::temp_directory_path() / ("sculptd_crash_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path data = dir / "data";
  std::mt19937 rng(20261121);
  std::uniform_int_distribution<int> life_ms(30, 250);
  constexpr uint64_t kClientId = 4242;
  std::set<uint64_t> acked;
  uint64_t next_seq = 1;
  for (int round = 0; round < 20; ++round) {
    Daemon d(data, dir / "port");
    const uint16_t port = d.WaitPort();
    ASSERT_NE(port, 0) << "round " << round << ": sculptd did not start";
    RawClient c(port);
    ASSERT_TRUE(c.Enter("sculpt-dev-sculptor", v1::ROLE_SCULPTOR, kClientId)) << round;
    // Stream from a reader thread's point of view: write strokes back to back, collect acks
    // until the kill cuts the connection.
    const auto deadline =
        std::chrono::steady_clock::now() + std::chrono::milliseconds(life_ms(rng));
    std::thread killer([&] {
      std::this_thread::sleep_until(deadline);
      d.Kill(SIGKILL);
    });
    c.SetTimeoutMs(100);
    while (std::chrono::steady_clock::now() < deadline) {
      const double a = 0.013 * static_cast<double>(next_seq);
      if (!c.Send(RawClient::PressStroke(next_seq, {12.8 * std::cos(a), 12.8 * std::sin(a),
                                                    6 * std::sin(3 * a)},
                                         2))) {
        break;
      }
      ++next_seq;
      while (auto m = c.Read()) {
        if (m->has_ack()) acked.insert(m->ack().client_seq());
        if (m->has_ack() || m->has_error()) break;
      }
    }
    killer.join();
    while (auto m = c.Read()) {
      if (m->has_ack()) acked.insert(m->ack().client_seq());
    }
  }
  ASSERT_GT(acked.size(), 50u);

  // Every acknowledged stroke is in the log (both of its poses).
  std::map<uint64_t, int> poses_logged;
  {
    store::RecoveryReport report;
    auto log = store::EditLog::Open((data / "log").string(), store::FsyncPolicy{}, &report);
    ASSERT_TRUE(log.ok()) << log.status();
    ASSERT_TRUE((*log)
                    ->ForEachFrom(0,
                                  [&](const store::LogRecord& r) {
                                    v1::EditRecord e;
                                    EXPECT_TRUE(e.ParseFromString(r.payload));
                                    if (e.client_id() == kClientId) ++poses_logged[e.client_seq()];
                                    return Status::Ok();
                                  })
                    .ok());
  }
  for (uint64_t s : acked) EXPECT_EQ(poses_logged[s], 2) << "acknowledged stroke " << s;

  // The recovered state (newest snapshot + tail) equals a replay of the whole log.
  ServerConfig config;
  config.data_dir = data.string();
  uint64_t recovered = 0;
  {
    auto scene = Scene::Open(config);
    ASSERT_TRUE(scene.ok()) << scene.status();
    recovered = (*scene)->StateHash("clay");
  }
  fs::remove_all(data / "snapshots");
  {
    auto scene = Scene::Open(config);
    ASSERT_TRUE(scene.ok()) << scene.status();
    EXPECT_EQ((*scene)->StateHash("clay"), recovered);
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace sculpt::server
