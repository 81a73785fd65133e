/// @brief The real sculptd (Scene + Server, and the HTTP port when asked) in the test process for
/// tests that speak the wire protocol themselves (RawClient, WebSocket and TLS clients): a fresh
/// data directory named after the test, loopback on ephemeral ports, two I/O threads; stoppable
/// and restartable.
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

#include "net/http_server.h"
#include "net/server.h"
#include "scene/scene.h"

namespace sculpt::testing {

class RawServerTest : public ::testing::Test {
 protected:
  /// A fresh, empty directory `<tag>_<test>_<pid>`; the configuration listens on 127.0.0.1:0
  /// with its data directory inside.
  void Prepare(const std::string& tag) {
    dir_ = std::filesystem::temp_directory_path() /
           (tag + "_" + ::testing::UnitTest::GetInstance()->current_test_info()->name() + "_" +
            std::to_string(::getpid()));
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    config_.listen = "127.0.0.1:0";
    config_.data_dir = (dir_ / "data").string();
  }
  /// As above, with the two shared tokens and the default object of radius 12.
  void Prepare(const std::string& tag, const std::string& sculptor_token,
               const std::string& viewer_token) {
    Prepare(tag);
    config_.sculptor_token = sculptor_token;
    config_.viewer_token = viewer_token;
    config_.scene.objects[0].radius = 12;
  }
  /// Opens the scene (recovering from the data directory) and listens, on the HTTP port too when
  /// `with_http_`; new ports each time. The first failure, for tests of refused start-ups.
  Status TryStart() {
    auto scene = server::Scene::Open(config_);
    if (!scene.ok()) return scene.status();
    scene_ = std::move(scene).value();
    server_ = std::make_unique<server::Server>(io_, config_, *scene_);
    auto port = server_->Start();
    if (!port.ok()) return port.status();
    port_ = *port;
    if (with_http_) {
      http_ = std::make_unique<server::HttpServer>(io_, http_config_, *server_);
      auto hport = http_->Start();
      if (!hport.ok()) return hport.status();
      http_port_ = *hport;
    }
    guard_.emplace(io_.get_executor());
    for (int i = 0; i < 2; ++i) threads_.emplace_back([this] { io_.run(); });
    return Status::Ok();
  }
  void Start() {
    const Status s = TryStart();
    ASSERT_TRUE(s.ok()) << s;
  }
  /// Stops listening, flushes the scene and joins the I/O threads; Start() may follow.
  void Stop() {
    if (server_) server_->Stop();
    if (http_) http_->Stop();
    if (scene_) scene_->Flush();
    guard_.reset();
    io_.stop();
    for (auto& t : threads_) t.join();
    threads_.clear();
    // Handlers the stop left queued (the acceptor's aborted accept, closed sessions' reads) run
    // now, against the server they belong to; left queued, the next Start()'s threads would run
    // them against a destroyed one.
    io_.restart();
    io_.poll();
    http_.reset();
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
  server::HttpConfig http_config_;
  bool with_http_ = false;  // Start() opens the HTTP port (http_config_) too
  server::asio::io_context io_;
  std::optional<server::asio::executor_work_guard<server::asio::io_context::executor_type>> guard_;
  std::vector<std::thread> threads_;
  std::unique_ptr<server::Scene> scene_;
  std::unique_ptr<server::Server> server_;
  std::unique_ptr<server::HttpServer> http_;
  uint16_t port_ = 0;
  uint16_t http_port_ = 0;
};

}  // namespace sculpt::testing

#endif  // SCULPT_TESTS_INTEGRATION_RAW_SERVER_H_
