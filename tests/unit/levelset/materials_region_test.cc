// Replication of material fractions (issue 7): leaf records carry the fraction grids' cells
// (SLR2) when materials are declared, leaf hashes cover them, replicas converge, and records
// with fractions off the simplex or for another material count are refused unapplied.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "levelset/sculpture_impl.h"
#include "sculpt/levelset/edit.h"
#include "sculpt/levelset/materials.h"
#include "sculpt/levelset/region.h"

namespace sculpt::levelset {
namespace {

const std::vector<MaterialDecl> kDecls = {{"clay"}, {"wax"}, {"stone"}};

SculptureOptions Options() {
  SculptureOptions o;
  o.voxel_size = 1.0;
  o.half_width = 4;
  o.name = "clay";
  return o;
}

Sculpture PaintedSphere() {
  Sculpture s = std::move(Sculpture::MakeSphere(Options(), {0, 0, 0}, 16)).value();
  EXPECT_TRUE(SetMaterials(s, kDecls).ok());
  EXPECT_TRUE(PaintMaterial(s, ToolShape::Sphere({0, 0, 16}, 6), 1, 0.6).ok());
  EXPECT_TRUE(PaintMaterial(s, ToolShape::Sphere({4, 0, 15}, 4), 2, 0.5).ok());
  return s;
}

Sculpture EmptyReplica() {
  Sculpture r = MakeEmptySculpture(Options()).value();
  EXPECT_TRUE(SetMaterials(r, kDecls).ok());
  return r;
}

const VoxelBox kAll{{-40, -40, -40}, {40, 40, 40}};

// A server whose fraction grids hold `values` at voxel (1, 2, 3): written behind the API's back
// (what a corrupt or hostile sender could put in its records).
std::string RecordsWithVector(const std::vector<float>& values) {
  Sculpture server = PaintedSphere();
  for (size_t m = 0; m < values.size(); ++m) {
    server.impl().fractions[m]->tree().setValueOn(openvdb::Coord(1, 2, 3), values[m]);
  }
  return EncodeLeafRecords(server, {{0, 0, 0}}, nullptr);
}

class MaterialsRegionTest : public ::testing::Test {};

TEST_F(MaterialsRegionTest, LeafRecordsRebuildTheFractionsExactly) {
  const Sculpture server = PaintedSphere();
  Sculpture replica = EmptyReplica();
  const std::vector<Int3> cells = OccupiedLeafCells(server, kAll);
  const std::string bytes = EncodeLeafRecords(server, cells, nullptr);
  auto r = ApplyLeafRecords(replica, bytes);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(RegionHash(replica, kAll), RegionHash(server, kAll));
  EXPECT_EQ(LeavesHash(replica, cells), LeavesHash(server, cells));
  EXPECT_EQ(FractionsAtVoxel(replica, {0, 0, 15}).value(),
            FractionsAtVoxel(server, {0, 0, 15}).value());
  EXPECT_EQ(FractionsAtVoxel(replica, {0, 0, 0}).value(), (std::vector<double>{1, 0, 0}));
  EXPECT_TRUE(CheckSimplex(replica).Ok());
}

TEST_F(MaterialsRegionTest, LeavesHashSeesAPaintThatLeftTheSdfAlone) {
  Sculpture s = PaintedSphere();
  const std::vector<Int3> cells = OccupiedLeafCells(s, kAll);
  const uint64_t before = LeavesHash(s, cells);
  const uint64_t region = RegionHash(s, kAll);
  ASSERT_TRUE(PaintMaterial(s, ToolShape::Sphere({0, 16, 0}, 3), 2, 1.0).ok());
  EXPECT_EQ(RegionHash(s, kAll), region);  // the SDF did not change
  EXPECT_NE(LeavesHash(s, cells), before);
}

TEST_F(MaterialsRegionTest, LeafDeltasOfAnEditConvergeAReplica) {
  Sculpture server = PaintedSphere();
  Sculpture replica = server.Clone();
  EditRequest req;
  req.kind = EditKind::kInflate;
  req.tool = ToolShape::Sphere({0, 0, 16}, 4);
  req.amount = 2;
  auto a = ApplyEdit(server, req, EditSettings{});
  ASSERT_TRUE(a.ok());
  ASSERT_FALSE(a->dirty_leaves.empty());
  EXPECT_NE(LeavesHash(server, a->dirty_leaves), LeavesHash(replica, a->dirty_leaves));
  auto r = ApplyLeafRecords(replica, EncodeLeafRecords(server, a->dirty_leaves, nullptr));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(LeavesHash(server, a->dirty_leaves), LeavesHash(replica, a->dirty_leaves));
  EXPECT_EQ(FractionsAtVoxel(replica, {0, 0, 17}).value(),
            FractionsAtVoxel(server, {0, 0, 17}).value());
}

TEST_F(MaterialsRegionTest, ClearRegionResetsFractionsToTheFill) {
  Sculpture s = PaintedSphere();
  ClearRegion(s, kAll);
  EXPECT_EQ(FractionsAtVoxel(s, {0, 0, 15}).value(), (std::vector<double>{1, 0, 0}));
}

TEST_F(MaterialsRegionTest, RejectsRecordsForAnotherMaterialCount) {
  const Sculpture server = PaintedSphere();
  const std::string bytes = EncodeLeafRecords(server, OccupiedLeafCells(server, kAll), nullptr);
  Sculpture plain = MakeEmptySculpture(Options()).value();
  auto r = ApplyLeafRecords(plain, bytes);
  EXPECT_EQ(r.status().code(), Status::Code::kDataLoss);
  EXPECT_NE(r.status().message().find("magic=SLR2"), std::string::npos) << r.status().message();
  Sculpture two = MakeEmptySculpture(Options()).value();
  ASSERT_TRUE(SetMaterials(two, {{"a"}, {"b"}}).ok());
  auto t = ApplyLeafRecords(two, bytes);
  EXPECT_EQ(t.status().code(), Status::Code::kDataLoss);
  EXPECT_NE(t.status().message().find("materials=3 outside {2}"), std::string::npos)
      << t.status().message();
  EXPECT_EQ(two.ActiveVoxelCount(), 0u);
}

TEST_F(MaterialsRegionTest, RejectsRecordsWithFractionsOffTheSimplex) {
  Sculpture fresh = EmptyReplica();
  ASSERT_TRUE(ApplyLeafRecords(fresh, RecordsWithVector({0.25f, 0.25f, 0.5f})).ok());
  Sculpture target = EmptyReplica();
  auto sum = ApplyLeafRecords(target, RecordsWithVector({1.f, 0.5f, 0.f}));
  EXPECT_EQ(sum.status().code(), Status::Code::kDataLoss);
  EXPECT_NE(sum.status().message().find("fractions.sum=1.5 outside [0.999999, 1.000001]"),
            std::string::npos)
      << sum.status().message();
  auto nan = ApplyLeafRecords(target, RecordsWithVector({0.5f, 0.5f, std::nanf("")}));
  EXPECT_EQ(nan.status().code(), Status::Code::kDataLoss);
  EXPECT_NE(nan.status().message().find("fraction[2]=nan outside [0, 1]"), std::string::npos)
      << nan.status().message();
  auto neg = ApplyLeafRecords(target, RecordsWithVector({1.25f, -0.25f, 0.f}));
  EXPECT_EQ(neg.status().code(), Status::Code::kDataLoss);
  EXPECT_NE(neg.status().message().find("fraction[0]=1.25 outside [0, 1]"), std::string::npos)
      << neg.status().message();
  auto small = ApplyLeafRecords(target, RecordsWithVector({0.5f, 0.5f, 2e-6f}));
  EXPECT_EQ(small.status().code(), Status::Code::kDataLoss);
  EXPECT_EQ(target.ActiveVoxelCount(), 0u);  // nothing applied
  EXPECT_EQ(FractionsAtVoxel(target, {1, 2, 3}).value(), (std::vector<double>{1, 0, 0}));
}

}  // namespace
}  // namespace sculpt::levelset
