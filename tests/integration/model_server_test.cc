/// @brief Hyperpatch models as scene objects (issue 7, seed 001 §10.4): sculptors edit a `model`
/// object's control points through ModelIntent over the wire; the server expands each intent,
/// checks validity after ordering, refuses an invalid edit with its reason code (nothing
/// changed), refuses malformed fields by name, and recovers the same model after a restart.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <set>
#include <string>
#include <vector>

#include "integration/in_process_server.h"
#include "integration/raw_client.h"
#include "scene/scene.h"
#include "sculpt/hetero/composite_model.h"
#include "sculpt/hetero/construction.h"
#include "sculpt/hetero/hyperpatch.h"
#include "sculpt/hetero/model_io.h"
#include "sculpt/hetero/validity.h"

namespace sculpt::server {
namespace {

using testing_support::InProcessServer;

class ModelServerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    // Two glued 4-unit boxes of two materials: small enough to voxelise in a blink.
    auto model = hetero::CompositeModel::Create({{"steel", {0.6, 0.6, 0.6}},
                                                 {"bronze", {0.8, 0.5, 0.2}}});
    ASSERT_TRUE(model.ok()) << model.status();
    model_ = std::move(model).value();
    hetero::ValidityChecker checker;
    const std::vector<double> steel{1, 0}, bronze{0, 1};
    auto a = hetero::LibraryBox({0, 0, 0}, {4, 4, 4}, steel);
    auto b = hetero::LibraryBox({4, 0, 0}, {8, 4, 4}, bronze);
    ASSERT_TRUE(a.ok() && b.ok());
    for (const auto* p : {&*a, &*b}) {
      auto r = hetero::AddCellChecked(&model_, &checker, *p, hetero::CellSource::kLibrary);
      ASSERT_TRUE(r.ok()) << r.status();
      ASSERT_TRUE(r->added) << r->rejection.ToString();
    }
    const std::string path = (srv_.dir() / "two_boxes.json").string();
    ASSERT_TRUE(hetero::SaveModel(model_, path, "two boxes").ok());

    ServerConfig& c = srv_.config();
    c.scene.voxel_size = 0.25;
    c.scene.half_width = 3;
    c.scene.min_tool_size = 0.25;
    c.scene.max_tool_size = 4;
    c.scene.materials = {{"steel", {0.6, 0.6, 0.6}}, {"bronze", {0.8, 0.5, 0.2}}};
    ObjectConfig o;
    o.name = "part";
    o.primitive = "model";
    o.model = path;
    c.scene.objects = {o};
    // A snapshot after every second edit: the restart then reads a saved model file and
    // replays the intents logged after it.
    c.snapshot_every_edits = 2;
    ASSERT_TRUE(srv_.Start());
  }

  // Pool index of the corner coefficient of `cell` at slot (i, j, k) in {0, 3}.
  uint32_t Corner(int cell, int i, int j, int k) const {
    return model_.cell(cell).coef[static_cast<size_t>(hetero::Hyperpatch::Index(i, j, k))];
  }

  static v1::ClientMessage Intent(uint64_t seq, uint32_t corner, Vec3 d,
                                  std::vector<int> offset = {0, 0, 0}) {
    v1::ClientMessage m;
    v1::ModelIntent* i = m.mutable_model_intent();
    i->set_client_seq(seq);
    i->set_object("part");
    i->set_corner(corner);
    for (int o : offset) i->add_offset(o);
    i->set_displacement_x(d.x);
    i->set_displacement_y(d.y);
    i->set_displacement_z(d.z);
    i->set_cell(-1);
    return m;
  }

  static v1::ModelAck Send(testing::RawClient& c, const v1::ClientMessage& m) {
    EXPECT_TRUE(c.Send(m));
    auto a = c.ReadUntil(v1::ServerMessage::kModelAck);
    EXPECT_TRUE(a.has_value());
    return a ? a->model_ack() : v1::ModelAck{};
  }

  InProcessServer srv_{"model"};
  hetero::CompositeModel model_{2};
};

TEST_F(ModelServerTest, IntentsAcceptedRefusedByReasonAndRecovered) {
  auto start = srv_.scene().ModelInfo("part");
  ASSERT_TRUE(start.ok()) << start.status();
  EXPECT_EQ(start->version, 0u);
  EXPECT_EQ(start->cells, 2u);
  EXPECT_EQ(start->coefficients, model_.coefficient_count());
  EXPECT_FALSE(srv_.scene().ModelInfo("nope").ok());

  testing::RawClient s1(srv_.port()), s2(srv_.port());
  ASSERT_TRUE(s1.Enter(srv_.config().sculptor_token, v1::ROLE_SCULPTOR));
  ASSERT_TRUE(s2.Enter(srv_.config().sculptor_token, v1::ROLE_SCULPTOR));

  // Two sculptors, valid intents: each accepted with a higher version and a new hash.
  std::set<uint64_t> hashes{start->hash};
  uint64_t version = 0;
  const v1::ModelAck a1 = Send(s1, Intent(1, Corner(0, 0, 0, 0), {-0.3, 0, 0}));
  ASSERT_TRUE(a1.accepted()) << a1.DebugString();
  EXPECT_GT(a1.model_version(), version);
  version = a1.model_version();
  EXPECT_GE(a1.moved_coefficients(), 1u);
  EXPECT_TRUE(hashes.insert(a1.model_hash()).second);
  const v1::ModelAck a2 = Send(s2, Intent(1, Corner(1, 3, 3, 3), {0.2, 0.2, 0.2}));
  ASSERT_TRUE(a2.accepted()) << a2.DebugString();
  EXPECT_GT(a2.model_version(), version);
  version = a2.model_version();
  EXPECT_TRUE(hashes.insert(a2.model_hash()).second);
  // An interior neighbour of the first corner, moved a little inwards.
  const v1::ModelAck a3 = Send(s1, Intent(2, Corner(0, 0, 0, 0), {0.1, 0.1, 0.1}, {1, 1, 1}));
  ASSERT_TRUE(a3.accepted()) << a3.DebugString();
  EXPECT_GT(a3.model_version(), version);
  version = a3.model_version();
  EXPECT_TRUE(hashes.insert(a3.model_hash()).second);
  EXPECT_GT(a3.global_seq(), a1.global_seq());

  // The first box's corner pushed through the opposite face (x = 4): folds the cell over.
  const v1::ModelAck fold = Send(s2, Intent(2, Corner(0, 0, 0, 0), {6, 0, 0}));
  EXPECT_FALSE(fold.accepted());
  EXPECT_FALSE(fold.has_error()) << fold.DebugString();
  const std::set<std::string> fold_reasons{"SPAN_NOT_ORDERED", "SKIN_INTERSECT", "JACOBIAN_SIGN",
                                           "CELL_OVERLAP"};
  EXPECT_TRUE(fold_reasons.count(fold.reason())) << fold.DebugString();
  EXPECT_GE(fold.cell(), 0);
  EXPECT_EQ(fold.model_version(), version);
  EXPECT_EQ(fold.model_hash(), a3.model_hash());
  auto after_fold = srv_.scene().ModelInfo("part");
  ASSERT_TRUE(after_fold.ok());
  EXPECT_EQ(after_fold->version, version);
  EXPECT_EQ(after_fold->hash, a3.model_hash());

  // Malformed fields: refused by name with the value and the allowed range.
  const v1::ModelAck nan =
      Send(s1, Intent(3, Corner(0, 0, 0, 0), {std::numeric_limits<double>::quiet_NaN(), 0, 0}));
  EXPECT_FALSE(nan.accepted());
  EXPECT_EQ(nan.error().code(), v1::ERROR_CODE_INVALID_ARGUMENT);
  EXPECT_EQ(nan.error().field(), "ModelIntent.displacement_x");
  EXPECT_EQ(nan.error().value(), "nan");
  EXPECT_NE(nan.error().allowed_range().find("1e+06"), std::string::npos) << nan.DebugString();
  const uint32_t past = static_cast<uint32_t>(model_.coefficient_count());
  const v1::ModelAck corner = Send(s1, Intent(4, past, {0.1, 0, 0}));
  EXPECT_FALSE(corner.accepted());
  EXPECT_EQ(corner.error().field(), "ModelIntent.corner");
  EXPECT_EQ(corner.error().value(), std::to_string(past));
  EXPECT_EQ(corner.error().allowed_range(), "[0, " + std::to_string(past - 1) + "]");
  const v1::ModelAck offset = Send(s1, Intent(5, Corner(0, 0, 0, 0), {0.1, 0, 0}, {0, 2, 0}));
  EXPECT_FALSE(offset.accepted());
  EXPECT_EQ(offset.error().field(), "ModelIntent.offset[1]");
  EXPECT_EQ(offset.error().value(), "2");
  EXPECT_EQ(offset.error().allowed_range(), "[-1, 1]");
  v1::ClientMessage bad_cell = Intent(6, Corner(0, 0, 0, 0), {0.1, 0, 0});
  bad_cell.mutable_model_intent()->set_cell(7);
  const v1::ModelAck cell = Send(s1, bad_cell);
  EXPECT_EQ(cell.error().field(), "ModelIntent.cell");
  EXPECT_EQ(cell.error().allowed_range(), "[-1, 1]");

  // A resend of an applied intent is a duplicate, not applied again.
  const v1::ModelAck dup = Send(s1, Intent(2, Corner(0, 0, 0, 0), {0.1, 0.1, 0.1}, {1, 1, 1}));
  EXPECT_TRUE(dup.accepted());
  EXPECT_TRUE(dup.duplicate());
  EXPECT_EQ(dup.model_version(), version);

  auto before = srv_.scene().ModelInfo("part");
  ASSERT_TRUE(before.ok());
  EXPECT_EQ(before->hash, a3.model_hash());
  // The saved model file and the log hold what the acks said: same model after a restart.
  EXPECT_TRUE(std::filesystem::exists(srv_.dir() / "data" / "models" / "part.json"));
  srv_.Stop();
  ASSERT_TRUE(srv_.Start());
  auto after = srv_.scene().ModelInfo("part");
  ASSERT_TRUE(after.ok()) << after.status();
  EXPECT_EQ(after->version, before->version);
  EXPECT_EQ(after->hash, before->hash);
  EXPECT_EQ(after->json, before->json);
  // And editing continues from there.
  testing::RawClient s3(srv_.port());
  ASSERT_TRUE(s3.Enter(srv_.config().sculptor_token, v1::ROLE_SCULPTOR));
  const v1::ModelAck a4 = Send(s3, Intent(1, Corner(1, 3, 0, 0), {0.1, -0.1, 0}));
  ASSERT_TRUE(a4.accepted()) << a4.DebugString();
  EXPECT_EQ(a4.model_version(), version + 1);
}

}  // namespace
}  // namespace sculpt::server
