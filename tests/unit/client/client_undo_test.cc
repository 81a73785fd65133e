/// @brief Client::Undo / Redo / SendUndo / WaitUndoAck against FakeSculptd: the request on the
/// wire, its answers (accepted, refused by ack, refused by Error, unknown to the server), the
/// shared sequence with strokes, and the resend after a reconnect in client_seq order.
#include "sculpt/client/client.h"

#include <gtest/gtest.h>

#include <chrono>
#include <memory>
#include <string>
#include <vector>

#include "unit/client/fake_sculptd.h"

namespace sculpt::client {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;
using testing_support::AcceptedUndo;
using testing_support::ErrorMessage;
using testing_support::FakeSculptd;
using Reply = FakeSculptd::Reply;

StrokeRequest Press() {
  StrokeRequest s;
  s.object = "clay";
  for (int k = 0; k < 2; ++k) {
    codec::Pose p;
    p.position = {0.5 * k, 0, 23};
    p.t_ms = static_cast<uint32_t>(8 * k);
    s.poses.push_back(p);
  }
  return s;
}

v1::ServerMessage StrokeAck(uint64_t client_seq, uint64_t global_seq) {
  v1::ServerMessage m;
  m.mutable_ack()->set_client_seq(client_seq);
  m.mutable_ack()->set_global_seq_first(global_seq);
  m.mutable_ack()->set_edits(2);
  return m;
}

class ClientUndoTest : public ::testing::Test {
 protected:
  /// A client joined to the fake server as a sculptor (scene "fake": clay, stone).
  std::unique_ptr<Client> Joined(ClientOptions options = {}) {
    options.timeout = seconds(5);
    options.skip_state = true;
    auto c = std::make_unique<Client>(options);
    EXPECT_TRUE(c->Connect("127.0.0.1", fake_.port()).ok());
    EXPECT_TRUE(c->Hello("t", v1::ROLE_SCULPTOR, "u", 77).ok());
    EXPECT_TRUE(c->Join().ok());
    return c;
  }

  FakeSculptd fake_;
};

TEST_F(ClientUndoTest, UndoSendsItsRequestAndReturnsTheAck) {
  fake_.set_handler([](const v1::ClientMessage& m, int) {
    Reply r;
    if (!m.has_undo()) return r;
    v1::ServerMessage a = AcceptedUndo(m.undo(), 41, 17);
    a.mutable_undo_ack()->set_replayed(3);
    v1::ReplayedEdits* by = a.mutable_undo_ack()->add_replayed_by();
    by->set_author("alice");
    by->set_edits(3);
    a.mutable_undo_ack()->set_undo_depth(5);
    a.mutable_undo_ack()->set_redo_depth(1);
    r.messages.push_back(a);
    return r;
  });
  auto c = Joined();
  auto ack = c->Undo("stone");
  ASSERT_TRUE(ack.ok()) << ack.status();
  EXPECT_TRUE(ack->accepted());
  EXPECT_FALSE(ack->redo());
  EXPECT_EQ(ack->global_seq(), 41u);
  EXPECT_EQ(ack->target_seq(), 17u);
  EXPECT_EQ(ack->replayed(), 3u);
  ASSERT_EQ(ack->replayed_by_size(), 1);
  EXPECT_EQ(ack->replayed_by(0).author(), "alice");
  EXPECT_EQ(ack->undo_depth(), 5u);
  EXPECT_EQ(ack->redo_depth(), 1u);

  auto redo = c->Redo();
  ASSERT_TRUE(redo.ok()) << redo.status();
  EXPECT_TRUE(redo->redo());

  const std::vector<v1::UndoRequest> sent = fake_.undos();
  ASSERT_EQ(sent.size(), 2u);
  EXPECT_EQ(sent[0].client_seq(), ack->client_seq());
  EXPECT_EQ(sent[0].object(), "stone");
  EXPECT_FALSE(sent[0].redo());
  EXPECT_EQ(sent[1].object(), "clay") << "no object: the scene's first";
  EXPECT_TRUE(sent[1].redo());
  EXPECT_GT(sent[1].client_seq(), sent[0].client_seq());

  const ClientStats st = c->stats();
  EXPECT_EQ(st.undos_sent, 2u);
  EXPECT_EQ(st.undo_acks, 2u);
  EXPECT_EQ(st.undos_refused, 0u);
  EXPECT_EQ(c->unacked(), 0u);
  // The ack is an event too (delivered once WaitAllAcked returns).
  ASSERT_TRUE(c->WaitAllAcked(seconds(5)));
  int events = 0;
  for (const Event& e : c->DrainEvents()) events += e.type == Event::Type::kUndoAck;
  EXPECT_EQ(events, 2);
}

TEST_F(ClientUndoTest, UndoSharesTheStrokeSequenceFromFirstClientSeq) {
  ClientOptions o;
  o.first_client_seq = 1000;
  auto c = Joined(o);
  auto s1 = c->SendStroke(Press());
  auto u = c->SendUndo("clay");
  auto s2 = c->SendStroke(Press());
  ASSERT_TRUE(s1.ok() && u.ok() && s2.ok());
  EXPECT_EQ(*s1, 1000u);
  EXPECT_EQ(*u, 1001u);
  EXPECT_EQ(*s2, 1002u);
  ASSERT_TRUE(fake_.WaitFor([](const auto& r) { return r.size() >= 5; }));
  const auto got = fake_.received();
  EXPECT_EQ(got[2].second.stroke().client_seq(), 1000u);
  EXPECT_EQ(got[3].second.undo().client_seq(), 1001u);
  EXPECT_EQ(got[4].second.stroke().client_seq(), 1002u);
}

TEST_F(ClientUndoTest, NothingToUndoIsFailedPrecondition) {
  fake_.set_handler([](const v1::ClientMessage& m, int) {
    Reply r;
    v1::ServerMessage a;
    a.mutable_undo_ack()->set_client_seq(m.undo().client_seq());
    a.mutable_undo_ack()->set_accepted(false);
    *a.mutable_undo_ack()->mutable_error() =
        ErrorMessage(v1::ERROR_CODE_FAILED_PRECONDITION, "", m.undo().client_seq(),
                     "undo: author=\"77\" has nothing to undo")
            .error();
    r.messages.push_back(a);
    return r;
  });
  auto c = Joined();
  auto ack = c->Undo();
  ASSERT_FALSE(ack.ok());
  EXPECT_EQ(ack.status().code(), Status::Code::kFailedPrecondition);
  EXPECT_NE(ack.status().message().find("nothing to undo"), std::string::npos)
      << ack.status().message();
  EXPECT_EQ(c->stats().undos_refused, 1u);
  EXPECT_EQ(c->unacked(), 0u);
}

TEST_F(ClientUndoTest, ErrorNamingTheRequestSettlesItAndNoStroke) {
  // A viewer's undo is refused before the history with a plain Error naming its client_seq.
  fake_.set_handler([](const v1::ClientMessage& m, int) {
    Reply r;
    if (m.has_undo()) {
      r.messages.push_back(ErrorMessage(v1::ERROR_CODE_PERMISSION_DENIED, "Hello.role",
                                        m.undo().client_seq(), "viewers may not edit"));
    }
    return r;
  });
  auto c = Joined();
  auto stroke = c->SendStroke(Press());  // left pending: the fake never acks strokes
  ASSERT_TRUE(stroke.ok());
  auto seq = c->SendUndo("clay");
  ASSERT_TRUE(seq.ok());
  auto ack = c->WaitUndoAck(*seq, seconds(5));
  ASSERT_TRUE(ack.ok()) << ack.status();
  EXPECT_FALSE(ack->accepted());
  EXPECT_EQ(ack->client_seq(), *seq);
  EXPECT_EQ(ack->error().code(), v1::ERROR_CODE_PERMISSION_DENIED);
  EXPECT_EQ(c->stats().refused, 0u) << "the stroke was not the one refused";
  EXPECT_EQ(c->UnackedSeqs(), std::vector<uint64_t>{*stroke});
  // Each answer is returned once.
  EXPECT_EQ(c->WaitUndoAck(*seq, milliseconds(10)).status().code(), Status::Code::kNotFound);
}

TEST_F(ClientUndoTest, ServerWithoutUndoAnswersAtOnce) {
  // A sculptd older than undo: unknown message body, an Error without a client_seq.
  fake_.set_handler([](const v1::ClientMessage& m, int) {
    Reply r;
    if (m.has_undo()) {
      r.messages.push_back(
          ErrorMessage(v1::ERROR_CODE_MALFORMED, "ClientMessage.body", 0, "unknown message"));
    }
    return r;
  });
  auto c = Joined();
  const auto start = std::chrono::steady_clock::now();
  auto ack = c->Undo();
  ASSERT_FALSE(ack.ok());
  EXPECT_EQ(ack.status().code(), Status::Code::kInvalidArgument);
  EXPECT_NE(ack.status().message().find("MALFORMED"), std::string::npos) << ack.status();
  EXPECT_LT(std::chrono::steady_clock::now() - start, seconds(4)) << "waited for the timeout";
  EXPECT_EQ(c->unacked(), 0u);
}

TEST_F(ClientUndoTest, ResentWithStrokesInSequenceOrderAfterReconnect) {
  // Connection 0 answers nothing; connection 1 answers everything.
  fake_.set_handler([](const v1::ClientMessage& m, int connection) {
    Reply r;
    if (connection == 0) return r;
    if (m.has_stroke()) r.messages.push_back(StrokeAck(m.stroke().client_seq(), 10));
    if (m.has_undo()) r.messages.push_back(AcceptedUndo(m.undo(), 12, 10));
    return r;
  });
  auto c = Joined();
  auto s1 = c->SendStroke(Press());
  auto u = c->SendUndo("clay");
  auto s2 = c->SendStroke(Press());
  ASSERT_TRUE(s1.ok() && u.ok() && s2.ok());
  ASSERT_TRUE(fake_.WaitFor([](const auto& r) { return r.size() >= 5; }));
  c->DropConnection();
  // Lost while waiting: answered at once, the request stays pending.
  auto lost = c->WaitUndoAck(*u, seconds(5));
  EXPECT_EQ(lost.status().code(), Status::Code::kUnavailable);
  EXPECT_EQ(c->unacked(), 3u);

  ASSERT_TRUE(c->Reconnect().ok());
  auto ack = c->WaitUndoAck(*u, seconds(5));
  ASSERT_TRUE(ack.ok()) << ack.status();
  EXPECT_TRUE(ack->accepted());
  ASSERT_TRUE(c->WaitAllAcked(seconds(5)));

  std::vector<uint64_t> resent;
  for (const auto& [connection, m] : fake_.received()) {
    if (connection != 1) continue;
    if (m.has_stroke()) resent.push_back(m.stroke().client_seq());
    if (m.has_undo()) resent.push_back(m.undo().client_seq());
  }
  EXPECT_EQ(resent, (std::vector<uint64_t>{*s1, *u, *s2}));
  EXPECT_EQ(c->stats().undos_resent, 1u);
  EXPECT_EQ(c->stats().strokes_resent, 2u);
}

TEST_F(ClientUndoTest, TimesOutAsUnavailable) {
  auto c = Joined();
  auto seq = c->SendUndo("clay");
  ASSERT_TRUE(seq.ok());
  auto ack = c->WaitUndoAck(*seq, milliseconds(200));
  EXPECT_EQ(ack.status().code(), Status::Code::kUnavailable);
  EXPECT_NE(ack.status().message().find("no UndoAck"), std::string::npos) << ack.status();
  EXPECT_EQ(c->unacked(), 1u) << "still pending: a late answer or a resend settles it";
}

TEST_F(ClientUndoTest, RejectsUnknownObjectAndUndoBeforeJoin) {
  Client fresh;
  EXPECT_EQ(fresh.SendUndo("clay").status().code(), Status::Code::kFailedPrecondition);
  EXPECT_EQ(fresh.Undo().status().code(), Status::Code::kFailedPrecondition);
  auto c = Joined();
  auto bad = c->SendUndo("marble");
  EXPECT_EQ(bad.status().code(), Status::Code::kNotFound);
  EXPECT_NE(bad.status().message().find("UndoRequest.object=marble"), std::string::npos);
  EXPECT_TRUE(fake_.undos().empty());
}

TEST_F(ClientUndoTest, ClockClientSeqIsAboveAnEarlierRunsSequences) {
  const uint64_t a = ClockClientSeq();
  EXPECT_GT(a, uint64_t{1} << 50) << "microseconds since 1970";
  EXPECT_GE(ClockClientSeq(), a);
}

}  // namespace
}  // namespace sculpt::client
