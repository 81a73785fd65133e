/// @brief The real sculptd (Scene + Server) in the test process for tests that speak the wire
/// protocol through RawClient: a fresh data directory named after the test, loopback on an
/// ephemeral port, two I/O threads; stoppable and restartable.
#ifndef SCULPT_TESTS_INTEGRATION_RAW_SERVER_H_
#define SCULPT_TESTS_INTEGRATION_RAW_SERVER_H_

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "net/server.h"
#include "scene/scene.h"

namespace sculpt::testing {

class RawServerTest : public ::testing::Test {
 protected:
  /// A fresh directory `<tag>_<test>_<pid>`; the configuration listens on 127.0.0.1:0 with its
  /// data directory inside and the two shared tokens, the default object of radius 12.
  void Prepare(const std::string& tag, const std::string& sculptor_token,
               const std::string& viewer_token) {
    dir_ = std::filesystem::temp_directory_path() /
           (tag + "_" + ::testing::UnitTest::GetInstance()->current_test_info()->name() + "_" +
            std::to_string(::getpid()));
    std::filesystem::remove_all(dir_);
    config_.listen = "127.0.0.1:0";
    config_.data_dir = (dir_ / "data").string();
    config_.sculptor_token = sculptor_token;
    config_.viewer_token = viewer_token;
    config_.scene.objects[0].radius = 12;
  }
  /// Opens the scene (recovering from the data directory) and listens; a new port each time.
  void Start() {
    auto scene = server::Scene::Open(config_);
    ASSERT_TRUE(scene.ok()) << scene.status();
    scene_ = std::move(scene).value();
    server_ = std::make_unique<server::Server>(io_, config_, *scene_);
    auto port = server_->Start();
    ASSERT_TRUE(port.ok()) << port.status();
    port_ = *port;
    guard_.emplace(io_.get_executor());
    for (int i = 0; i < 2; ++i) threads_.emplace_back([this] { io_.run(); });
  }
  /// Stops listening, flushes the scene and joins the I/O threads; Start() may follow.
  void Stop() {
    if (!server_) return;
    server_->Stop();
    scene_->Flush();
    guard_.reset();
    io_.stop();
    for (auto& t : threads_) t.join();
    threads_.clear();
    server_.reset();
    scene_.reset();
    io_.restart();
  }
  void TearDown() override {
    Stop();
    std::filesystem::remove_all(dir_);
  }

  std::filesystem::path dir_;
  server::ServerConfig config_;
  server::asio::io_context io_;
  std::optional<server::asio::executor_work_guard<server::asio::io_context::executor_type>> guard_;
  std::vector<std::thread> threads_;
  std::unique_ptr<server::Scene> scene_;
  std::unique_ptr<server::Server> server_;
  uint16_t port_ = 0;
};

}  // namespace sculpt::testing

#endif  // SCULPT_TESTS_INTEGRATION_RAW_SERVER_H_
