/// @brief Heterogeneous materials on the server (issue 7) with the real server in-process: scene
/// materials from the config, paint and fill over the wire (validated field by field, logged,
/// acknowledged once durable), replicas that converge on SDF and fractions, a restart that
/// recovers the same state.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "config/server_config.h"
#include "integration/raw_client.h"
#include "net/server.h"
#include "net/wire_info.h"
#include "scene/scene.h"
#include "sculpt/client/client.h"
#include "sculpt/client/replica.h"
#include "sculpt/levelset/materials.h"
#include "sculpt/levelset/region.h"
#include "sculpt/mesh/draco_chunk_codec.h"

namespace sculpt::client {
namespace {

namespace fs = std::filesystem;
using std::chrono::milliseconds;
using std::chrono::seconds;

const std::vector<levelset::MaterialDecl> kMaterials = {
    {"clay", {0.8, 0.5, 0.3}}, {"gold", {1.0, 0.85, 0.1}}, {"jade", {0.1, 0.7, 0.4}}};

// A press stroke on a horizontal circle at height z, one unit inside the default sphere (radius
// 24).
StrokeRequest Arc(double z, int i, int poses = 4) {
  StrokeRequest s;
  s.object = "clay";
  s.tool_size = {2.5, 0, 0};
  s.speed = 60;
  s.t0_ms = static_cast<uint64_t>(i) * 33;
  const double r = std::sqrt(23.0 * 23.0 - z * z);
  for (int k = 0; k < poses; ++k) {
    const double a = (i * poses + k) * 0.5 / r;
    codec::Pose p;
    p.position = {r * std::cos(a), r * std::sin(a), z};
    p.t_ms = static_cast<uint32_t>(k * 8);
    s.poses.push_back(p);
  }
  return s;
}

v1::Vec3f F(double x, double y, double z) {
  v1::Vec3f v;
  v.set_x(static_cast<float>(x));
  v.set_y(static_cast<float>(y));
  v.set_z(static_cast<float>(z));
  return v;
}

// A paint of `material` with a sphere at the surface point of the default sphere at angle a.
v1::ClientMessage Paint(uint64_t seq, double a, double z, uint32_t material, double weight) {
  v1::ClientMessage m;
  v1::PaintEdit* p = m.mutable_paint();
  p->set_client_seq(seq);
  p->set_object("clay");
  p->set_tool(v1::TOOL_KIND_SPHERE);
  *p->mutable_tool_size() = F(3, 0, 0);
  const double r = std::sqrt(24.0 * 24.0 - z * z);
  *p->mutable_position() = F(r * std::cos(a), r * std::sin(a), z);
  p->set_material(material);
  p->set_weight(weight);
  return m;
}

// Hash of every voxel's fractions in `box` (independent of how the grids store them), with the
// SDF's region hash folded in.
uint64_t FractionHash(const levelset::Sculpture& s, const levelset::VoxelBox& box) {
  std::string bytes;
  for (int z = box.min.z; z <= box.max.z; ++z) {
    for (int y = box.min.y; y <= box.max.y; ++y) {
      for (int x = box.min.x; x <= box.max.x; ++x) {
        auto f = levelset::FractionsAtVoxel(s, {x, y, z});
        if (!f.ok()) continue;
        for (double v : *f) {
          const float q = static_cast<float>(v);
          bytes.append(reinterpret_cast<const char*>(&q), sizeof q);
        }
      }
    }
  }
  return std::hash<std::string>{}(bytes) ^ levelset::RegionHash(s, box);
}

class MaterialsServerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("sculpt_materials_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    config_.data_dir = (dir_ / "data").string();
    config_.listen = "127.0.0.1:0";
    config_.scene.materials = kMaterials;
    StartServer();
  }

  void StartServer() {
    io_ = std::make_unique<server::asio::io_context>();
    auto scene = server::Scene::Open(config_);
    ASSERT_TRUE(scene.ok()) << scene.status();
    scene_ = std::move(scene).value();
    server_ = std::make_unique<server::Server>(*io_, config_, *scene_);
    auto port = server_->Start();
    ASSERT_TRUE(port.ok()) << port.status();
    port_ = *port;
    io_thread_ = std::thread([io = io_.get()] { io->run(); });
  }

  void StopServer() {
    if (server_) server_->Stop();
    if (io_) io_->stop();
    if (io_thread_.joinable()) io_thread_.join();
    server_.reset();
    scene_.reset();
    // The io_context goes last: handlers of the stopped server may still be queued in it.
    old_io_.push_back(std::move(io_));
  }

  void TearDown() override {
    StopServer();
    fs::remove_all(dir_);
  }

  std::unique_ptr<Client> Joined(v1::Role role) {
    ClientOptions options;
    options.timeout = seconds(10);
    options.skip_state = true;
    auto c = std::make_unique<Client>(options);
    EXPECT_TRUE(c->Connect("127.0.0.1", port_).ok());
    auto w = c->Hello(role == v1::ROLE_SCULPTOR ? "sculpt-dev-sculptor" : "sculpt-dev-viewer", role,
                      "t", 0);
    EXPECT_TRUE(w.ok()) << w.status();
    auto j = c->Join();
    EXPECT_TRUE(j.ok()) << j.status();
    return c;
  }

  uint64_t ServerFractionHash(const levelset::VoxelBox& box) {
    uint64_t h = 0;
    EXPECT_TRUE(
        scene_->Inspect("clay", [&](const levelset::Sculpture& s) { h = FractionHash(s, box); }));
    return h;
  }

  // The replica's latest published copy once it equals the server over `box` (polled).
  bool Converges(const Replica& r, const levelset::VoxelBox& box, seconds limit = seconds(30)) {
    const uint64_t want = ServerFractionHash(box);
    const auto end = std::chrono::steady_clock::now() + limit;
    while (std::chrono::steady_clock::now() < end) {
      auto snap = r.Snapshot();
      if (snap && FractionHash(*snap, box) == want) return true;
      std::this_thread::sleep_for(milliseconds(50));
    }
    return false;
  }

  fs::path dir_;
  server::ServerConfig config_;
  std::unique_ptr<server::asio::io_context> io_;
  std::vector<std::unique_ptr<server::asio::io_context>> old_io_;
  std::unique_ptr<server::Scene> scene_;
  std::unique_ptr<server::Server> server_;
  std::thread io_thread_;
  uint16_t port_ = 0;
};

TEST_F(MaterialsServerTest, SceneInfoDeclaresTheMaterialsAndEveryObjectCarriesThem) {
  const v1::SceneInfo info = server::ToWireSceneInfo(scene_->Info());
  ASSERT_EQ(info.effects().materials_size(), 3);
  EXPECT_EQ(info.effects().materials(1), "gold");
  ASSERT_EQ(info.effects().material_colours_size(), 9);
  EXPECT_FLOAT_EQ(info.effects().material_colours(3), 1.0f);
  int n = 0;
  ASSERT_TRUE(scene_->Inspect("clay", [&](const levelset::Sculpture& s) {
    n = levelset::MaterialCount(s);
    auto f = levelset::FractionsAtWorld(s, {0, 0, 0});
    ASSERT_TRUE(f.ok());
    EXPECT_DOUBLE_EQ((*f)[0], 1.0);  // uniform material 0 until painted
  }));
  EXPECT_EQ(n, 3);
}

TEST_F(MaterialsServerTest, RejectsBadMaterialDeclarationsInTheConfig) {
  server::ServerConfig c = config_;
  c.scene.materials.push_back({"gold", {0.1, 0.1, 0.1}});
  Status st = server::ValidateConfig(c);
  EXPECT_EQ(st.code(), Status::Code::kInvalidArgument);
  EXPECT_NE(st.message().find("scene.materials: materials[3].name=gold"), std::string::npos) << st;
  c = config_;
  c.scene.materials[2].colour[1] = 1.5;
  st = server::ValidateConfig(c);
  EXPECT_NE(st.message().find("materials[2].colour[1]=1.5 outside [0, 1]"), std::string::npos)
      << st;
  c = config_;
  c.scene.materials.assign(17, {});
  for (size_t i = 0; i < c.scene.materials.size(); ++i)
    c.scene.materials[i].name = "m" + std::to_string(i);
  st = server::ValidateConfig(c);
  EXPECT_NE(st.message().find("materials.size=17 outside [1, 16]"), std::string::npos) << st;
  // The TOML form.
  const fs::path toml = dir_ / "scene.toml";
  std::ofstream(toml) << "[scene]\nmaterials = [{name = \"a\", colour = [1, 0, 0]}, "
                         "{name = \"b\", colour = [0, 0, 1]}]\n";
  server::ServerConfig loaded;
  ASSERT_TRUE(server::LoadConfigFile(toml.string(), &loaded).ok());
  ASSERT_EQ(loaded.scene.materials.size(), 2u);
  EXPECT_EQ(loaded.scene.materials[1].name, "b");
  EXPECT_EQ(loaded.scene.materials[1].colour[2], 1.0);
  EXPECT_TRUE(server::ValidateConfig(loaded).ok());
}

TEST_F(MaterialsServerTest, RefusesBadPaintsFieldByFieldAndAcksGoodOnesOnceDurable) {
  testing::RawClient raw(port_);
  ASSERT_TRUE(raw.Enter("sculpt-dev-sculptor", v1::ROLE_SCULPTOR, 4242));
  auto refused = [&](v1::ClientMessage m, const std::string& field, const std::string& value) {
    EXPECT_TRUE(raw.Send(m));
    auto r = raw.ReadUntil(v1::ServerMessage::kPaintAck);
    if (!r) return ::testing::AssertionFailure() << "no PaintAck for " << field;
    const v1::PaintAck& a = r->paint_ack();
    if (a.accepted()) return ::testing::AssertionFailure() << field << " accepted";
    if (a.error().field() != field || a.error().value() != value ||
        a.error().allowed_range().empty()) {
      return ::testing::AssertionFailure()
             << "want " << field << "=" << value << ", got " << a.error().DebugString();
    }
    return ::testing::AssertionSuccess();
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  // The hard case of the issue: a fraction vector that is negative, NaN or does not sum to 1.
  auto fill = [](std::vector<double> f) {
    v1::ClientMessage m = Paint(1, 0, 0, 0, 0);
    for (double v : f) m.mutable_paint()->add_fractions(v);
    return m;
  };
  EXPECT_TRUE(refused(fill({-0.1, 0.6, 0.5}), "PaintEdit.fractions[0]", "-0.1"));
  EXPECT_TRUE(refused(fill({0.5, nan, 0.5}), "PaintEdit.fractions[1]", "nan"));
  EXPECT_TRUE(refused(fill({0.5, 0.3, 0.2 + 2e-6}), "PaintEdit.fractions.sum", "1.000002"));
  EXPECT_TRUE(refused(fill({0.5, 0.5}), "PaintEdit.fractions.size", "2"));
  EXPECT_TRUE(refused(Paint(1, 0, 0, 3, 0.5), "PaintEdit.material", "3"));
  EXPECT_TRUE(refused(Paint(1, 0, 0, 1, 1.5), "PaintEdit.weight", "1.5"));
  EXPECT_TRUE(refused(Paint(1, 0, 0, 1, nan), "PaintEdit.weight", "nan"));
  v1::ClientMessage m = Paint(1, 0, 0, 1, 0.5);
  m.mutable_paint()->set_tool(v1::TOOL_KIND_CAPSULE);
  EXPECT_TRUE(refused(m, "PaintEdit.tool", "4"));
  m = Paint(1, 0, 0, 1, 0.5);
  m.mutable_paint()->mutable_tool_size()->set_x(1000);
  EXPECT_TRUE(refused(m, "PaintEdit.tool_size.x", "1000"));
  m = Paint(1, 0, 0, 1, 0.5);
  m.mutable_paint()->mutable_position()->set_x(500);
  EXPECT_TRUE(refused(m, "PaintEdit.position.x", "500"));
  EXPECT_EQ(scene_->global_seq(), 0u);  // nothing refused reached the log

  // A good fill and a good paint: logged, applied, acknowledged with their sequence.
  ASSERT_TRUE(raw.Send(fill({0.2, 0.3, 0.5})));
  auto a = raw.ReadUntil(v1::ServerMessage::kPaintAck);
  ASSERT_TRUE(a);
  EXPECT_TRUE(a->paint_ack().accepted()) << a->paint_ack().DebugString();
  EXPECT_EQ(a->paint_ack().global_seq(), 1u);
  EXPECT_GT(a->paint_ack().changed_voxels(), 0u);
  ASSERT_TRUE(raw.Send(Paint(2, 0, 0, 2, 1.0)));
  a = raw.ReadUntil(v1::ServerMessage::kPaintAck);
  ASSERT_TRUE(a);
  EXPECT_TRUE(a->paint_ack().accepted());
  EXPECT_EQ(a->paint_ack().global_seq(), 2u);
  // A resend is not applied again.
  ASSERT_TRUE(raw.Send(Paint(2, 0, 0, 2, 1.0)));
  a = raw.ReadUntil(v1::ServerMessage::kPaintAck);
  ASSERT_TRUE(a);
  EXPECT_TRUE(a->paint_ack().duplicate());
  EXPECT_EQ(scene_->global_seq(), 2u);
  ASSERT_TRUE(scene_->Inspect("clay", [](const levelset::Sculpture& s) {
    // The paint of material 2 with weight 1 at the surface point (24, 0, 0).
    auto f = levelset::FractionsAtWorld(s, {23.5, 0, 0});
    ASSERT_TRUE(f.ok());
    EXPECT_NEAR((*f)[2], 1.0, 1e-6);
    EXPECT_TRUE(levelset::CheckSimplex(s).Ok());
  }));
  // Viewers may not paint.
  testing::RawClient viewer(port_);
  ASSERT_TRUE(viewer.Enter("sculpt-dev-viewer", v1::ROLE_VIEWER));
  ASSERT_TRUE(viewer.Send(Paint(1, 0, 0, 1, 0.5)));
  auto e = viewer.ReadUntil(v1::ServerMessage::kError);
  ASSERT_TRUE(e);
  EXPECT_EQ(e->error().code(), v1::ERROR_CODE_PERMISSION_DENIED);
}

TEST_F(MaterialsServerTest, TwoSculptorsPressAndPaintReplicasConvergeAndARestartRecovers) {
  constexpr int kRounds = 12;
  auto a = Joined(v1::ROLE_SCULPTOR);
  auto b = Joined(v1::ROLE_SCULPTOR);
  auto c = Joined(v1::ROLE_VIEWER);
  auto d = Joined(v1::ROLE_VIEWER);
  auto e = Joined(v1::ROLE_VIEWER);
  ReplicaOptions replay;
  replay.snapshot_interval = milliseconds(5);
  ReplicaOptions delta = replay;
  delta.mode = v1::REPLICA_MODE_LEAF_DELTA;
  ReplicaOptions part = replay;
  part.interest = levelset::Aabb{{15, -10, -6}, {26, 10, 6}};
  Replica rc(*c, replay);
  Replica rd(*d, delta);
  Replica rp(*e, part);
  for (Replica* r : {&rc, &rd, &rp}) ASSERT_TRUE(r->Start().ok());
  for (Replica* r : {&rc, &rd, &rp}) ASSERT_TRUE(r->WaitLoaded(1, seconds(20)));

  // Each sculptor presses an arc and paints along it, at the same time, overlapping.
  auto work = [](Client* cl, double z, uint32_t material) {
    for (int i = 0; i < kRounds; ++i) {
      EXPECT_TRUE(cl->SendStroke(Arc(z, i)).ok());
      EXPECT_TRUE(cl->SendMessage(Paint(i + 1, i * 2.0 / 23, z, material, 0.6)).ok());
    }
  };
  std::thread ta(work, a.get(), 1.5, 1);
  std::thread tb(work, b.get(), -1.5, 2);
  ta.join();
  tb.join();
  ASSERT_TRUE(a->WaitAllAcked(seconds(30)));
  ASSERT_TRUE(b->WaitAllAcked(seconds(30)));
  // Paint acks are not strokes' acks: wait until every paint is in the log and applied.
  const uint64_t want = 2u * kRounds * (4 + 1);
  for (int i = 0; i < 200 && scene_->global_seq() < want; ++i) {
    std::this_thread::sleep_for(milliseconds(50));
  }
  scene_->Flush();
  ASSERT_EQ(scene_->global_seq(), want);
  EXPECT_EQ(a->stats().refused + b->stats().refused, 0u);

  // The painted band holds gold and jade, every vector in the simplex.
  ASSERT_TRUE(scene_->Inspect("clay", [](const levelset::Sculpture& s) {
    EXPECT_TRUE(levelset::CheckSimplex(s).Ok());
    const std::vector<double> v = levelset::MaterialVolumes(s);
    ASSERT_EQ(v.size(), 3u);
    EXPECT_GT(v[1], 1.0);
    EXPECT_GT(v[2], 1.0);
  }));
  // The arcs and paints cover x in [23, 48] voxels, y in [0, 46], z in [-8, 8].
  const levelset::VoxelBox band{{16, -8, -12}, {52, 48, 12}};
  for (Replica* r : {&rc, &rd}) {
    ASSERT_TRUE(r->WaitForSeq(scene_->global_seq(), seconds(30)));
    EXPECT_TRUE(Converges(*r, band));
    EXPECT_EQ(r->stats().hash_mismatches, 0u);
    EXPECT_EQ(r->stats().errors, 0u);
  }
  // Paints reach replay replicas as leaf deltas (one per paint), beside the strokes' broadcasts.
  EXPECT_EQ(rc.stats().broadcasts_applied, 2u * kRounds);
  EXPECT_EQ(rc.stats().deltas_applied, 2u * kRounds);
  EXPECT_EQ(rd.stats().deltas_applied, 4u * kRounds);
  const levelset::VoxelBox interest{{30, -20, -12}, {52, 20, 12}};  // inside the part's box
  EXPECT_TRUE(Converges(rp, interest));
  EXPECT_EQ(rp.stats().errors, 0u);
  EXPECT_EQ(scene_->replication_stats().divergences.load(), 0u);

  // A restart replays strokes and paints from the log to the same voxels and fractions.
  const uint64_t before_state = scene_->StateHash("clay");
  const uint64_t before_fractions = ServerFractionHash(band);
  uint64_t before_materials = 0;
  ASSERT_TRUE(scene_->Inspect("clay", [&](const levelset::Sculpture& s) {
    before_materials = levelset::MaterialStateHash(s);
  }));
  a.reset();
  b.reset();
  StopServer();
  StartServer();
  ASSERT_EQ(scene_->global_seq(), want);
  EXPECT_EQ(scene_->StateHash("clay"), before_state);
  EXPECT_EQ(ServerFractionHash(band), before_fractions);
  uint64_t after_materials = 0;
  ASSERT_TRUE(scene_->Inspect("clay", [&](const levelset::Sculpture& s) {
    after_materials = levelset::MaterialStateHash(s);
  }));
  EXPECT_EQ(after_materials, before_materials);
}

TEST_F(MaterialsServerTest, ViewerChunksCarryColoursMixedFromTheFractions) {
  auto viewer = Joined(v1::ROLE_VIEWER);
  std::mutex mu;
  std::map<std::array<int, 3>, v1::MeshChunk> chunks;  // the newest of each key
  viewer->SetReplicationHandler([&](v1::ServerMessage&& m) {
    if (!m.has_mesh_chunk()) return;
    std::lock_guard<std::mutex> lock(mu);
    const v1::MeshChunk& c = m.mesh_chunk();
    chunks[{c.key(0), c.key(1), c.key(2)}] = c;
  });
  v1::ClientMessage sub;
  sub.mutable_viewer_subscribe()->set_object("clay");
  sub.mutable_viewer_subscribe()->set_max_rate_hz(30);
  ASSERT_TRUE(viewer->SendMessage(sub).ok());
  testing::RawClient raw(port_);
  ASSERT_TRUE(raw.Enter("sculpt-dev-sculptor", v1::ROLE_SCULPTOR, 77));
  // Jade with weight 1 on the +x pole, radius 3.
  ASSERT_TRUE(raw.Send(Paint(1, 0, 0, 2, 1.0)));
  auto ack = raw.ReadUntil(v1::ServerMessage::kPaintAck);
  ASSERT_TRUE(ack && ack->paint_ack().accepted());
  const uint64_t painted = ack->paint_ack().global_seq();
  const Vec3 centre{24, 0, 0};
  int jade = 0, clay = 0, checked = 0;
  const auto end = std::chrono::steady_clock::now() + seconds(20);
  while (std::chrono::steady_clock::now() < end && jade == 0) {
    std::this_thread::sleep_for(milliseconds(100));
    std::lock_guard<std::mutex> lock(mu);
    jade = clay = checked = 0;
    for (const auto& [key, c] : chunks) {
      if (c.draco().empty()) continue;
      auto d = mesh::DecodeChunk(c.draco());
      ASSERT_TRUE(d.ok()) << d.status();
      const mesh::TriangleMesh& m = d->mesh;
      ASSERT_EQ(m.colours.size(), m.positions.size());  // every chunk of this scene is coloured
      for (size_t v = 0; v < m.vertex_count(); ++v) {
        const float* p = &m.positions[3 * v];
        const float* col = &m.colours[3 * v];
        for (int k = 0; k < 3; ++k) ASSERT_TRUE(col[k] >= 0.f && col[k] <= 1.f);
        const double dist = std::hypot(p[0] - centre.x, p[1] - centre.y, p[2] - centre.z);
        const auto& want = dist < 1.5 ? kMaterials[2].colour
                           : dist > 5 ? kMaterials[0].colour
                                      : std::array<double, 3>{-1, -1, -1};
        if (want[0] < 0) continue;
        if (dist < 1.5 && c.version() < painted) continue;  // an update not yet received
        ++checked;
        bool near = true;
        for (int k = 0; k < 3; ++k) near = near && std::abs(col[k] - want[k]) < 0.02;
        EXPECT_TRUE(near) << "vertex at distance " << dist << " colour " << col[0] << ", " << col[1]
                          << ", " << col[2];
        (dist < 1.5 ? jade : clay) += near ? 1 : 0;
      }
    }
  }
  EXPECT_GT(jade, 0);
  EXPECT_GT(clay, 100);
  viewer->SetReplicationHandler(nullptr);
}

}  // namespace
}  // namespace sculpt::client
