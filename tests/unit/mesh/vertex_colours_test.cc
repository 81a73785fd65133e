#include "sculpt/mesh/vertex_colours.h"

#include <draco/io/gltf_decoder.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>

#include "sculpt/levelset/materials.h"
#include "sculpt/mesh/chunk_mesher.h"
#include "sculpt/mesh/draco_chunk_codec.h"
#include "sculpt/mesh/glb_writer.h"
#include "unit/mesh/mesh_test_util.h"

namespace sculpt::mesh {
namespace {

const std::vector<levelset::MaterialDecl> kMaterials = {
    {"clay", {0.8, 0.5, 0.3}}, {"gold", {1.0, 0.85, 0.1}}, {"jade", {0.1, 0.7, 0.4}}};
// Where the paint goes: a ball of radius 6 voxels on the +x pole of the sphere (radius 16 voxels,
// voxel size 1, centre (0.3, -0.2, 0.1)).
const Vec3 kPaintCentre{16.3, -0.2, 0.1};
constexpr double kPaintRadius = 6;

levelset::Sculpture Painted() {
  levelset::Sculpture s = testing::Sphere(16);
  EXPECT_TRUE(levelset::SetMaterials(s, kMaterials).ok());
  auto p =
      levelset::PaintMaterial(s, levelset::ToolShape::Sphere(kPaintCentre, kPaintRadius), 1, 1.0);
  EXPECT_TRUE(p.ok()) << p.status();
  return s;
}

double Distance(const float* p, const Vec3& c) {
  return std::sqrt((p[0] - c.x) * (p[0] - c.x) + (p[1] - c.y) * (p[1] - c.y) +
                   (p[2] - c.z) * (p[2] - c.z));
}

// Checks a mesh's colours: in [0, 1]; gold well inside the paint, clay well outside it.
void ExpectPaintedColours(const TriangleMesh& m, double tolerance) {
  ASSERT_EQ(m.colours.size(), m.positions.size());
  int inside = 0, outside = 0;
  for (size_t v = 0; v < m.vertex_count(); ++v) {
    const float* c = &m.colours[3 * v];
    for (int k = 0; k < 3; ++k) {
      ASSERT_GE(c[k], 0.f);
      ASSERT_LE(c[k], 1.f);
    }
    const double d = Distance(&m.positions[3 * v], kPaintCentre);
    const auto& want = d < kPaintRadius - 2   ? kMaterials[1].colour
                       : d > kPaintRadius + 3 ? kMaterials[0].colour
                                              : std::array<double, 3>{-1, -1, -1};
    if (want[0] < 0) continue;
    (d < kPaintRadius ? inside : outside)++;
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(c[k], want[k], tolerance) << "vertex " << v;
  }
  EXPECT_GT(inside, 10);
  EXPECT_GT(outside, 100);
}

TEST(VertexColoursTest, MixesTheFractionsAtEachVertex) {
  const levelset::Sculpture s = Painted();
  TriangleMesh m = MeshWhole(s);
  ASSERT_TRUE(ColourVertices(s, &m).ok());
  ExpectPaintedColours(m, 1e-5);
}

TEST(VertexColoursTest, NoMaterialsNoColours) {
  const levelset::Sculpture s = testing::Sphere(16);
  TriangleMesh m = MeshWhole(s);
  m.colours = {0.5f};
  ASSERT_TRUE(ColourVertices(s, &m).ok());
  EXPECT_TRUE(m.colours.empty());
  auto f = FrameAround(s, 4);
  ASSERT_TRUE(f.ok());
  DracoChunkOptions o;
  o.frame = *f;
  auto e = EncodeChunk(m, o);
  ASSERT_TRUE(e.ok());
  auto d = DecodeChunk(e->bytes);
  ASSERT_TRUE(d.ok());
  EXPECT_TRUE(d->mesh.colours.empty());
}

TEST(VertexColoursTest, DracoChunkCarriesTheColours) {
  const levelset::Sculpture s = Painted();
  TriangleMesh m = MeshWhole(s);
  ASSERT_TRUE(ColourVertices(s, &m).ok());
  auto f = FrameAround(s, 4);
  ASSERT_TRUE(f.ok());
  DracoChunkOptions o;
  o.frame = *f;
  auto e = EncodeChunk(m, o);
  ASSERT_TRUE(e.ok()) << e.status();
  auto d = DecodeChunk(e->bytes);
  ASSERT_TRUE(d.ok()) << d.status();
  // 8-bit channels: within one step of 1/255 plus the position quantisation's shift.
  ExpectPaintedColours(d->mesh, 0.01);
}

TEST(VertexColoursTest, RejectsColoursOfTheWrongSizeOrOutOfRange) {
  const levelset::Sculpture s = Painted();
  TriangleMesh m = MeshWhole(s);
  ASSERT_TRUE(ColourVertices(s, &m).ok());
  auto f = FrameAround(s, 4);
  ASSERT_TRUE(f.ok());
  DracoChunkOptions o;
  o.frame = *f;
  TriangleMesh bad = m;
  bad.colours.pop_back();
  auto e = EncodeChunk(bad, o);
  ASSERT_FALSE(e.ok());
  EXPECT_NE(e.status().message().find("TriangleMesh.colours.size="), std::string::npos);
  bad = m;
  bad.colours[4] = 1.5f;
  e = EncodeChunk(bad, o);
  ASSERT_FALSE(e.ok());
  EXPECT_NE(e.status().message().find("TriangleMesh.colours[4]=1.5"), std::string::npos);
}

TEST(VertexColoursTest, GlbCarriesColour0) {
  const levelset::Sculpture s = Painted();
  const auto path = std::filesystem::temp_directory_path() /
                    ("sculpt_colours_" + std::to_string(::getpid()) + ".glb");
  ASSERT_TRUE(WriteGlb(s, path.string()).ok());
  draco::GltfDecoder decoder;
  auto mesh = decoder.DecodeFromFile(path.string());
  std::filesystem::remove(path);
  ASSERT_TRUE(mesh.ok()) << mesh.status().error_msg();
  const draco::PointAttribute* col =
      mesh.value()->GetNamedAttribute(draco::GeometryAttribute::COLOR);
  ASSERT_NE(col, nullptr);
  const draco::PointAttribute* pos =
      mesh.value()->GetNamedAttribute(draco::GeometryAttribute::POSITION);
  ASSERT_NE(pos, nullptr);
  TriangleMesh m;
  const uint32_t np = mesh.value()->num_points();
  m.positions.resize(3 * np);
  m.colours.resize(3 * np);
  for (uint32_t p = 0; p < np; ++p) {
    float rgba[4] = {0, 0, 0, 1};
    const draco::AttributeValueIndex pi = pos->mapped_index(draco::PointIndex(p));
    const draco::AttributeValueIndex ci = col->mapped_index(draco::PointIndex(p));
    const bool pos_ok = pos->ConvertValue<float, 3>(pi, &m.positions[3 * p]);
    const bool col_ok = col->num_components() == 3 ? col->ConvertValue<float, 3>(ci, rgba)
                                                   : col->ConvertValue<float, 4>(ci, rgba);
    ASSERT_TRUE(pos_ok && col_ok) << "point " << p;
    for (int c = 0; c < 3; ++c) m.colours[3 * p + c] = rgba[c];
  }
  ExpectPaintedColours(m, 0.01);
}

}  // namespace
}  // namespace sculpt::mesh
