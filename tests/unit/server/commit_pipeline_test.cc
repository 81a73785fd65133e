// The one commit pipeline (server/src/scene/commit.h): each guarantee is checked once per edit
// kind (stroke, paint, sweep, ball edit, model intent) against a real Scene in-process:
//   - logged before applied: every "applied" step comes after its "appended" step, with the log
//     already holding the edit's last record;
//   - acknowledged only once durable: at every "answered" step the log is durable up to it;
//   - a resend is acknowledged as a duplicate and changes nothing, also after a restart;
//   - a refusal logs nothing and changes nothing;
//   - recovery reproduces the live state (object hash, skin balls, model hash).
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <future>
#include <mutex>
#include <string>
#include <vector>

#include "integration/raw_client.h"
#include "scene/commit.h"
#include "scene/outcomes.h"
#include "scene/scene.h"
#include "sculpt/hetero/composite_model.h"
#include "sculpt/hetero/construction.h"
#include "sculpt/hetero/model_io.h"
#include "sculpt/hetero/validity.h"
#include "sculpt/levelset/materials.h"
#include "store/edit_log.h"

namespace sculpt::server {
namespace {

namespace fs = std::filesystem;

enum class Kind { kStroke, kPaint, kSweep, kBallEdit, kModelIntent };

std::string KindName(const ::testing::TestParamInfo<Kind>& info) {
  switch (info.param) {
    case Kind::kStroke: return "Stroke";
    case Kind::kPaint: return "Paint";
    case Kind::kSweep: return "Sweep";
    case Kind::kBallEdit: return "BallEdit";
    case Kind::kModelIntent: return "ModelIntent";
  }
  return "Unknown";
}

// What any kind's answer says, in the pipeline's terms.
/// The field a refusal names (empty when it names none).
std::string ViolationField(const Status& s) { return s.violation() ? s.violation()->field : ""; }

struct Answer {
  bool accepted = false;
  bool duplicate = false;
  uint64_t global_seq = 0;
  std::string error_field;
};

Answer FromSkin(const SkinOutcome& k) {
  Answer a{k.status.ok(), k.duplicate, k.global_seq, {}};
  if (!k.status.ok()) a.error_field = ViolationField(k.status);
  return a;
}

v1::Vec3f F(double x, double y, double z) {
  v1::Vec3f v;
  v.set_x(static_cast<float>(x));
  v.set_y(static_cast<float>(y));
  v.set_z(static_cast<float>(z));
  return v;
}

class CommitPipelineTest : public ::testing::TestWithParam<Kind> {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("sculpt_commit_" + std::to_string(::getpid()) + "_" +
            std::to_string(static_cast<int>(GetParam())));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    // A two-box hyperpatch model for the `part` object.
    auto model = hetero::CompositeModel::Create({{"steel", {0.6, 0.6, 0.6}},
                                                 {"bronze", {0.8, 0.5, 0.2}}});
    ASSERT_TRUE(model.ok()) << model.status();
    hetero::ValidityChecker checker;
    auto a = hetero::LibraryBox({40, 0, 0}, {44, 4, 4}, std::vector<double>{1, 0});
    auto b = hetero::LibraryBox({44, 0, 0}, {48, 4, 4}, std::vector<double>{0, 1});
    ASSERT_TRUE(a.ok() && b.ok());
    for (const auto* p : {&*a, &*b}) {
      auto r = hetero::AddCellChecked(&*model, &checker, *p, hetero::CellSource::kLibrary);
      ASSERT_TRUE(r.ok() && r->added);
    }
    corner_ = model->cell(0).coef[0];
    const std::string path = (dir_ / "two_boxes.json").string();
    ASSERT_TRUE(hetero::SaveModel(*model, path, "two boxes").ok());

    config_.data_dir = (dir_ / "data").string();
    config_.fsync = "group";
    config_.group_commit_ms = 5;
    config_.scene.materials = {{"steel", {0.6, 0.6, 0.6}}, {"bronze", {0.8, 0.5, 0.2}}};
    ObjectConfig part;
    part.name = "part";
    part.primitive = "model";
    part.model = path;
    config_.scene.objects.push_back(part);  // after the default sphere "clay"
    SkinConfig skin;
    skin.name = "outline";
    skin.origin = {0, 0, 0};
    skin.chord_tolerance = 0.05;
    skin.balls = {{-12, 0, 3, 0}, {-6, 1, 2.5, 0}, {0, 0, 3, 0}, {6, -1, 2.5, 0}, {12, 0, 3, 0}};
    config_.scene.skins = {skin};
    config_.scene.effects.contours = true;
    Open();
  }
  void TearDown() override {
    scene_.reset();
    fs::remove_all(dir_);
  }

  void Open() {
    scene_.reset();
    auto s = Scene::Open(config_);
    ASSERT_TRUE(s.ok()) << s.status();
    scene_ = std::move(s).value();
  }

  // Edit `i` of the kind under test by `client`; `bad` makes it one the scene refuses after the
  // session's checks (an unknown object, skin or corner).
  Answer Do(uint64_t client, uint64_t client_seq, int i, bool bad = false) {
    std::promise<Answer> p;
    switch (GetParam()) {
      case Kind::kStroke: {
        v1::ClientMessage m =
            testing::RawClient::PressStroke(client_seq, {0, 0, 22.5 - 0.4 * i}, 3);
        auto limits = scene_->LimitsFor("clay");
        EXPECT_TRUE(limits.ok());
        auto stroke = codec::DecodeStroke(m.stroke(), *limits);
        EXPECT_TRUE(stroke.ok()) << stroke.status();
        if (bad) stroke->object = "nothing";
        scene_->Submit(client, std::move(stroke).value(), [&p](const StrokeOutcome& o) {
          Answer a;
          a.accepted = o.status.ok();
          a.duplicate = o.duplicate;
          a.global_seq = o.global_seq_first;
          if (!o.status.ok()) a.error_field = ViolationField(o.status);
          p.set_value(a);
        });
        break;
      }
      case Kind::kPaint: {
        v1::PaintEdit e;
        e.set_client_seq(client_seq);
        e.set_object(bad ? "nothing" : "clay");
        e.set_tool(v1::TOOL_KIND_SPHERE);
        *e.mutable_tool_size() = F(3, 0, 0);
        *e.mutable_position() = F(0, 0, 24 - 0.5 * i);
        e.set_material(1);
        e.set_weight(0.5);
        // The session refuses an unknown object before decoding; the scene is asked anyway.
        auto limits = scene_->LimitsFor("clay");
        EXPECT_TRUE(limits.ok());
        auto paint = codec::DecodePaintEdit(e, *limits, 2);
        EXPECT_TRUE(paint.ok()) << paint.status();
        scene_->Paint(client, std::move(paint).value(), [&](const PaintOutcome& k) {
          Answer a{k.status.ok(), k.duplicate, k.global_seq, {}};
          if (!k.status.ok()) a.error_field = ViolationField(k.status);
          p.set_value(a);
        });
        break;
      }
      case Kind::kSweep: {
        v1::SkinSweep s;
        s.set_client_seq(client_seq);
        s.set_skin(bad ? "nothing" : "outline");
        s.set_object("clay");
        s.set_mode(v1::SKIN_SWEEP_MODE_EXTRUDE);
        s.set_kind(i % 2 ? v1::EDIT_KIND_SUBTRACT : v1::EDIT_KIND_ADD);
        s.set_depth(1.0 + 0.25 * i);
        auto sweep = codec::DecodeSkinSweep(s);
        EXPECT_TRUE(sweep.ok()) << sweep.status();
        scene_->SweepSkin(client, std::move(sweep).value(), [&](const SkinOutcome& k) {
          p.set_value(FromSkin(k));
        });
        break;
      }
      case Kind::kBallEdit: {
        v1::SkinBallEdit e;
        e.set_client_seq(client_seq);
        e.set_skin(bad ? "nothing" : "outline");
        e.set_op(v1::SKIN_BALL_OP_MOVE);
        e.set_index(2);
        e.mutable_ball()->set_x(0.1 * (i + 1));
        e.mutable_ball()->set_y(0.05 * i);
        e.mutable_ball()->set_r(3);
        auto edit = codec::DecodeSkinBallEdit(e);
        EXPECT_TRUE(edit.ok()) << edit.status();
        scene_->EditSkin(client, std::move(edit).value(), [&](const SkinOutcome& k) {
          p.set_value(FromSkin(k));
        });
        break;
      }
      case Kind::kModelIntent: {
        v1::ModelIntent m;
        m.set_client_seq(client_seq);
        m.set_object("part");
        m.set_corner(bad ? 100000 : corner_);
        for (int o : {0, 0, 0}) m.add_offset(o);
        m.set_displacement_x(-0.02);
        m.set_displacement_y(-0.01 * (i % 3));
        m.set_displacement_z(0);
        m.set_cell(-1);
        auto edit = codec::DecodeModelIntent(m);
        EXPECT_TRUE(edit.ok()) << edit.status();
        scene_->EditModel(client, std::move(edit).value(), [&](const ModelOutcome& k) {
          Answer a{k.status.ok() && !k.rejection, k.duplicate, k.global_seq, {}};
          if (!k.status.ok()) a.error_field = ViolationField(k.status);
          p.set_value(a);
        });
        break;
      }
    }
    return p.get_future().get();
  }

  // Everything an edit of any kind can change.
  struct State {
    uint64_t clay = 0;
    uint64_t fractions = 0;
    std::vector<double> balls;
    uint64_t model = 0;
    bool operator==(const State&) const = default;
  };
  State Now() {
    State s;
    s.clay = scene_->StateHash("clay");
    EXPECT_TRUE(scene_->Inspect("clay", [&s](const levelset::Sculpture& c) {
      s.fractions = levelset::MaterialStateHash(c);
    }));
    auto skin = scene_->SkinCopy("outline");
    EXPECT_TRUE(skin.ok());
    for (const auto& b : skin->balls()) s.balls.insert(s.balls.end(), {b.c.x, b.c.y, b.r});
    auto model = scene_->ModelInfo("part");
    EXPECT_TRUE(model.ok());
    s.model = model->hash;
    return s;
  }

  fs::path dir_;
  ServerConfig config_;
  std::unique_ptr<Scene> scene_;
  uint32_t corner_ = 0;
};

TEST_P(CommitPipelineTest, LogsBeforeApplyingAndAnswersOnlyOnceDurable) {
  std::mutex mu;
  std::vector<Scene::CommitEvent> events;
  scene_->ObserveCommitsForTesting([&](const Scene::CommitEvent& e) {
    std::lock_guard<std::mutex> lock(mu);
    events.push_back(e);
  });
  const State before = Now();
  for (int i = 0; i < 4; ++i) {
    const Answer a = Do(7, i + 1, i);
    ASSERT_TRUE(a.accepted) << "edit " << i << ": " << a.error_field;
    EXPECT_FALSE(a.duplicate);
    EXPECT_GT(a.global_seq, 0u);
  }
  scene_->ObserveCommitsForTesting(nullptr);
  EXPECT_NE(Now(), before) << "the edits changed nothing";

  std::lock_guard<std::mutex> lock(mu);
  int appended = 0, applied = 0, answered = 0;
  uint64_t last_appended = 0;
  for (const Scene::CommitEvent& e : events) {
    if (e.step == "appended") {
      ++appended;
      last_appended = e.seq;
      EXPECT_GE(e.log_last_seq, e.seq) << e.operation;
    } else if (e.step == "applied") {
      ++applied;
      EXPECT_EQ(e.seq, last_appended) << e.operation << ": applied before its records were logged";
      EXPECT_GE(e.log_last_seq, e.seq) << e.operation;
    } else if (e.step == "answered") {
      ++answered;
      EXPECT_GE(e.log_durable_seq, e.seq) << e.operation << ": answered before durable";
    }
  }
  EXPECT_EQ(appended, 4);
  EXPECT_EQ(applied, 4);
  EXPECT_EQ(answered, 4);
}

TEST_P(CommitPipelineTest, ResendIsADuplicateAndChangesNothingAlsoAfterARestart) {
  ASSERT_TRUE(Do(7, 1, 0).accepted);
  ASSERT_TRUE(Do(7, 2, 1).accepted);
  const State after = Now();
  const uint64_t seq = scene_->global_seq();
  const Answer again = Do(7, 2, 1);
  EXPECT_TRUE(again.accepted);
  EXPECT_TRUE(again.duplicate);
  EXPECT_EQ(scene_->global_seq(), seq) << "a resend reached the log";
  EXPECT_EQ(Now(), after);
  // Another client's same client_seq is its own edit.
  const Answer other = Do(8, 2, 2);
  EXPECT_TRUE(other.accepted);
  EXPECT_FALSE(other.duplicate);

  Open();
  const State recovered = Now();
  const Answer late = Do(7, 1, 0);
  EXPECT_TRUE(late.duplicate) << "a resend after a restart was applied again";
  EXPECT_EQ(Now(), recovered);
}

TEST_P(CommitPipelineTest, RefusalLogsNothingAndChangesNothing) {
  ASSERT_TRUE(Do(7, 1, 0).accepted);
  const State before = Now();
  const uint64_t seq = scene_->global_seq();
  const Answer bad = Do(7, 2, 1, /*bad=*/true);
  EXPECT_FALSE(bad.accepted);
  EXPECT_FALSE(bad.error_field.empty()) << "the refusal names no field";
  EXPECT_EQ(scene_->global_seq(), seq);
  EXPECT_EQ(Now(), before);
  // The refused client_seq is not consumed: the same number with a good edit is applied.
  const Answer good = Do(7, 2, 1);
  EXPECT_TRUE(good.accepted);
  EXPECT_FALSE(good.duplicate);
}

TEST_P(CommitPipelineTest, RecoveryReproducesTheLiveState) {
  for (int i = 0; i < 5; ++i) ASSERT_TRUE(Do(7 + i % 2, i + 1, i).accepted) << i;
  const State live = Now();
  const uint64_t seq = scene_->global_seq();
  Open();
  EXPECT_EQ(scene_->global_seq(), seq);
  EXPECT_EQ(Now(), live);
}

INSTANTIATE_TEST_SUITE_P(EveryEditKind, CommitPipelineTest,
                         ::testing::Values(Kind::kStroke, Kind::kPaint, Kind::kSweep,
                                           Kind::kBallEdit, Kind::kModelIntent),
                         KindName);

TEST(DecodeLogRecordTest, TellsEveryKindApartAndRefusesGarbageByName) {
  v1::EditRecord pose;
  pose.set_client_id(3);
  pose.set_client_seq(9);
  pose.set_object("clay");
  pose.set_pose_index(0);
  pose.set_pose_count(2);
  auto e = DecodeLogRecord(1, pose.SerializeAsString());
  ASSERT_TRUE(e.ok()) << e.status();
  EXPECT_EQ(e->stream, ResendStream::kStrokes);
  EXPECT_EQ(e->client_id, 3u);
  EXPECT_EQ(e->client_seq, 9u);
  EXPECT_EQ(e->object, "clay");
  EXPECT_FALSE(e->completes) << "the first of two poses completes nothing";
  pose.set_pose_index(1);
  EXPECT_TRUE(DecodeLogRecord(2, pose.SerializeAsString())->completes);

  // A tagged record whose body does not parse names its sequence.
  const std::string garbage = std::string(1, '\x01') + "\xff\xff\xff";
  auto bad = DecodeLogRecord(42, garbage);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().code(), Status::Code::kDataLoss);
  EXPECT_NE(bad.status().message().find("42"), std::string::npos) << bad.status();
}

TEST(ResendFilterTest, KeysByStreamAndClientAndNeverLowers) {
  ResendFilter f;
  f.Record(ResendStream::kStrokes, 1, 5);
  EXPECT_TRUE(f.IsResend(ResendStream::kStrokes, 1, 5));
  EXPECT_TRUE(f.IsResend(ResendStream::kStrokes, 1, 4));
  EXPECT_FALSE(f.IsResend(ResendStream::kStrokes, 1, 6));
  EXPECT_FALSE(f.IsResend(ResendStream::kPaints, 1, 5)) << "streams are separate";
  EXPECT_FALSE(f.IsResend(ResendStream::kStrokes, 2, 5)) << "clients are separate";
  f.Record(ResendStream::kStrokes, 1, 3);
  EXPECT_FALSE(f.IsResend(ResendStream::kStrokes, 1, 6));
  EXPECT_TRUE(f.IsResend(ResendStream::kStrokes, 1, 5)) << "a lower sequence lowered the filter";
}

}  // namespace
}  // namespace sculpt::server
