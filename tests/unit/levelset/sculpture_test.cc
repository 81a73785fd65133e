#include "sculpt/levelset/sculpture.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>

namespace sculpt::levelset {
namespace {

SculptureOptions Opts(double dx = 1.0, int hw = 6) {
  SculptureOptions o;
  o.voxel_size = dx;
  o.half_width = hw;
  o.name = "test";
  return o;
}

std::string TempPath(const std::string& name) {
  return (std::filesystem::temp_directory_path() / ("sculpt_test_" + name)).string();
}

TEST(SculptureTest, SphereVolumeMatchesAnalytic) {
  auto s = Sculpture::MakeSphere(Opts(0.5), {1, 2, 3}, 10.0);
  ASSERT_TRUE(s.ok()) << s.status();
  const double exact = 4.0 / 3.0 * M_PI * 1000.0;
  EXPECT_NEAR(s->volume(), exact, 0.003 * exact);
  EXPECT_DOUBLE_EQ(s->volume(), s->ComputeVolume());
  EXPECT_DOUBLE_EQ(s->reference_volume(), s->volume());
  EXPECT_TRUE(s->CheckLevelSet(9).ok()) << s->CheckLevelSet(9);
}

// The smoothed-Heaviside measure (eps = 1.5 voxels) carries a bias of order (eps * curvature)^2,
// so primitives are checked at a resolution where their features span many voxels.
TEST(SculptureTest, BoxCapsuleTorusVolumesMatchAnalytic) {
  auto box = Sculpture::MakeBox(Opts(0.25), {-4, -3, -2}, {4, 3, 2});
  ASSERT_TRUE(box.ok()) << box.status();
  EXPECT_NEAR(box->volume(), 8 * 6 * 4, 0.015 * 192);
  EXPECT_TRUE(box->CheckLevelSet().ok());

  auto cap = Sculpture::MakeCapsule(Opts(0.25), {0, 0, -5}, {0, 0, 5}, 3.0);
  ASSERT_TRUE(cap.ok()) << cap.status();
  const double vcap = M_PI * 9 * 10 + 4.0 / 3.0 * M_PI * 27;
  EXPECT_NEAR(cap->volume(), vcap, 0.01 * vcap);

  auto torus = Sculpture::MakeTorus(Opts(0.25), {0, 0, 0}, 6.0, 2.0);
  ASSERT_TRUE(torus.ok()) << torus.status();
  const double vtorus = 2 * M_PI * M_PI * 6.0 * 4.0;
  EXPECT_NEAR(torus->volume(), vtorus, 0.01 * vtorus);
  EXPECT_TRUE(torus->CheckLevelSet().ok());
}

TEST(SculptureTest, RejectsBadPrimitiveParameters) {
  auto nan_r = Sculpture::MakeSphere(Opts(), {0, 0, 0}, std::nan(""));
  ASSERT_FALSE(nan_r.ok());
  EXPECT_NE(nan_r.status().message().find("sphere.radius=nan"), std::string::npos)
      << nan_r.status();
  auto neg = Sculpture::MakeSphere(Opts(), {0, 0, 0}, -2);
  ASSERT_FALSE(neg.ok());
  EXPECT_NE(neg.status().message().find("sphere.radius=-2 outside"), std::string::npos);
  auto zero_dx = Sculpture::MakeSphere(Opts(0.0), {0, 0, 0}, 5);
  ASSERT_FALSE(zero_dx.ok());
  EXPECT_NE(zero_dx.status().message().find("voxel_size=0 outside"), std::string::npos);
  auto inf_c = Sculpture::MakeSphere(Opts(), {INFINITY, 0, 0}, 5);
  EXPECT_FALSE(inf_c.ok());
  auto thin_band = Sculpture::MakeSphere(Opts(1.0, 1), {0, 0, 0}, 5);
  ASSERT_FALSE(thin_band.ok());
  EXPECT_NE(thin_band.status().message().find("half_width=1"), std::string::npos);
  auto huge = Sculpture::MakeSphere(Opts(), {0, 0, 0}, 1e9);
  EXPECT_FALSE(huge.ok());
  auto torus = Sculpture::MakeTorus(Opts(), {0, 0, 0}, 3, 5);
  EXPECT_FALSE(torus.ok());
}

TEST(SculptureTest, VdbRoundTripKeepsHashAndMetadata) {
  auto s = Sculpture::MakeSphere(Opts(0.5), {0, 0, 0}, 6.0);
  ASSERT_TRUE(s.ok());
  s->set_reference_volume(123.5);
  const std::string path = TempPath("roundtrip.vdb");
  ASSERT_TRUE(s->SaveVdb(path).ok());
  auto back = Sculpture::LoadVdb(path);
  ASSERT_TRUE(back.ok()) << back.status();
  EXPECT_EQ(back->StateHash(), s->StateHash());
  EXPECT_EQ(back->name(), "test");
  EXPECT_DOUBLE_EQ(back->voxel_size(), 0.5);
  EXPECT_EQ(back->half_width(), 6);
  EXPECT_DOUBLE_EQ(back->reference_volume(), 123.5);
  EXPECT_DOUBLE_EQ(back->volume(), s->volume());
  std::filesystem::remove(path);
}

TEST(SculptureTest, SerializeRoundTripKeepsHash) {
  auto s = Sculpture::MakeSphere(Opts(0.5), {0, 0, 0}, 6.0);
  ASSERT_TRUE(s.ok());
  s->set_reference_volume(99.25);
  auto bytes = s->SerializeVdb();
  ASSERT_TRUE(bytes.ok()) << bytes.status();
  auto back = Sculpture::DeserializeVdb(*bytes);
  ASSERT_TRUE(back.ok()) << back.status();
  EXPECT_EQ(back->StateHash(), s->StateHash());
  EXPECT_DOUBLE_EQ(back->reference_volume(), 99.25);
  EXPECT_FALSE(Sculpture::DeserializeVdb(bytes->substr(0, bytes->size() / 2)).ok());
  EXPECT_FALSE(Sculpture::DeserializeVdb("garbage").ok());
}

TEST(SculptureTest, LoadRejectsMissingAndCorruptFiles) {
  EXPECT_EQ(Sculpture::LoadVdb(TempPath("missing.vdb")).status().code(), Status::Code::kNotFound);
  const std::string path = TempPath("corrupt.vdb");
  std::ofstream(path) << "not a vdb file";
  auto r = Sculpture::LoadVdb(path);
  EXPECT_FALSE(r.ok());
  std::filesystem::remove(path);
}

TEST(SculptureTest, StateHashIsCanonical) {
  auto a = Sculpture::MakeSphere(Opts(0.5), {0, 0, 0}, 6.0);
  auto b = Sculpture::MakeSphere(Opts(0.5), {0, 0, 0}, 6.0);
  auto c = Sculpture::MakeSphere(Opts(0.5), {0, 0, 0.25}, 6.0);
  auto d = Sculpture::MakeSphere(Opts(0.25), {0, 0, 0}, 6.0);
  EXPECT_EQ(a->StateHash(), b->StateHash());
  EXPECT_EQ(a->StateHash(), a->Clone().StateHash());
  EXPECT_NE(a->StateHash(), c->StateHash());
  EXPECT_NE(a->StateHash(), d->StateHash());
}

TEST(SculptureTest, MeshExportAndReimportPreserveShape) {
  auto s = Sculpture::MakeSphere(Opts(0.5), {0, 0, 0}, 8.0);
  ASSERT_TRUE(s.ok());
  const std::string ply = TempPath("sphere.ply");
  const std::string obj = TempPath("sphere.obj");
  auto mp = s->ExportMesh(ply);
  ASSERT_TRUE(mp.ok()) << mp.status();
  EXPECT_GT(mp->triangles, 1000u);
  auto mo = s->ExportMesh(obj);
  ASSERT_TRUE(mo.ok());
  EXPECT_EQ(mo->triangles, mp->triangles);
  for (const std::string& path : {ply, obj}) {
    auto back = Sculpture::FromMeshFile(Opts(0.5), path);
    ASSERT_TRUE(back.ok()) << back.status();
    // Outward winding: a reversed mesh would give an inverted (negative or tiny) volume.
    EXPECT_NEAR(back->volume(), s->volume(), 0.02 * s->volume()) << path;
  }
  // Counter-clockwise seen from outside: the divergence-theorem volume of the OBJ is positive.
  std::ifstream in(obj);
  std::vector<std::array<double, 3>> v;
  double signed_volume = 0;
  std::string tag;
  while (in >> tag) {
    if (tag == "v") {
      std::array<double, 3> p{};
      in >> p[0] >> p[1] >> p[2];
      v.push_back(p);
    } else if (tag == "f") {
      size_t a, b, c;
      in >> a >> b >> c;
      const auto &p = v[a - 1], &q = v[b - 1], &r = v[c - 1];
      signed_volume += (p[0] * (q[1] * r[2] - q[2] * r[1]) - p[1] * (q[0] * r[2] - q[2] * r[0]) +
                        p[2] * (q[0] * r[1] - q[1] * r[0])) /
                       6.0;
    } else {
      std::getline(in, tag);
    }
  }
  EXPECT_NEAR(signed_volume, s->volume(), 0.02 * s->volume());
  EXPECT_FALSE(s->ExportMesh(TempPath("sphere.stl")).ok());
  std::filesystem::remove(ply);
  std::filesystem::remove(obj);
}

TEST(SculptureTest, MeshImportRejectsMissingFile) {
  auto r = Sculpture::FromMeshFile(Opts(), TempPath("nope.obj"));
  EXPECT_EQ(r.status().code(), Status::Code::kNotFound);
}

TEST(SculptureTest, SampleWorldIsSignedDistance) {
  auto s = Sculpture::MakeSphere(Opts(0.5), {0, 0, 0}, 8.0);
  EXPECT_NEAR(s->SampleWorld({9, 0, 0}), 1.0, 0.05);
  EXPECT_NEAR(s->SampleWorld({0, 7, 0}), -1.0, 0.05);
  EXPECT_NEAR(s->SampleWorld({0, 0, 0}), -3.0, 1e-6);  // clamped at the band: 6 voxels * 0.5
}

}  // namespace
}  // namespace sculpt::levelset
