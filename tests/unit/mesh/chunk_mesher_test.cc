#include "sculpt/mesh/chunk_mesher.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <map>

#include "sculpt/levelset/edit.h"
#include "sculpt/mesh/draco_chunk_codec.h"
#include "unit/mesh/mesh_test_util.h"

namespace sculpt::mesh {
namespace {

using testing::Append;
using testing::CheckClosed;
using testing::CutSphere;
using testing::SortedTriangles;
using testing::Sphere;

// Every chunk's mesh, keyed; chunks without faces left out.
std::map<ChunkKey, TriangleMesh> MeshChunks(const levelset::Sculpture& s,
                                            const std::vector<ChunkKey>& keys,
                                            const ChunkMeshOptions& options = {}) {
  std::map<ChunkKey, TriangleMesh> out;
  for (const ChunkKey& k : keys) {
    auto c = MeshChunk(s, k, options);
    EXPECT_TRUE(c.ok()) << c.status();
    if (c.ok() && !c->mesh.empty()) out[k] = std::move(c->mesh);
  }
  return out;
}

// Assembles the chunks and checks they hold exactly the whole-grid mesh's triangles, bit for bit.
void ExpectChunksAssembleToWhole(const levelset::Sculpture& s, const ChunkMeshOptions& options) {
  const TriangleMesh whole = MeshWhole(s);
  ASSERT_GT(whole.face_count(), 1000u);
  const auto chunks = MeshChunks(s, AllChunks(s, options), options);
  ASSERT_GT(chunks.size(), 8u);  // seams cross the surface
  TriangleMesh all;
  for (const auto& [k, m] : chunks) Append(m, &all);
  EXPECT_EQ(all.face_count(), whole.face_count());
  EXPECT_TRUE(SortedTriangles(all) == SortedTriangles(whole));
  const testing::Closure c = CheckClosed(all);
  EXPECT_EQ(c.edges_not_two, 0u);
  EXPECT_EQ(c.degenerate_faces, 0u);
}

TEST(ChunkMesherTest, SphereChunksAssembleToTheWholeMesh) {
  ExpectChunksAssembleToWhole(Sphere(40), {});
}

TEST(ChunkMesherTest, CutSphereChunksAssembleToTheWholeMesh) {
  ExpectChunksAssembleToWhole(CutSphere(40), {});
}

TEST(ChunkMesherTest, SmallChunksAssembleToTheWholeMesh) {
  ExpectChunksAssembleToWhole(CutSphere(24), ChunkMeshOptions{8});
}

// (a) of the brief: the chunks decoded from Draco, welded by exact quantised position, close.
TEST(ChunkMesherTest, DracoDecodedChunksWeldIntoAClosedMesh) {
  for (const bool cut : {false, true}) {
    const levelset::Sculpture s = cut ? CutSphere(40) : Sphere(40);
    DracoChunkOptions draco;
    auto frame = FrameAround(s, 4);
    ASSERT_TRUE(frame.ok()) << frame.status();
    draco.frame = *frame;
    draco.position_bits = 16;
    TriangleMesh all;
    for (const ChunkKey& k : AllChunks(s)) {
      auto c = MeshChunk(s, k);
      ASSERT_TRUE(c.ok()) << c.status();
      auto enc = EncodeChunk(c->mesh, draco);
      ASSERT_TRUE(enc.ok()) << enc.status();
      auto dec = DecodeChunk(enc->bytes);
      ASSERT_TRUE(dec.ok()) << dec.status();
      EXPECT_EQ(dec->mesh.face_count(), c->mesh.face_count());
      Append(dec->mesh, &all);
    }
    EXPECT_EQ(all.face_count(), MeshWhole(s).face_count()) << "cut=" << cut;
    const testing::Closure c = CheckClosed(all);
    EXPECT_GT(c.edges, 1000u);
    EXPECT_EQ(c.edges_not_two, 0u) << "cut=" << cut;
    EXPECT_EQ(c.degenerate_faces, 0u) << "cut=" << cut;
  }
}

// (c) of the brief: remeshing only the chunks an edit touched gives what remeshing all gives.
TEST(ChunkMesherTest, RemeshingTouchedChunksEqualsRemeshingAll) {
  levelset::Sculpture s = Sphere(40);
  auto chunks = MeshChunks(s, AllChunks(s));
  levelset::EditSettings settings;  // shell compensation: the edit reaches beyond the tool
  // Presses straddling the seam planes x = 32 and y = 0 near the surface.
  for (const Vec3 c : {Vec3{32.5, 0.5, 22.0}, Vec3{0.2, -30.0, 25.0}}) {
    levelset::EditRequest press;
    press.kind = levelset::EditKind::kPress;
    press.tool = levelset::ToolShape::Sphere(c, 5.0);
    press.speed = 10;
    press.dt = 0.2;
    auto r = levelset::ApplyEdit(s, press, settings);
    ASSERT_TRUE(r.ok()) << r.status();
    ASSERT_TRUE(r->changed);
    const std::vector<ChunkKey> touched = ChunksTouchedBy(r->dirty_leaves);
    ASSERT_FALSE(touched.empty());
    EXPECT_LT(touched.size(), AllChunks(s).size());
    for (const ChunkKey& k : touched) {
      auto m = MeshChunk(s, k);
      ASSERT_TRUE(m.ok()) << m.status();
      if (m->mesh.empty()) {
        chunks.erase(k);
      } else {
        chunks[k] = std::move(m->mesh);
      }
    }
  }
  const auto fresh = MeshChunks(s, AllChunks(s));
  ASSERT_EQ(chunks.size(), fresh.size());
  for (const auto& [k, m] : fresh) {
    ASSERT_TRUE(chunks.count(k)) << k.x << "," << k.y << "," << k.z;
    EXPECT_TRUE(SortedTriangles(chunks[k]) == SortedTriangles(m))
        << k.x << "," << k.y << "," << k.z;
  }
}

TEST(ChunkMesherTest, LeafNearASeamTouchesTheNeighbouringChunks) {
  // Leaf [24, 31] borders chunk 1 at x = 32; leaf [8, 15] is two voxels or more from every seam.
  const auto near = ChunksTouchedBy({{24, 8, 8}});
  EXPECT_EQ(near, (std::vector<ChunkKey>{{0, 0, 0}, {1, 0, 0}}));
  EXPECT_EQ(ChunksTouchedBy({{8, 8, 8}}), (std::vector<ChunkKey>{{0, 0, 0}}));
  const auto corner = ChunksTouchedBy({{-8, -8, -8}});
  EXPECT_EQ(corner.size(), 8u);  // the leaf at the origin's corner reaches all 8 chunks there
}

TEST(ChunkMesherTest, AllChunksListsEveryChunkWithSurfaceAndFewWithout) {
  const levelset::Sculpture s = CutSphere(40);
  const auto keys = AllChunks(s);
  size_t with_surface = 0, listed_empty = 0;
  // Every chunk of the block around the object: a chunk with faces must be listed.
  for (int z = -3; z <= 2; ++z) {
    for (int y = -3; y <= 2; ++y) {
      for (int x = -3; x <= 2; ++x) {
        auto m = MeshChunk(s, {x, y, z});
        ASSERT_TRUE(m.ok());
        const bool listed = std::binary_search(keys.begin(), keys.end(), ChunkKey{x, y, z});
        if (!m->mesh.empty()) {
          ++with_surface;
          EXPECT_TRUE(listed) << x << "," << y << "," << z;
        } else {
          listed_empty += listed;
        }
      }
    }
  }
  EXPECT_GT(with_surface, 30u);
  EXPECT_LE(listed_empty, with_surface / 2);
}

TEST(ChunkMesherTest, RejectsChunkKeyOutOfRange) {
  const levelset::Sculpture s = Sphere(10);
  auto m = MeshChunk(s, {0, kMaxChunkKey + 1, 0});
  ASSERT_FALSE(m.ok());
  EXPECT_EQ(m.status().code(), Status::Code::kInvalidArgument);
  EXPECT_NE(m.status().message().find("ChunkKey.y=1048577"), std::string::npos)
      << m.status();
}

TEST(ChunkMesherTest, RejectsChunkSizeNotAMultipleOfTheLeaf) {
  const levelset::Sculpture s = Sphere(10);
  auto m = MeshChunk(s, {0, 0, 0}, ChunkMeshOptions{20});
  ASSERT_FALSE(m.ok());
  EXPECT_NE(m.status().message().find("chunk_voxels=20"), std::string::npos) << m.status();
  EXPECT_FALSE(MeshChunk(s, {0, 0, 0}, ChunkMeshOptions{512}).ok());
  EXPECT_TRUE(ChunksTouchedBy({{0, 0, 0}}, ChunkMeshOptions{0}).empty());
}

}  // namespace
}  // namespace sculpt::mesh
