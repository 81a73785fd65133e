// Figures for docs/benchmarks.md ("Viewer meshes"): chunk mesh, Draco encode and decode times and
// bytes on spheres of radius 64 and 128 voxels. Disabled in `make test` (it meshes a 308k-quad
// object several times); run with
//   mesh_unit_tests --gtest_also_run_disabled_tests --gtest_filter='*ChunkCodecFigures*'
// It prints one JSON line per case and asserts only that every chunk survives the round trip.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <vector>

#include "sculpt/levelset/edit.h"
#include "sculpt/mesh/chunk_mesher.h"
#include "sculpt/mesh/draco_chunk_codec.h"
#include "sculpt/mesh/glb_writer.h"

namespace sculpt::mesh {
namespace {

struct Dist {
  std::vector<double> v;
  nlohmann::json Json() {
    std::sort(v.begin(), v.end());
    double sum = 0;
    for (double x : v) sum += x;
    auto q = [&](double p) { return v[std::min(v.size() - 1, static_cast<size_t>(p * v.size()))]; };
    return {{"mean", sum / v.size()}, {"p50", q(0.5)}, {"p99", q(0.99)}, {"max", v.back()},
            {"sum", sum}};
  }
};

void Figures(double radius, int bits, int speed) {
  levelset::SculptureOptions so;  // the scene default: voxel size 1, half-width 6
  auto s = levelset::Sculpture::MakeSphere(so, {0, 0, 0}, radius);
  ASSERT_TRUE(s.ok()) << s.status();
  DracoChunkOptions o;
  o.position_bits = bits;
  o.speed = speed;
  auto frame = FrameAround(*s, 8);
  ASSERT_TRUE(frame.ok());
  o.frame = *frame;

  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<ChunkKey> keys = AllChunks(*s);
  const double all_chunks_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  const auto t1 = std::chrono::steady_clock::now();
  const TriangleMesh whole = MeshWhole(*s);
  const double whole_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t1).count();

  Dist mesh_ms, encode_ms, decode_ms, bytes, faces;
  size_t total_bytes = 0, total_faces = 0, raw_bytes = 0;
  for (const ChunkKey& k : keys) {
    auto c = MeshChunk(*s, k);
    ASSERT_TRUE(c.ok());
    if (c->mesh.empty()) continue;
    auto enc = EncodeChunk(c->mesh, o);
    ASSERT_TRUE(enc.ok()) << enc.status();
    auto dec = DecodeChunk(enc->bytes);
    ASSERT_TRUE(dec.ok()) << dec.status();
    ASSERT_EQ(dec->mesh.face_count(), c->mesh.face_count());
    mesh_ms.v.push_back(c->mesh_ms);
    encode_ms.v.push_back(enc->encode_ms);
    decode_ms.v.push_back(dec->decode_ms);
    bytes.v.push_back(static_cast<double>(enc->bytes.size()));
    faces.v.push_back(static_cast<double>(enc->faces));
    total_bytes += enc->bytes.size();
    total_faces += enc->faces;
    raw_bytes += 4 * (c->mesh.positions.size() + c->mesh.indices.size());
  }
  ASSERT_EQ(total_faces, whole.face_count());
  const auto glb = std::filesystem::temp_directory_path() / "sculpt_figures.glb";
  GlbOptions go;
  go.position_bits = bits;
  auto g = WriteGlb(*s, glb.string(), go);
  ASSERT_TRUE(g.ok()) << g.status();
  const nlohmann::json out = {
      {"radius_voxels", radius},
      {"position_bits", bits},
      {"speed", speed},
      {"chunk_voxels", kDefaultChunkVoxels},
      {"chunks_listed", keys.size()},
      {"chunks_with_surface", mesh_ms.v.size()},
      {"all_chunks_ms", all_chunks_ms},
      {"whole_mesh_ms", whole_ms},
      {"faces", total_faces},
      {"chunk_faces", faces.Json()},
      {"chunk_mesh_ms", mesh_ms.Json()},
      {"chunk_encode_ms", encode_ms.Json()},
      {"chunk_decode_ms", decode_ms.Json()},
      {"chunk_bytes", bytes.Json()},
      {"total_bytes", total_bytes},
      {"bytes_per_face", static_cast<double>(total_bytes) / total_faces},
      {"raw_float_bytes", raw_bytes},
      {"glb_bytes", std::filesystem::file_size(glb)}};
  std::printf("%s\n", out.dump().c_str());
  std::filesystem::remove(glb);
}

// After one press of a 5-voxel tool on the radius-128 sphere: how many chunks ChunksTouchedBy
// returns and what remeshing and encoding them costs (the server's work per coalesced update).
void EditFigures(int presses) {
  levelset::SculptureOptions so;
  auto s = levelset::Sculpture::MakeSphere(so, {0, 0, 0}, 128);
  ASSERT_TRUE(s.ok()) << s.status();
  DracoChunkOptions o;
  auto frame = FrameAround(*s, 8);
  ASSERT_TRUE(frame.ok());
  o.frame = *frame;
  Dist touched, update_ms, update_bytes;
  for (int i = 0; i < presses; ++i) {
    const double a = 0.37 * i, b = 0.23 * i;
    const Vec3 c{127 * std::cos(a) * std::cos(b), 127 * std::sin(a) * std::cos(b),
                 127 * std::sin(b)};
    levelset::EditRequest press;
    press.kind = levelset::EditKind::kPress;
    press.tool = levelset::ToolShape::Sphere(c, 5.0);
    press.speed = 10;
    press.dt = 0.2;
    auto r = levelset::ApplyEdit(*s, press, levelset::EditSettings{});
    ASSERT_TRUE(r.ok()) << r.status();
    const auto t0 = std::chrono::steady_clock::now();
    size_t bytes = 0;
    const std::vector<ChunkKey> keys = ChunksTouchedBy(r->dirty_leaves);
    for (const ChunkKey& k : keys) {
      auto m = MeshChunk(*s, k);
      ASSERT_TRUE(m.ok());
      auto enc = EncodeChunk(m->mesh, o);
      ASSERT_TRUE(enc.ok()) << enc.status();
      bytes += enc->bytes.size();
    }
    touched.v.push_back(static_cast<double>(keys.size()));
    update_ms.v.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    update_bytes.v.push_back(static_cast<double>(bytes));
  }
  const nlohmann::json out = {{"radius_voxels", 128},
                              {"tool_radius_voxels", 5},
                              {"presses", presses},
                              {"chunks_touched", touched.Json()},
                              {"remesh_encode_ms", update_ms.Json()},
                              {"update_bytes", update_bytes.Json()}};
  std::printf("%s\n", out.dump().c_str());
}

TEST(ChunkCodecFigures, DISABLED_OnePress) { EditFigures(40); }

TEST(ChunkCodecFigures, DISABLED_Spheres) {
  for (double r : {64.0, 128.0}) {
    for (int bits : {12, 14, 16}) Figures(r, bits, 5);
  }
}

}  // namespace
}  // namespace sculpt::mesh
