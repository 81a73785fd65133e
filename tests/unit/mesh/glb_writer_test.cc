#include "sculpt/mesh/glb_writer.h"

#include <draco/io/gltf_decoder.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <string>

#include "sculpt/mesh/chunk_mesher.h"
#include "unit/mesh/mesh_test_util.h"

namespace sculpt::mesh {
namespace {

std::filesystem::path TempPath(const std::string& name) {
  return std::filesystem::temp_directory_path() /
         ("sculpt_glb_" + std::to_string(::getpid()) + "_" + name);
}

uint32_t U32(const std::string& b, size_t at) {
  uint32_t v = 0;
  std::memcpy(&v, b.data() + at, 4);
  return v;  // glTF is little-endian, as is this machine
}

TEST(GlbWriterTest, DracoGltfDecoderReadsTheFaces) {
  const levelset::Sculpture s = testing::CutSphere(24);
  const auto path = TempPath("cut.glb");
  auto stats = WriteGlb(s, path.string());
  ASSERT_TRUE(stats.ok()) << stats.status();
  EXPECT_EQ(stats->triangles, MeshWhole(s).face_count());
  draco::GltfDecoder decoder;
  auto mesh = decoder.DecodeFromFile(path.string());
  ASSERT_TRUE(mesh.ok()) << mesh.status().error_msg();
  EXPECT_EQ(mesh.value()->num_faces(), stats->triangles);
  std::filesystem::remove(path);
}

// The GLB's faces, as a glTF viewer reads them, enclose the sculpture's volume with positive sign
// (counter-clockwise front faces): it was inside out, -57,702 against the PLY's +57,702.
TEST(GlbWriterTest, FacesAreWoundOutward) {
  const levelset::Sculpture s = testing::Sphere(20);
  const auto path = TempPath("wound.glb");
  ASSERT_TRUE(WriteGlb(s, path.string()).ok());
  draco::GltfDecoder decoder;
  auto decoded = decoder.DecodeFromFile(path.string());
  ASSERT_TRUE(decoded.ok()) << decoded.status().error_msg();
  const draco::Mesh& m = *decoded.value();
  const draco::PointAttribute* pos = m.GetNamedAttribute(draco::GeometryAttribute::POSITION);
  ASSERT_NE(pos, nullptr);
  double volume = 0;
  for (draco::FaceIndex f(0); f < m.num_faces(); ++f) {
    std::array<std::array<float, 3>, 3> p;
    for (int c = 0; c < 3; ++c) pos->GetMappedValue(m.face(f)[c], p[c].data());
    const auto& [a, b, q] = p;
    volume += (double(a[0]) * (double(b[1]) * q[2] - double(b[2]) * q[1]) +
               double(a[1]) * (double(b[2]) * q[0] - double(b[0]) * q[2]) +
               double(a[2]) * (double(b[0]) * q[1] - double(b[1]) * q[0])) / 6.0;
  }
  EXPECT_GT(volume, 0.0);
  EXPECT_NEAR(volume, s.volume(), 0.02 * s.volume());
  std::filesystem::remove(path);
}

TEST(GlbWriterTest, JsonChunkNamesKhrDracoMeshCompression) {
  const auto path = TempPath("ball.glb");
  auto stats = WriteGlb(testing::Sphere(16), path.string());
  ASSERT_TRUE(stats.ok()) << stats.status();
  std::ifstream in(path, std::ios::binary);
  const std::string b((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ASSERT_GE(b.size(), 20u);
  EXPECT_EQ(U32(b, 0), 0x46546C67u);  // "glTF"
  EXPECT_EQ(U32(b, 4), 2u);           // version
  EXPECT_EQ(U32(b, 8), b.size());     // total length
  const uint32_t json_len = U32(b, 12);
  EXPECT_EQ(U32(b, 16), 0x4E4F534Au);  // "JSON"
  ASSERT_LE(20u + json_len, b.size());
  const auto json = nlohmann::json::parse(b.substr(20, json_len));
  ASSERT_TRUE(json.contains("extensionsUsed"));
  bool named = false;
  for (const auto& e : json["extensionsUsed"]) named = named || e == "KHR_draco_mesh_compression";
  EXPECT_TRUE(named) << json["extensionsUsed"].dump();
  EXPECT_EQ(json["asset"]["version"], "2.0");
  // The primitive carries the extension (Draco-compressed, not a plain accessor mesh).
  const auto& prim = json["meshes"][0]["primitives"][0];
  EXPECT_TRUE(prim["extensions"].contains("KHR_draco_mesh_compression")) << prim.dump();
  std::filesystem::remove(path);
}

TEST(GlbWriterTest, RejectsAnotherExtension) {
  auto r = WriteGlb(testing::Sphere(8), TempPath("ball.gltf").string());
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("extension=.gltf"), std::string::npos) << r.status();
}

TEST(GlbWriterTest, RejectsBadOptions) {
  GlbOptions o;
  o.compression_level = 11;
  auto r = WriteGlb(testing::Sphere(8), TempPath("x.glb").string(), o);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("compression_level=11 outside [0, 10]"),
            std::string::npos)
      << r.status();
}

}  // namespace
}  // namespace sculpt::mesh
