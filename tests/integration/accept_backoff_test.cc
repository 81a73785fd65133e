// sculptd out of file descriptors: a real sculptd started with a low RLIMIT_NOFILE, more
// connections than it can accept. The acceptor must pause instead of spinning, log the
// condition once per interval, and accept again once descriptors are free.
#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "integration/raw_client.h"

extern char** environ;

namespace sculpt::server {
namespace {

namespace fs = std::filesystem;
using sculpt::testing::RawClient;

// User + system CPU seconds of `pid` so far (/proc/PID/stat fields 14 and 15).
double CpuSeconds(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string stat((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const size_t close = stat.rfind(')');
  if (close == std::string::npos) return -1;
  std::istringstream rest(stat.substr(close + 2));
  std::string field;
  long long utime = 0, stime = 0;
  for (int i = 3; i <= 15 && rest >> field; ++i) {
    if (i == 14) utime = std::stoll(field);
    if (i == 15) stime = std::stoll(field);
  }
  return static_cast<double>(utime + stime) / static_cast<double>(sysconf(_SC_CLK_TCK));
}

int OpenDescriptors(pid_t pid) {
  int n = 0;
  std::error_code ec;
  for (auto it = fs::directory_iterator("/proc/" + std::to_string(pid) + "/fd", ec);
       !ec && it != fs::directory_iterator(); it.increment(ec)) {
    ++n;
  }
  return n;
}

size_t CountLines(const fs::path& file, const std::string& needle) {
  std::ifstream in(file);
  size_t n = 0;
  for (std::string line; std::getline(in, line);) n += line.find(needle) != std::string::npos;
  return n;
}

class AcceptBackoffTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("sculptd_emfile_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    log_ = dir_ / "sculptd.log";
  }
  void TearDown() override {
    if (pid_ > 0) {
      kill(pid_, SIGKILL);
      int status = 0;
      waitpid(pid_, &status, 0);
    }
    if (!HasFailure()) fs::remove_all(dir_);
  }
  // sculptd under `ulimit -n nofile`; returns its TCP port (0 on failure).
  uint16_t Spawn(int nofile) {
    const fs::path port_file = dir_ / "port";
    const std::string cmd = "ulimit -n " + std::to_string(nofile) + " && exec " +
                            std::string(SCULPT_BIN_DIR) +
                            "/sculptd serve --listen 127.0.0.1:0 --http off --io-threads 2 "
                            "--auth-timeout-ms 60000 --data " +
                            (dir_ / "data").string() + " --port-file " + port_file.string();
    std::vector<std::string> args = {"/bin/sh", "-c", cmd};
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 1, log_.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
    posix_spawn_file_actions_addopen(&fa, 2, log_.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
    EXPECT_EQ(posix_spawn(&pid_, "/bin/sh", &fa, nullptr, argv.data(), environ), 0);
    posix_spawn_file_actions_destroy(&fa);
    for (int i = 0; i < 1000; ++i) {
      std::ifstream in(port_file);
      unsigned p = 0;
      if (in >> p && p > 0) return static_cast<uint16_t>(p);
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return 0;
  }

  fs::path dir_, log_;
  pid_t pid_ = -1;
};

TEST_F(AcceptBackoffTest, AcceptLoopPausesOnEmfileLogsOnceAndRecovers) {
  // Enough descriptors to start and serve a few clients, far fewer than the connections below.
  const uint16_t port = Spawn(48);
  ASSERT_GT(port, 0) << "sculptd did not start; see " << log_;
  const int at_rest = OpenDescriptors(pid_);
  ASSERT_GT(at_rest, 0);
  ASSERT_LT(at_rest, 44) << "the limit leaves no room for connections";
  // Each connection the server accepts takes a descriptor; those beyond the limit stay in the
  // backlog and every accept of them fails with EMFILE.
  std::vector<std::unique_ptr<RawClient>> clients;
  for (int i = 0; i < 64 - at_rest; ++i) clients.push_back(std::make_unique<RawClient>(port));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  const double cpu0 = CpuSeconds(pid_);
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  const double cpu = CpuSeconds(pid_) - cpu0;
  // A spinning acceptor burns a whole core (1.5 s here); paused, it wakes once a second.
  EXPECT_LT(cpu, 0.3) << "CPU seconds in 1.5 s while out of descriptors";
  EXPECT_GE(CountLines(log_, "failed accepts since the last report"), 1u);
  EXPECT_LE(CountLines(log_, "failed accepts since the last report"), 2u);
  EXPECT_LT(fs::file_size(log_), 64u << 10);
  // Descriptors free again: a new client is accepted (the pause is at most 1 s) and served.
  clients.clear();
  RawClient c(port);
  ASSERT_TRUE(c.Enter("sculpt-dev-sculptor", v1::ROLE_SCULPTOR)) << "see " << log_;
  c.Send(RawClient::PressStroke(1, {0, 0, 25.3}));
  EXPECT_TRUE(c.ReadUntil(v1::ServerMessage::kAck));
}

}  // namespace
}  // namespace sculpt::server
