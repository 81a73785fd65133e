/// @brief Unit tests for the shared replication frames: each parses back, as a client reads it,
/// into the ServerMessage with every field the encoder was given.
#include "sculpt/codec/replica_frames.h"

#include <gtest/gtest.h>

#include <cstring>
#include <string>

#include "sculpt/codec/frame.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::codec {
namespace {

// The one message a frame holds, parsed the way clients read frames; fails the test on a frame
// that is not exactly one length-prefixed ServerMessage.
v1::ServerMessage Parse(const SharedFrame& frame) {
  v1::ServerMessage m;
  EXPECT_TRUE(frame);
  if (!frame) return m;
  FrameReader reader;
  reader.Feed(frame->data(), frame->size());
  auto payload = reader.Next();
  EXPECT_TRUE(payload.ok());
  if (!payload.ok() || !*payload) {
    ADD_FAILURE() << "no complete frame";
    return m;
  }
  EXPECT_EQ(reader.buffered(), 0u) << "bytes after the frame";
  EXPECT_TRUE(m.ParseFromString(**payload));
  return m;
}

class ReplicaFramesTest : public ::testing::Test {};

TEST_F(ReplicaFramesTest, LeafDeltaOfOneEditCarriesItsAuthorAndNoRegion) {
  LeafDeltaFrame in;
  in.object = "clay";
  in.global_seq = 42;
  in.records = std::string("\x01\x00\x02", 3);
  in.record_count = 7;
  in.state = {1.5, 2.25, 9};
  in.client_id = 5;
  in.client_seq = 11;
  const v1::ServerMessage m = Parse(EncodeLeafDelta(in));
  ASSERT_TRUE(m.has_leaf_delta());
  const v1::LeafDelta& d = m.leaf_delta();
  EXPECT_EQ(d.object(), "clay");
  EXPECT_EQ(d.global_seq(), 42u);
  EXPECT_EQ(d.records(), in.records);
  EXPECT_EQ(d.record_count(), 7u);
  EXPECT_FALSE(d.replace_region());
  EXPECT_EQ(d.region_min_size(), 0);
  EXPECT_EQ(d.region_max_size(), 0);
  EXPECT_EQ(d.volume(), 1.5);
  EXPECT_EQ(d.reference_volume(), 2.25);
  EXPECT_EQ(d.edits_since_reinit(), 9u);
  EXPECT_EQ(d.client_id(), 5u);
  EXPECT_EQ(d.client_seq(), 11u);
}

TEST_F(ReplicaFramesTest, LeafDeltaOfARegionCarriesItsCornersAndReplaceFlag) {
  LeafDeltaFrame in;
  in.object = "clay";
  in.global_seq = 3;
  in.region = levelset::VoxelBox{{-8, -16, 0}, {7, 15, 23}};
  in.replace_region = true;
  const v1::ServerMessage m = Parse(EncodeLeafDelta(in));
  ASSERT_TRUE(m.has_leaf_delta());
  const v1::LeafDelta& d = m.leaf_delta();
  EXPECT_TRUE(d.replace_region());
  ASSERT_EQ(d.region_min_size(), 3);
  ASSERT_EQ(d.region_max_size(), 3);
  EXPECT_EQ(d.region_min(0), -8);
  EXPECT_EQ(d.region_min(1), -16);
  EXPECT_EQ(d.region_min(2), 0);
  EXPECT_EQ(d.region_max(0), 7);
  EXPECT_EQ(d.region_max(1), 15);
  EXPECT_EQ(d.region_max(2), 23);
  EXPECT_EQ(d.client_id(), 0u);
}

TEST_F(ReplicaFramesTest, EditBroadcastCarriesTheStrokeWithoutItsObject) {
  v1::Stroke stroke;
  stroke.set_object("clay");
  stroke.set_client_seq(17);
  stroke.set_amount(2.5f);
  const std::string bytes = stroke.SerializeAsString();
  EditBroadcastFrame in;
  in.object = "clay";
  in.global_seq_first = 100;
  in.stroke = bytes;
  in.client_id = 8;
  in.before = {10.0, 12.0, 4};
  in.leaves_hash = 0xfeedbeefcafe;
  in.dirty_leaves = 6;
  const v1::ServerMessage m = Parse(EncodeEditBroadcast(in));
  ASSERT_TRUE(m.has_edit());
  const v1::EditBroadcast& b = m.edit();
  EXPECT_EQ(b.object(), "clay");
  EXPECT_EQ(b.global_seq_first(), 100u);
  EXPECT_EQ(b.stroke().object(), "");
  EXPECT_EQ(b.stroke().client_seq(), 17u);
  EXPECT_EQ(b.stroke().amount(), 2.5f);
  EXPECT_EQ(b.client_id(), 8u);
  EXPECT_EQ(b.volume(), 10.0);
  EXPECT_EQ(b.reference_volume(), 12.0);
  EXPECT_EQ(b.edits_since_reinit(), 4u);
  EXPECT_EQ(b.leaves_hash(), 0xfeedbeefcafeu);
  EXPECT_EQ(b.dirty_leaves(), 6u);
}

TEST_F(ReplicaFramesTest, EditBroadcastOfUnparseableStrokeCarriesAnEmptyStroke) {
  EditBroadcastFrame in;
  in.object = "clay";
  const std::string junk("\xff\xff\xff", 3);
  in.stroke = junk;
  const v1::ServerMessage m = Parse(EncodeEditBroadcast(in));
  ASSERT_TRUE(m.has_edit());
  EXPECT_EQ(m.edit().stroke().ByteSizeLong(), 0u);
}

TEST_F(ReplicaFramesTest, MeshChunkCarriesKeyVersionAndDracoBytes) {
  MeshChunkFrame in;
  in.object = "clay";
  in.key[0] = -1;
  in.key[1] = 2;
  in.key[2] = -3;
  in.version = 77;
  in.chunk_voxels = 32;
  in.draco = std::string("DRACO\0\x01", 7);
  in.vertices = 120;
  in.faces = 236;
  in.encode_ms = 1.25f;
  const v1::ServerMessage m = Parse(EncodeMeshChunk(in));
  ASSERT_TRUE(m.has_mesh_chunk());
  const v1::MeshChunk& c = m.mesh_chunk();
  EXPECT_EQ(c.object(), "clay");
  ASSERT_EQ(c.key_size(), 3);
  EXPECT_EQ(c.key(0), -1);
  EXPECT_EQ(c.key(1), 2);
  EXPECT_EQ(c.key(2), -3);
  EXPECT_EQ(c.version(), 77u);
  EXPECT_EQ(c.chunk_voxels(), 32u);
  EXPECT_EQ(c.draco(), in.draco);
  EXPECT_EQ(c.vertices(), 120u);
  EXPECT_EQ(c.faces(), 236u);
  EXPECT_EQ(c.encode_ms(), 1.25f);
}

TEST_F(ReplicaFramesTest, EmptiedMeshChunkHasNoDracoBytes) {
  MeshChunkFrame in;
  in.object = "clay";
  in.version = 9;
  const v1::ServerMessage m = Parse(EncodeMeshChunk(in));
  ASSERT_TRUE(m.has_mesh_chunk());
  EXPECT_TRUE(m.mesh_chunk().draco().empty());
  EXPECT_EQ(m.mesh_chunk().key_size(), 3);
}

}  // namespace
}  // namespace sculpt::codec
