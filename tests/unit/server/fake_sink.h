/// @brief FakeSink: a session's end of a subscription for the scene collaborators' unit tests
/// (ReplicationHub, SkinBook): it keeps every frame it is sent, as the session would queue it,
/// and reads one back as the client would.
#ifndef SCULPT_TESTS_UNIT_SERVER_FAKE_SINK_H_
#define SCULPT_TESTS_UNIT_SERVER_FAKE_SINK_H_

#include <gtest/gtest.h>

#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "scene/replica_sink.h"
#include "sculpt/codec/frame.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::testing {

struct FakeSink {
  explicit FakeSink(uint64_t id) : session_id(id) {}
  uint64_t session_id = 0;
  std::vector<std::shared_ptr<const std::string>> frames;

  server::ReplicaSink sink() {
    server::ReplicaSink s;
    s.session_id = session_id;
    s.client_id = session_id + 100;
    s.send = [this](std::shared_ptr<const std::string> f) { frames.push_back(std::move(f)); };
    return s;
  }
  /// Frame `i` parsed as the client would parse it (an empty message, and a failure, otherwise).
  v1::ServerMessage Message(size_t i) const {
    v1::ServerMessage m;
    codec::FrameReader reader;
    reader.Feed(frames.at(i)->data(), frames.at(i)->size());
    auto payload = reader.Next();
    EXPECT_TRUE(payload.ok() && *payload);
    if (payload.ok() && *payload) {
      EXPECT_TRUE(m.ParseFromString(**payload));
    }
    return m;
  }
};

}  // namespace sculpt::testing

#endif  // SCULPT_TESTS_UNIT_SERVER_FAKE_SINK_H_
