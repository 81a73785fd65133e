/// @brief The real sculptd (Scene + Server) in the test process on a loopback port and a fresh
/// data directory, restartable, with clients that have said Hello and joined. Shared by the
/// integration tests that talk to a server through sculpt::client.
#ifndef SCULPT_TESTS_INTEGRATION_IN_PROCESS_SERVER_H_
#define SCULPT_TESTS_INTEGRATION_IN_PROCESS_SERVER_H_

#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "config/server_config.h"
#include "net/server.h"
#include "scene/scene.h"
#include "sculpt/client/client.h"

namespace sculpt::testing_support {

class InProcessServer {
 public:
  /// A fresh directory named after `tag`, the process and the running test; config defaults
  /// with its data directory inside and listen on an ephemeral loopback port.
  explicit InProcessServer(const std::string& tag) {
    dir_ = std::filesystem::temp_directory_path() /
           ("sculpt_" + tag + "_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    config_.data_dir = (dir_ / "data").string();
    config_.listen = "127.0.0.1:0";
  }
  ~InProcessServer() {
    Stop();
    std::filesystem::remove_all(dir_);
  }
  InProcessServer(const InProcessServer&) = delete;
  InProcessServer& operator=(const InProcessServer&) = delete;

  /// Opens the scene (recovering from the data directory) and listens; a new port each time.
  ::testing::AssertionResult Start() {
    io_ = std::make_unique<server::asio::io_context>();
    auto scene = server::Scene::Open(config_);
    if (!scene.ok()) return ::testing::AssertionFailure() << scene.status().ToString();
    scene_ = std::move(scene).value();
    server_ = std::make_unique<server::Server>(*io_, config_, *scene_);
    auto port = server_->Start();
    if (!port.ok()) return ::testing::AssertionFailure() << port.status().ToString();
    port_ = *port;
    io_thread_ = std::thread([io = io_.get()] { io->run(); });
    return ::testing::AssertionSuccess();
  }

  void Stop() {
    if (server_) server_->Stop();
    if (io_) io_->stop();
    if (io_thread_.joinable()) io_thread_.join();
    server_.reset();
    scene_.reset();
    // The io_context outlives its server: handlers of the stopped server may still be queued.
    if (io_) old_io_.push_back(std::move(io_));
  }

  /// A client that has said Hello (development tokens) and joined the default scene.
  std::unique_ptr<client::Client> Joined(v1::Role role, bool skip_state = false,
                                         const std::string& name = "t", uint64_t client_id = 0) {
    client::ClientOptions options;
    options.timeout = std::chrono::seconds(10);
    options.skip_state = skip_state;
    auto c = std::make_unique<client::Client>(options);
    EXPECT_TRUE(c->Connect("127.0.0.1", port_).ok());
    auto w = c->Hello(role == v1::ROLE_SCULPTOR ? config_.sculptor_token : config_.viewer_token,
                      role, name, client_id);
    EXPECT_TRUE(w.ok()) << w.status();
    auto j = c->Join();
    EXPECT_TRUE(j.ok()) << j.status();
    return c;
  }

  server::ServerConfig& config() { return config_; }
  server::Scene& scene() { return *scene_; }
  server::Server& server() { return *server_; }
  uint16_t port() const { return port_; }
  const std::filesystem::path& dir() const { return dir_; }

 private:
  std::filesystem::path dir_;
  server::ServerConfig config_;
  std::unique_ptr<server::asio::io_context> io_;
  std::vector<std::unique_ptr<server::asio::io_context>> old_io_;
  std::unique_ptr<server::Scene> scene_;
  std::unique_ptr<server::Server> server_;
  std::thread io_thread_;
  uint16_t port_ = 0;
};

/// A press stroke along a horizontal circle at height z, one world unit inside the default
/// sphere (radius 24), poses 0.5 apart; stroke `i` continues where stroke i - 1 ended.
inline client::StrokeRequest PressArc(double z, int i, int poses = 4) {
  client::StrokeRequest s;
  s.object = "clay";
  s.kind = v1::EDIT_KIND_PRESS;
  s.tool = v1::TOOL_KIND_SPHERE;
  s.tool_size = {2.5, 0, 0};
  s.speed = 60;
  s.t0_ms = static_cast<uint64_t>(i) * 33;
  const double r = std::sqrt(23.0 * 23.0 - z * z);
  for (int k = 0; k < poses; ++k) {
    const double a = (i * poses + k) * 0.5 / r;
    codec::Pose p;
    p.position = {r * std::cos(a), r * std::sin(a), z};
    p.t_ms = static_cast<uint32_t>(k * 8);
    s.poses.push_back(p);
  }
  return s;
}

}  // namespace sculpt::testing_support

#endif  // SCULPT_TESTS_INTEGRATION_IN_PROCESS_SERVER_H_
