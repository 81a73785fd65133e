/// @brief Unit tests for SkinBook without a scene: opening skins from the configuration or their
/// saved files, ball edits checked on a copy and applied, recovery's replay past a file's
/// sequence, save and reopen, and what contour and slice subscribers are sent.
#include "scene/skins.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "sculpt/levelset/region.h"
#include "sculpt/v1/sculpt.pb.h"
#include "unit/server/fake_sink.h"

namespace sculpt::server {
namespace {

namespace fs = std::filesystem;

constexpr const char* kSkin = "outline";

using testing::FakeSink;

// Frame `i` of `sink` as the contour update it carries.
v1::ContourUpdate Update(const FakeSink& sink, size_t i) {
  const v1::ServerMessage m = sink.Message(i);
  EXPECT_TRUE(m.has_contour());
  return m.contour();
}

SkinConfig FiveBalls() {
  SkinConfig c;
  c.name = kSkin;
  c.origin = {0, 0, 0};
  c.u = {1, 0, 0};
  c.v = {0, 1, 0};
  c.balls = {{-12, 0, 3, 0}, {-6, 1, 2.5, 0}, {0, 0, 3, 0}, {6, -1, 2.5, 0}, {12, 0, 3, 0}};
  return c;
}

codec::BallEdit Move(uint32_t index, double x, double y, double r, uint64_t client_seq = 1) {
  codec::BallEdit e;
  e.client_seq = client_seq;
  e.skin = kSkin;
  e.op = codec::BallOp::kMove;
  e.index = index;
  e.x = x;
  e.y = y;
  e.r = r;
  return e;
}

class SkinBookTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("sculpt_skin_book_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    ASSERT_TRUE(book_.Open({FiveBalls()}, dir_.string(), &resend_).ok());
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Prepares and applies `edit` as the commit pipeline does; the ball count after it.
  size_t Edit(const codec::BallEdit& edit) {
    auto plan = book_.PrepareBallEdit(edit);
    EXPECT_TRUE(plan.ok()) << plan.status();
    return plan.ok() ? book_.ApplyBallEdit(std::move(plan).value()) : 0;
  }
  // Subscribes `sink` to the skin and expects acceptance answered before the first frame.
  void SubscribeSkin(FakeSink& sink) {
    codec::ContourRequest req;
    req.skin = kSkin;
    bool answered = false;
    book_.Subscribe(sink.sink(), req, nullptr, 0, [&](Status st) {
      EXPECT_TRUE(st.ok()) << st.ToString();
      EXPECT_TRUE(sink.frames.empty()) << "answered after a frame";
      answered = true;
    });
    EXPECT_TRUE(answered);
  }

  fs::path dir_;
  ResendFilter resend_;
  SkinBook book_;
};

TEST_F(SkinBookTest, OpensFromTheConfigurationWithoutAFile) {
  EXPECT_EQ(book_.ball_count(kSkin), 5u);
  EXPECT_EQ(book_.version(kSkin), 0u);
  auto copy = book_.Copy(kSkin);
  ASSERT_TRUE(copy.ok()) << copy.status();
  EXPECT_EQ(copy->balls()[1].c.y, 1.0);
  EXPECT_EQ(copy->balls()[1].r, 2.5);
  const Status missing = book_.Copy("nope").status();
  EXPECT_EQ(missing.code(), Status::Code::kNotFound);
  ASSERT_NE(missing.violation(), nullptr);
  EXPECT_EQ(missing.violation()->field, "skin");
  EXPECT_TRUE(resend_.entries().empty());
}

TEST_F(SkinBookTest, OpensFromItsSavedFileWithTheResendSequencesItCarries) {
  codec::SavedSkin saved;
  saved.seq = 40;
  saved.version = 3;
  saved.balls = {{-10, 0, 2, 0}, {0, 0, 2, 0}, {10, 0, 2, 0}};
  saved.last_edit_seq = {{42, 9}};
  saved.last_sweep_seq = {{43, 4}};
  fs::create_directories(dir_ / "skins");
  ASSERT_TRUE(SaveSkinFile((dir_ / "skins" / "outline.pb").string(), saved).ok());
  SkinBook reopened;
  ResendFilter resend;
  ASSERT_TRUE(reopened.Open({FiveBalls()}, dir_.string(), &resend).ok());
  EXPECT_EQ(reopened.ball_count(kSkin), 3u);  // the file's balls, not the configuration's
  EXPECT_EQ(reopened.version(kSkin), 3u);
  EXPECT_TRUE(resend.IsResend(ResendStream::kBallEdits, 42, 9));
  EXPECT_FALSE(resend.IsResend(ResendStream::kBallEdits, 42, 10));
  EXPECT_TRUE(resend.IsResend(ResendStream::kSweeps, 43, 4));
}

TEST_F(SkinBookTest, RejectsUnparsableSkinFileAndUnbuildableBalls) {
  fs::create_directories(dir_ / "skins");
  {
    std::FILE* f = std::fopen((dir_ / "skins" / "outline.pb").c_str(), "wb");
    ASSERT_NE(f, nullptr);
    std::fputs("\xff\xff\xff not a skin", f);
    std::fclose(f);
  }
  SkinBook damaged;
  EXPECT_EQ(damaged.Open({FiveBalls()}, dir_.string(), nullptr).code(), Status::Code::kDataLoss);
  fs::remove_all(dir_ / "skins");
  SkinConfig one = FiveBalls();
  one.balls.resize(1);  // a skin needs at least two balls
  SkinBook unbuildable;
  const Status st = unbuildable.Open({one}, dir_.string(), nullptr);
  EXPECT_EQ(st.code(), Status::Code::kInvalidArgument);
  EXPECT_NE(st.message().find("scene.skins outline"), std::string::npos) << st;
}

TEST_F(SkinBookTest, BallEditIsCheckedOnACopyThenApplied) {
  auto plan = book_.PrepareBallEdit(Move(2, 0, 0.5, 3.5));
  ASSERT_TRUE(plan.ok()) << plan.status();
  EXPECT_EQ(plan->version, 1u);
  EXPECT_FALSE(plan->change.changed.empty());
  // The two sections beside the ball, then any up to the next codec restart (Skin::
  // CodecRestart), none of which is a restart.
  const std::vector<size_t>& changed = plan->change.changed;
  ASSERT_GE(changed.size(), 2u);
  EXPECT_EQ(changed[0], 1u);
  for (size_t j = 2; j < changed.size(); ++j) {
    EXPECT_EQ(changed[j], changed[j - 1] + 1);
    EXPECT_FALSE(book_.Copy(kSkin)->CodecRestart(changed[j]));
  }
  // Nothing changed before Apply.
  EXPECT_EQ(book_.Copy(kSkin)->balls()[2].r, 3.0);
  EXPECT_EQ(book_.version(kSkin), 0u);
  EXPECT_EQ(book_.ApplyBallEdit(std::move(plan).value()), 5u);
  EXPECT_EQ(book_.Copy(kSkin)->balls()[2].r, 3.5);
  EXPECT_EQ(book_.Copy(kSkin)->balls()[2].c.y, 0.5);
  EXPECT_EQ(book_.version(kSkin), 1u);
}

TEST_F(SkinBookTest, RejectsBallIndexOutOfRange) {
  const Status move = book_.PrepareBallEdit(Move(5, 0, 0, 3)).status();
  EXPECT_EQ(move.code(), Status::Code::kInvalidArgument);
  ASSERT_NE(move.violation(), nullptr);
  EXPECT_EQ(move.violation()->field, "SkinBallEdit.index");
  EXPECT_EQ(move.violation()->value, "5");
  EXPECT_EQ(move.violation()->allowed_range, "[0, 4]");
  codec::BallEdit add = Move(6, 18, 0, 3);
  add.op = codec::BallOp::kAdd;
  const Status past = book_.PrepareBallEdit(add).status();
  ASSERT_NE(past.violation(), nullptr);
  EXPECT_EQ(past.violation()->field, "SkinBallEdit.index");
  EXPECT_EQ(past.violation()->allowed_range, "[0, 5]");  // an ADD may append
  add.index = 5;
  EXPECT_TRUE(book_.PrepareBallEdit(add).ok());
  EXPECT_EQ(book_.ball_count(kSkin), 5u);  // prepared, not applied
}

TEST_F(SkinBookTest, RejectsUnknownSkinAndInadmissibleBall) {
  codec::BallEdit unknown = Move(0, 0, 0, 3);
  unknown.skin = "nope";
  const Status st = book_.PrepareBallEdit(unknown).status();
  EXPECT_EQ(st.code(), Status::Code::kNotFound);
  ASSERT_NE(st.violation(), nullptr);
  EXPECT_EQ(st.violation()->field, "SkinBallEdit.skin");
  // Ball 1 moved onto ball 2's centre: a concentric pair.
  const Status nested = book_.PrepareBallEdit(Move(1, 0, 0, 1)).status();
  EXPECT_FALSE(nested.ok());
  ASSERT_NE(nested.violation(), nullptr);
  EXPECT_EQ(nested.violation()->field, "SkinBallEdit.ball");
  EXPECT_EQ(book_.Copy(kSkin)->balls()[1].c.x, -6.0);
}

TEST_F(SkinBookTest, SaveAndReopenRoundTrip) {
  ASSERT_EQ(Edit(Move(4, 12, 1, 2.75)), 5u);
  ASSERT_TRUE(book_.Save(17));
  SkinBook reopened;
  ASSERT_TRUE(reopened.Open({FiveBalls()}, dir_.string(), nullptr).ok());
  EXPECT_EQ(reopened.version(kSkin), 1u);
  const skin::Skin a = std::move(book_.Copy(kSkin)).value();
  const skin::Skin b = std::move(reopened.Copy(kSkin)).value();
  ASSERT_EQ(a.balls().size(), b.balls().size());
  for (size_t i = 0; i < a.balls().size(); ++i) {
    EXPECT_EQ(a.balls()[i].c.x, b.balls()[i].c.x) << i;
    EXPECT_EQ(a.balls()[i].c.y, b.balls()[i].c.y) << i;
    EXPECT_EQ(a.balls()[i].r, b.balls()[i].r) << i;
    EXPECT_EQ(a.balls()[i].theta, b.balls()[i].theta) << i;
  }
  auto saved = LoadSkinFile((dir_ / "skins" / "outline.pb").string());
  ASSERT_TRUE(saved.ok()) << saved.status();
  EXPECT_EQ(saved->seq, 17u);
}

TEST_F(SkinBookTest, ReplaySkipsEditsItsFileHoldsAndAppliesLaterOnes) {
  ASSERT_TRUE(book_.Save(10));
  SkinBook reopened;
  ASSERT_TRUE(reopened.Open({FiveBalls()}, dir_.string(), nullptr).ok());
  codec::BallEditRecord rec;
  rec.edit = Move(0, -12, 0, 2);
  rec.skin_version = 1;
  reopened.Replay(10, rec);  // at the file's seq: already in it
  EXPECT_EQ(reopened.Copy(kSkin)->balls()[0].r, 3.0);
  EXPECT_EQ(reopened.version(kSkin), 0u);
  reopened.Replay(11, rec);
  EXPECT_EQ(reopened.Copy(kSkin)->balls()[0].r, 2.0);
  EXPECT_EQ(reopened.version(kSkin), 1u);
  // Refused live, refused on replay: nothing changes.
  codec::BallEditRecord bad = rec;
  bad.edit = Move(9, 0, 0, 3);
  bad.skin_version = 2;
  reopened.Replay(12, bad);
  EXPECT_EQ(reopened.version(kSkin), 1u);
  bad.edit.skin = "nope";
  reopened.Replay(13, bad);
  EXPECT_EQ(reopened.version(kSkin), 1u);
}

TEST_F(SkinBookTest, SubscriberGetsTheChangedSectionsUntilItUnsubscribes) {
  FakeSink a(1);
  SubscribeSkin(a);
  ASSERT_EQ(a.frames.size(), 1u);
  const v1::ContourUpdate snapshot = Update(a, 0);
  EXPECT_EQ(snapshot.skin(), kSkin);
  EXPECT_EQ(snapshot.skin_version(), 0u);
  EXPECT_EQ(snapshot.balls_size(), 5);
  EXPECT_EQ(snapshot.sections(), 4u);
  EXPECT_EQ(book_.subscriber_count(), 1u);

  auto plan = book_.PrepareBallEdit(Move(2, 0, 0.5, 3.5));
  ASSERT_TRUE(plan.ok());
  const size_t changed = plan->change.changed.size();
  EXPECT_EQ(a.frames.size(), 1u);  // prepared: nothing sent yet
  book_.ApplyBallEdit(std::move(plan).value());
  ASSERT_EQ(a.frames.size(), 2u);
  const v1::ContourUpdate update = Update(a, 1);
  EXPECT_EQ(update.skin_version(), 1u);
  EXPECT_EQ(update.sections(), changed);
  ASSERT_EQ(update.balls_size(), 5);
  EXPECT_EQ(update.balls(2).r(), 3.5);

  book_.Unsubscribe(a.session_id);
  EXPECT_EQ(book_.subscriber_count(), 0u);
  Edit(Move(2, 0, 0, 3));
  EXPECT_EQ(a.frames.size(), 2u);
}

TEST_F(SkinBookTest, SliceSubscriberGetsACutWhenAnEditCrossesItsPlane) {
  levelset::SculptureOptions o;
  o.voxel_size = 1.0;
  o.half_width = 3;
  o.name = "clay";
  levelset::Sculpture sphere = std::move(levelset::Sculpture::MakeSphere(o, {0, 0, 0}, 10)).value();
  codec::ContourRequest req;
  req.object = "clay";
  req.plane = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};  // z = 0
  req.half_extent = 16;
  req.step = 1;
  FakeSink s(3);
  Status answer = Internal("not answered");
  book_.Subscribe(s.sink(), req, nullptr, 5, [&](Status st) { answer = st; });
  EXPECT_EQ(answer.code(), Status::Code::kNotFound);  // no such object
  ASSERT_NE(answer.violation(), nullptr);
  EXPECT_EQ(answer.violation()->field, "ContourSubscribe.slice.object");
  book_.Subscribe(s.sink(), req, &sphere, 5, [&](Status st) { answer = st; });
  ASSERT_TRUE(answer.ok()) << answer;
  ASSERT_EQ(s.frames.size(), 1u);
  EXPECT_EQ(Update(s, 0).object(), "clay");
  EXPECT_EQ(Update(s, 0).global_seq(), 5u);
  EXPECT_GT(Update(s, 0).sections(), 0u);
  // A leaf far above the plane leaves the cut as it was; one across it sends a new cut.
  book_.SendSlices("clay", sphere, {{0, 0, 24}}, 6);
  EXPECT_EQ(s.frames.size(), 1u);
  book_.SendSlices("clay", sphere, {{0, 0, -4}}, 7);
  ASSERT_EQ(s.frames.size(), 2u);
  EXPECT_EQ(Update(s, 1).global_seq(), 7u);
  book_.Unsubscribe(s.session_id);
  book_.SendSlices("clay", sphere, {{0, 0, -4}}, 8);
  EXPECT_EQ(s.frames.size(), 2u);
}

TEST_F(SkinBookTest, SweepRequestCarriesTheSkinsOutlineAndPlane) {
  codec::SkinSweepRequest sweep;
  sweep.skin = kSkin;
  sweep.object = "clay";
  sweep.depth = 4;
  auto q = book_.SweepRequestFor(sweep);
  ASSERT_TRUE(q.ok()) << q.status();
  EXPECT_EQ(q->depth, 4.0);
  EXPECT_EQ(q->plane.u.x, 1.0);
  EXPECT_EQ(q->outline.size(), book_.Copy(kSkin)->Outline().size());
  EXPECT_GT(q->outline.size(), 2u);
  sweep.skin = "nope";
  const Status st = book_.SweepRequestFor(sweep).status();
  EXPECT_EQ(st.code(), Status::Code::kNotFound);
  ASSERT_NE(st.violation(), nullptr);
  EXPECT_EQ(st.violation()->field, "SkinSweep.skin");
}

}  // namespace
}  // namespace sculpt::server
