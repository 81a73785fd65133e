#include "net/frame_key.h"

#include <gtest/gtest.h>

#include "sculpt/codec/frame.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::server {
namespace {

std::string ChunkFrame(const std::string& object, int x, int y, int z, uint64_t version,
                       const std::string& draco = "draco-bytes") {
  v1::ServerMessage m;
  v1::MeshChunk* c = m.mutable_mesh_chunk();
  c->set_object(object);
  c->add_key(x);
  c->add_key(y);
  c->add_key(z);
  c->set_version(version);
  c->set_draco(draco);
  std::string f;
  codec::AppendMessage(m, &f);
  return f;
}

TEST(FrameKeyTest, SameChunkSameKeyWhateverTheVersion) {
  const std::string a = CoalescingKey(ChunkFrame("clay", 1, -2, 3, 10));
  EXPECT_FALSE(a.empty());
  EXPECT_EQ(a, CoalescingKey(ChunkFrame("clay", 1, -2, 3, 11, "")));
}

TEST(FrameKeyTest, OtherChunkOrObjectOtherKey) {
  const std::string a = CoalescingKey(ChunkFrame("clay", 1, -2, 3, 10));
  EXPECT_NE(a, CoalescingKey(ChunkFrame("clay", 1, 2, 3, 10)));
  EXPECT_NE(a, CoalescingKey(ChunkFrame("clay", -1, -2, 3, 10)));
  EXPECT_NE(a, CoalescingKey(ChunkFrame("rock", 1, -2, 3, 10)));
}

TEST(FrameKeyTest, OtherMessagesAreNeverCoalesced) {
  v1::ServerMessage m;
  m.mutable_ack()->set_client_seq(4);
  std::string f;
  codec::AppendMessage(m, &f);
  EXPECT_EQ(CoalescingKey(f), "");
  v1::ServerMessage p;
  p.mutable_presence();
  std::string g;
  codec::AppendMessage(p, &g);
  EXPECT_EQ(CoalescingKey(g), "");
}

TEST(FrameKeyTest, RejectsTruncatedFrame) {
  const std::string f = ChunkFrame("clay", 1, 2, 3, 10);
  for (size_t n = 0; n < 12 && n < f.size(); ++n) {
    EXPECT_EQ(CoalescingKey(f.substr(0, n)), "") << n;
  }
  EXPECT_EQ(CoalescingKey(std::string(64, '\xff')), "");
}

}  // namespace
}  // namespace sculpt::server
