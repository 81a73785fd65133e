#include "net/session.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>

#include "net/server.h"
#include "sculpt/codec/frame.h"

namespace sculpt::server {
namespace {

namespace fs = std::filesystem;

// A transport whose reads never complete and whose writes complete only when the test says.
class FakeTransport final : public Transport {
 public:
  TransportKind kind() const override { return TransportKind::kWebSocket; }
  std::string remote() const override { return "fake"; }
  void AsyncRead(ReadHandler done) override { read_ = std::move(done); }
  void AsyncWrite(std::vector<Frame> frames, WriteHandler done) override {
    writes.push_back(std::move(frames));
    write_done_ = std::move(done);
  }
  void Close() override {
    closed = true;
    read_ = nullptr;
    write_done_ = nullptr;
  }
  // Completes the write in flight.
  void FinishWrite() {
    uint64_t bytes = 0;
    for (const Frame& f : writes.back()) bytes += f->size();
    auto done = std::move(write_done_);
    write_done_ = nullptr;
    done(Status::Ok(), bytes);
  }
  bool write_in_flight() const { return write_done_ != nullptr; }

  std::vector<std::vector<Frame>> writes;
  bool closed = false;

 private:
  ReadHandler read_;
  WriteHandler write_done_;
};

Frame Chunk(int x, uint64_t version) {
  v1::ServerMessage m;
  v1::MeshChunk* c = m.mutable_mesh_chunk();
  c->set_object("clay");
  c->add_key(x);
  c->add_key(0);
  c->add_key(0);
  c->set_version(version);
  c->set_draco(std::string(100, 'd'));
  auto f = std::make_shared<std::string>();
  codec::AppendMessage(m, f.get());
  return f;
}

uint64_t VersionOf(const Frame& f) {
  v1::ServerMessage m;
  EXPECT_TRUE(m.ParseFromArray(f->data() + 4, static_cast<int>(f->size() - 4)));
  return m.mesh_chunk().version();
}

class SessionTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("sculpt_session_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    config_.data_dir = (dir_ / "data").string();
    config_.scene.objects[0].radius = 6;
    config_.limits.auth_timeout_ms = 60000;
    auto scene = Scene::Open(config_);
    ASSERT_TRUE(scene.ok()) << scene.status();
    scene_ = std::move(scene).value();
    server_ = std::make_unique<Server>(io_, config_, *scene_);
    transport_ = std::make_shared<FakeTransport>();
    session_ = std::make_shared<Session>(*server_, asio::make_strand(io_), transport_, 1);
    session_->Start();
    io_.poll();
  }
  void TearDown() override {
    session_->Shutdown("test over");
    io_.poll();
    // A write left in flight waits for the Bye grace timer, which never fires here; closing drops
    // its handler (and the session it holds) as a real socket's close would.
    transport_->Close();
    session_.reset();
    server_.reset();
    scene_.reset();
    fs::remove_all(dir_);
  }

  fs::path dir_;
  ServerConfig config_;
  asio::io_context io_;
  std::unique_ptr<Scene> scene_;
  std::unique_ptr<Server> server_;
  std::shared_ptr<FakeTransport> transport_;
  std::shared_ptr<Session> session_;
};

TEST_F(SessionTest, SlowViewerGetsTheNewestChunkNotABacklog) {
  session_->DeliverFrame(Chunk(0, 1));
  io_.poll();
  ASSERT_EQ(transport_->writes.size(), 1u);
  ASSERT_TRUE(transport_->write_in_flight());
  // While the first write is stuck, chunk 0 changes three times and chunk 1 once.
  session_->DeliverFrame(Chunk(0, 2));
  session_->DeliverFrame(Chunk(1, 2));
  session_->DeliverFrame(Chunk(0, 3));
  session_->DeliverFrame(Chunk(0, 4));
  io_.poll();
  EXPECT_EQ(server_->stats().frames_superseded.load(), 2u);
  transport_->FinishWrite();
  io_.poll();
  ASSERT_EQ(transport_->writes.size(), 2u);
  const std::vector<Frame>& second = transport_->writes[1];
  ASSERT_EQ(second.size(), 2u);  // one slot per chunk, in first-queued order
  EXPECT_EQ(VersionOf(second[0]), 4u);
  EXPECT_EQ(VersionOf(second[1]), 2u);
  // Once handed to the transport a slot is free again: the next version queues anew.
  session_->DeliverFrame(Chunk(0, 5));
  io_.poll();
  transport_->FinishWrite();
  io_.poll();
  ASSERT_EQ(transport_->writes.size(), 3u);
  EXPECT_EQ(VersionOf(transport_->writes[2][0]), 5u);
}

TEST_F(SessionTest, OtherFramesAreNeverCoalesced) {
  session_->DeliverFrame(Chunk(0, 1));
  io_.poll();
  v1::ServerMessage m;
  m.mutable_leaf_delta();
  auto f = std::make_shared<std::string>();
  codec::AppendMessage(m, f.get());
  for (int i = 0; i < 3; ++i) session_->DeliverFrame(f);
  io_.poll();
  transport_->FinishWrite();
  io_.poll();
  ASSERT_EQ(transport_->writes.size(), 2u);
  EXPECT_EQ(transport_->writes[1].size(), 3u);
  EXPECT_EQ(server_->stats().frames_superseded.load(), 0u);
}

TEST_F(SessionTest, ShutdownSendsAByeThenCloses) {
  session_->DeliverPresence(Chunk(0, 1));  // not joined: no presence
  io_.poll();
  EXPECT_TRUE(transport_->writes.empty());
  session_->Shutdown("maintenance");
  io_.poll();
  ASSERT_EQ(transport_->writes.size(), 1u);
  v1::ServerMessage bye;
  const Frame& f = transport_->writes[0].at(0);
  ASSERT_TRUE(bye.ParseFromArray(f->data() + 4, static_cast<int>(f->size() - 4)));
  EXPECT_EQ(bye.bye().reason(), "maintenance");
  EXPECT_FALSE(transport_->closed);
  transport_->FinishWrite();
  io_.poll();
  EXPECT_TRUE(transport_->closed);
}

}  // namespace
}  // namespace sculpt::server
