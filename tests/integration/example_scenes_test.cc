/// @brief The example scenes of issue 7 (deploy/scenes/tyre.toml, mechanical.toml): each starts
/// the real server in-process, which voxelises its hyperpatch model with the declared materials;
/// a sculptor presses and paints over the wire; `sculpt export` writes a .vdb with one grid per
/// material and a GLB whose vertices carry COLOR_0.
#include <gtest/gtest.h>
#include <openvdb/openvdb.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>

#include "config/server_config.h"
#include "integration/raw_client.h"
#include "net/server.h"
#include "net/wire_info.h"
#include "scene/scene.h"
#include "sculpt/client/client.h"
#include "sculpt/levelset/materials.h"

namespace sculpt::client {
namespace {

namespace fs = std::filesystem;
using std::chrono::seconds;

const fs::path kSourceDir = fs::path(__FILE__).parent_path().parent_path().parent_path();

struct Example {
  const char* toml;
  const char* object;
  int materials;
};

class ExampleSceneTest : public ::testing::TestWithParam<Example> {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("sculpt_example_" + std::to_string(::getpid()) + "_" + GetParam().object);
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    ASSERT_TRUE(server::LoadConfigFile((kSourceDir / GetParam().toml).string(), &config_).ok());
    config_.data_dir = (dir_ / "data").string();
    config_.listen = "127.0.0.1:0";
    auto scene = server::Scene::Open(config_);
    ASSERT_TRUE(scene.ok()) << scene.status();
    scene_ = std::move(scene).value();
    server_ = std::make_unique<server::Server>(io_, config_, *scene_);
    auto port = server_->Start();
    ASSERT_TRUE(port.ok()) << port.status();
    port_ = *port;
    io_thread_ = std::thread([this] { io_.run(); });
  }

  void TearDown() override {
    if (server_) server_->Stop();
    io_.stop();
    if (io_thread_.joinable()) io_thread_.join();
    server_.reset();
    scene_.reset();
    fs::remove_all(dir_);
  }

  // The first point inside the object along -x from beyond its bounds, through the middle of
  // its y and z extent.
  Vec3 SurfacePoint() {
    Vec3 hit{NAN, NAN, NAN};
    EXPECT_TRUE(scene_->Inspect(GetParam().object, [&](const levelset::Sculpture& s) {
      const levelset::Aabb b = s.WorldBounds();
      const double y = 0.5 * (b.min.y + b.max.y), z = 0.5 * (b.min.z + b.max.z);
      for (double x = b.max.x; x > b.min.x; x -= 0.25 * s.voxel_size()) {
        if (s.SampleWorld({x, y, z}) < 0) {
          hit = {x, y, z};
          return;
        }
      }
    }));
    return hit;
  }

  std::string Export(const std::string& format, const fs::path& out) {
    const std::string cmd = "SCULPT_TOKEN=" + config_.viewer_token + " " +
                            std::string(SCULPT_BIN_DIR) + "/sculpt export --server 127.0.0.1:" +
                            std::to_string(port_) + " --format " + format + " --out " +
                            out.string() + " > " + (dir_ / "export.log").string() + " 2>&1";
    EXPECT_EQ(std::system(cmd.c_str()), 0) << cmd;
    std::ifstream in(out, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  }

  fs::path dir_;
  server::ServerConfig config_;
  server::asio::io_context io_;
  std::unique_ptr<server::Scene> scene_;
  std::unique_ptr<server::Server> server_;
  std::thread io_thread_;
  uint16_t port_ = 0;
};

TEST_P(ExampleSceneTest, VoxelisesSculptsPaintsAndExports) {
  const Example& ex = GetParam();
  const v1::SceneInfo info = server::ToWireSceneInfo(scene_->Info());
  ASSERT_EQ(info.effects().materials_size(), ex.materials);
  ASSERT_EQ(info.objects_size(), 1);
  EXPECT_GT(info.objects(0).volume(), 1.0);
  const double dx = config_.scene.voxel_size;
  const Vec3 p = SurfacePoint();
  ASSERT_TRUE(p.IsFinite());
  const uint64_t before = scene_->StateHash(ex.object);

  // A few press strokes into the surface.
  ClientOptions options;
  options.timeout = seconds(20);
  options.skip_state = true;
  Client sculptor(options);
  ASSERT_TRUE(sculptor.Connect("127.0.0.1", port_).ok());
  ASSERT_TRUE(sculptor.Hello(config_.sculptor_token, v1::ROLE_SCULPTOR, "t", 0).ok());
  ASSERT_TRUE(sculptor.Join().ok());
  for (int i = 0; i < 3; ++i) {
    StrokeRequest s;
    s.object = ex.object;
    s.tool_size = {3 * dx, 0, 0};
    s.speed = 20 * dx;
    for (int k = 0; k < 4; ++k) {
      codec::Pose pose;
      pose.position = {p.x + dx, p.y + (i * 4 + k - 6) * 0.5 * dx, p.z};
      pose.t_ms = static_cast<uint32_t>(k * 8);
      s.poses.push_back(pose);
    }
    s.t0_ms = static_cast<uint64_t>(i) * 40;
    ASSERT_TRUE(sculptor.SendStroke(s).ok());
  }
  ASSERT_TRUE(sculptor.WaitAllAcked(seconds(30)));
  EXPECT_EQ(sculptor.stats().refused, 0u);
  EXPECT_NE(scene_->StateHash(ex.object), before);

  // Paint the pressed spot with the last material.
  testing::RawClient raw(port_);
  ASSERT_TRUE(raw.Enter(config_.sculptor_token, v1::ROLE_SCULPTOR));
  v1::ClientMessage m;
  v1::PaintEdit* e = m.mutable_paint();
  e->set_client_seq(1);
  e->set_object(ex.object);
  e->set_tool(v1::TOOL_KIND_SPHERE);
  e->mutable_tool_size()->set_x(static_cast<float>(4 * dx));
  e->mutable_position()->set_x(static_cast<float>(p.x));
  e->mutable_position()->set_y(static_cast<float>(p.y));
  e->mutable_position()->set_z(static_cast<float>(p.z));
  e->set_material(static_cast<uint32_t>(ex.materials - 1));
  e->set_weight(1.0);
  ASSERT_TRUE(raw.Send(m));
  auto ack = raw.ReadUntil(v1::ServerMessage::kPaintAck);
  ASSERT_TRUE(ack);
  ASSERT_TRUE(ack->paint_ack().accepted()) << ack->paint_ack().DebugString();
  EXPECT_GT(ack->paint_ack().changed_voxels(), 0u);
  ASSERT_TRUE(scene_->Inspect(ex.object, [&](const levelset::Sculpture& s) {
    EXPECT_TRUE(levelset::CheckSimplex(s).Ok());
    auto f = levelset::FractionsAtWorld(s, {p.x - dx, p.y, p.z});
    ASSERT_TRUE(f.ok());
    EXPECT_NEAR((*f)[ex.materials - 1], 1.0, 1e-6);
  }));

  // .vdb: the SDF and one fraction grid per material.
  const fs::path vdb = dir_ / "state.vdb";
  ASSERT_GT(Export("vdb", vdb).size(), 1000u);
  openvdb::initialize();
  openvdb::io::File file(vdb.string());
  file.open();
  const openvdb::GridPtrVecPtr grids = file.getGrids();
  file.close();
  EXPECT_EQ(static_cast<int>(grids->size()), 1 + ex.materials);
  // .glb: Draco-compressed, with per-vertex colours.
  const std::string glb = Export("glb", dir_ / "state.glb");
  ASSERT_GT(glb.size(), 1000u);
  EXPECT_EQ(glb.substr(0, 4), "glTF");
  EXPECT_NE(glb.find("KHR_draco_mesh_compression"), std::string::npos);
  EXPECT_NE(glb.find("COLOR_0"), std::string::npos);
}

// `sculpt play` sculpts the scene's first object when neither the script nor --object names
// one (it used to assume "clay" and failed on both example scenes), and names the scene's
// objects when --object names one it lacks.
TEST_P(ExampleSceneTest, PlaySculptsTheScenesFirstObjectByDefault) {
  const Example& ex = GetParam();
  const Vec3 p = SurfacePoint();
  ASSERT_TRUE(p.IsFinite());
  const double size = std::min(2.0 * config_.scene.voxel_size, config_.scene.max_tool_size);
  nlohmann::json script = {{"kind", "press"}, {"tool", "sphere"}, {"size", {size, 0, 0}},
                           {"speed", 10}, {"strokes", nlohmann::json::array()}};
  for (int i = 0; i < 2; ++i) {
    nlohmann::json poses = nlohmann::json::array();
    for (int k = 0; k < 4; ++k) {
      poses.push_back({p.x - 0.25 * size * k, p.y + 0.5 * size * i, p.z, 8.0 * k});
    }
    script["strokes"].push_back({{"t_ms", 20 * i}, {"poses", poses}});
  }
  std::ofstream(dir_ / "script.json") << script.dump();
  const uint64_t before = scene_->StateHash(ex.object);
  const std::string play = "SCULPT_TOKEN=" + config_.sculptor_token + " " +
                           std::string(SCULPT_BIN_DIR) + "/sculpt play --server 127.0.0.1:" +
                           std::to_string(port_) + " --script " + (dir_ / "script.json").string();
  const std::string out = (dir_ / "play.json").string();
  ASSERT_EQ(std::system((play + " > " + out + " 2>&1").c_str()), 0);
  const nlohmann::json summary = nlohmann::json::parse(std::ifstream(out));
  EXPECT_EQ(summary["acked"].get<int>(), 2) << summary.dump();
  EXPECT_NE(scene_->StateHash(ex.object), before);

  const int wrong = std::system((play + " --object nosuch > " + out + " 2>&1").c_str());
  EXPECT_TRUE(WIFEXITED(wrong) && WEXITSTATUS(wrong) == 1);
  const nlohmann::json refused = nlohmann::json::parse(std::ifstream(out));
  EXPECT_NE(refused["error"].get<std::string>().find(std::string("object=nosuch outside the "
                                                                 "scene's objects {") +
                                                     ex.object + "}"),
            std::string::npos)
      << refused.dump();
}

INSTANTIATE_TEST_SUITE_P(Examples, ExampleSceneTest,
                         ::testing::Values(Example{"deploy/scenes/tyre.toml", "tyre", 5},
                                           Example{"deploy/scenes/mechanical.toml", "part", 3}),
                         [](const ::testing::TestParamInfo<Example>& i) {
                           return std::string(i.param.object);
                         });

}  // namespace
}  // namespace sculpt::client
