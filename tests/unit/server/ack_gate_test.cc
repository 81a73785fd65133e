// AckGate: acknowledgements held until durable (locally, and under sync on the standby too),
// answered in sequence order, and the fall-back to async when the standby does not confirm.
#include "scene/ack_gate.h"

#include <gtest/gtest.h>

#include <atomic>
#include <mutex>
#include <thread>
#include <vector>

namespace sculpt::server {
namespace {

using std::chrono::milliseconds;

class AckGateTest : public ::testing::Test {
 protected:
  // A gate on an injected clock (the test calls CheckFallback; no timer thread).
  std::unique_ptr<AckGate> MakeGate(bool sync, milliseconds fallback) {
    AckGate::Options o;
    o.sync = sync;
    o.fallback = fallback;
    o.now = [this] { return now_; };
    return std::make_unique<AckGate>(std::move(o));
  }
  void Hold(AckGate& gate, uint64_t seq) {
    gate.Hold(seq, [this, seq] {
      std::lock_guard<std::mutex> lock(mu_);
      answered_.push_back(seq);
    });
  }
  std::vector<uint64_t> Answered() {
    std::lock_guard<std::mutex> lock(mu_);
    return answered_;
  }

  AckGate::Clock::time_point now_ = AckGate::Clock::time_point{} + std::chrono::hours(1);
  std::mutex mu_;
  std::vector<uint64_t> answered_;
};

TEST_F(AckGateTest, AsyncAnswersOnceTheLocalLogIsDurable) {
  auto gate = MakeGate(false, milliseconds(1000));
  Hold(*gate, 1);
  Hold(*gate, 3);
  EXPECT_TRUE(Answered().empty());
  gate->LocalDurable(2);
  EXPECT_EQ(Answered(), (std::vector<uint64_t>{1}));
  gate->LocalDurable(3);
  EXPECT_EQ(Answered(), (std::vector<uint64_t>{1, 3}));
  // The standby's word changes nothing under async.
  gate->StandbyDurable(100);
  EXPECT_EQ(gate->held(), 0u);
}

TEST_F(AckGateTest, SyncHoldsTheAckUntilTheStandbyIsDurable) {
  auto gate = MakeGate(true, milliseconds(1000));
  Hold(*gate, 1);
  Hold(*gate, 2);
  Hold(*gate, 3);
  gate->LocalDurable(3);
  EXPECT_TRUE(Answered().empty()) << "acknowledged before the standby had it";
  gate->StandbyDurable(2);
  EXPECT_EQ(Answered(), (std::vector<uint64_t>{1, 2}));
  EXPECT_EQ(gate->held(), 1u);
  // Either side may be behind: the lesser of the two bounds.
  Hold(*gate, 4);
  gate->StandbyDurable(4);
  EXPECT_EQ(Answered(), (std::vector<uint64_t>{1, 2, 3}));
  gate->LocalDurable(4);
  EXPECT_EQ(Answered(), (std::vector<uint64_t>{1, 2, 3, 4}));
  EXPECT_FALSE(gate->fallen_back());
  EXPECT_EQ(gate->standby_durable_seq(), 4u);
}

// Edits that never reach the standby's copy (ball edits, model intents: no object changed) wait
// for the standby only up to the seq before them, not for the next edit it does get.
TEST_F(AckGateTest, SkippedSeqsWaitForTheStandbyOnlyUpToTheSeqBeforeThem) {
  auto gate = MakeGate(true, milliseconds(0));  // never falls back: only Skip can release
  Hold(*gate, 1);
  gate->Skip(2, 2);
  Hold(*gate, 2);
  gate->Skip(3, 4);
  Hold(*gate, 4);
  Hold(*gate, 5);  // reaches the standby
  gate->LocalDurable(5);
  EXPECT_TRUE(Answered().empty()) << "a skipped seq went before the standby held seq 1";
  gate->StandbyDurable(1);
  EXPECT_EQ(Answered(), (std::vector<uint64_t>{1, 2, 4}));
  EXPECT_EQ(gate->held(), 1u) << "seq 5 reaches the standby and must wait for it";
  gate->StandbyDurable(5);
  EXPECT_EQ(Answered(), (std::vector<uint64_t>{1, 2, 4, 5}));
  // A skip the standby already passed changes nothing; one past a gap does not bridge it.
  gate->Skip(3, 3);
  gate->Skip(8, 8);
  Hold(*gate, 8);
  gate->LocalDurable(8);
  EXPECT_EQ(gate->held(), 1u) << "seqs 6-7 reach the standby: seq 8 waits for them";
  gate->StandbyDurable(7);
  EXPECT_EQ(Answered(), (std::vector<uint64_t>{1, 2, 4, 5, 8}));
  // Async ignores skips.
  auto async = MakeGate(false, milliseconds(0));
  async->Skip(1, 1);
  async->Hold(1, [] {});
  EXPECT_EQ(async->held(), 1u);
  async->LocalDurable(1);
  EXPECT_EQ(async->held(), 0u);
}

TEST_F(AckGateTest, StandbyOlderWordIsIgnored) {
  auto gate = MakeGate(true, milliseconds(1000));
  gate->LocalDurable(10);
  gate->StandbyDurable(5);
  gate->StandbyDurable(3);  // a late or repeated report never lowers the bound
  Hold(*gate, 5);
  Hold(*gate, 6);
  EXPECT_EQ(Answered(), (std::vector<uint64_t>{5}));
  EXPECT_EQ(gate->standby_durable_seq(), 5u);
}

TEST_F(AckGateTest, AnswersInSequenceOrderUnderConcurrentReleases) {
  // The local log's sync thread and the standby's session release at once (commit 1219ad8's
  // hazard): the answers still come out in sequence order.
  AckGate::Options o;
  o.sync = true;
  o.fallback = milliseconds(0);  // never fall back: only the two bounds release
  AckGate gate(std::move(o));
  constexpr uint64_t kN = 20000;
  std::atomic<uint64_t> held{0};
  std::thread producer([&] {
    for (uint64_t s = 1; s <= kN; ++s) {
      Hold(gate, s);
      held = s;
    }
  });
  std::thread local([&] {
    while (held.load() < kN) gate.LocalDurable(held.load());
    gate.LocalDurable(kN);
  });
  std::thread standby([&] {
    while (held.load() < kN) gate.StandbyDurable(held.load());
    gate.StandbyDurable(kN);
  });
  producer.join();
  local.join();
  standby.join();
  const std::vector<uint64_t> got = Answered();
  ASSERT_EQ(got.size(), kN);
  for (uint64_t i = 0; i < kN; ++i) ASSERT_EQ(got[i], i + 1) << "out of order at " << i;
}

TEST_F(AckGateTest, FallsBackToAsyncAfterTheWaitAndSaysSo) {
  auto gate = MakeGate(true, milliseconds(500));
  Hold(*gate, 1);
  Hold(*gate, 2);
  gate->LocalDurable(2);
  now_ += milliseconds(499);
  gate->CheckFallback();
  EXPECT_TRUE(Answered().empty()) << "fell back before sync_fallback_ms";
  EXPECT_FALSE(gate->fallen_back());
  now_ += milliseconds(2);
  gate->CheckFallback();
  EXPECT_EQ(Answered(), (std::vector<uint64_t>{1, 2}));
  EXPECT_TRUE(gate->fallen_back());
  EXPECT_EQ(gate->fallbacks(), 1u);
  // Async now: acknowledged as soon as the local log has it.
  Hold(*gate, 3);
  gate->LocalDurable(3);
  EXPECT_EQ(Answered(), (std::vector<uint64_t>{1, 2, 3}));
  // The standby catches up with what was held when it fell back: synchronous again.
  gate->StandbyDurable(1);
  EXPECT_TRUE(gate->fallen_back());
  gate->StandbyDurable(2);
  EXPECT_FALSE(gate->fallen_back());
  Hold(*gate, 4);
  gate->LocalDurable(4);
  EXPECT_EQ(gate->held(), 1u) << "back in sync, the ack waits for the standby again";
  gate->StandbyDurable(4);
  EXPECT_EQ(Answered(), (std::vector<uint64_t>{1, 2, 3, 4}));
}

TEST_F(AckGateTest, DoesNotFallBackWhileTheLocalLogIsTheOneBehind) {
  auto gate = MakeGate(true, milliseconds(100));
  Hold(*gate, 1);
  now_ += milliseconds(1000);
  gate->CheckFallback();
  EXPECT_FALSE(gate->fallen_back());
  EXPECT_EQ(gate->fallbacks(), 0u);
}

TEST_F(AckGateTest, ZeroFallbackHoldsForever) {
  auto gate = MakeGate(true, milliseconds(0));
  Hold(*gate, 1);
  gate->LocalDurable(1);
  now_ += std::chrono::hours(1);
  gate->CheckFallback();
  EXPECT_TRUE(Answered().empty());
  EXPECT_FALSE(gate->fallen_back());
}

TEST_F(AckGateTest, TimerThreadFallsBackOnTheRealClock) {
  AckGate::Options o;
  o.sync = true;
  o.fallback = milliseconds(50);
  AckGate gate(std::move(o));
  const auto t0 = AckGate::Clock::now();
  Hold(gate, 1);
  gate.LocalDurable(1);
  for (int i = 0; i < 400 && Answered().empty(); ++i) std::this_thread::sleep_for(milliseconds(5));
  const auto waited = AckGate::Clock::now() - t0;
  EXPECT_EQ(Answered(), (std::vector<uint64_t>{1}));
  EXPECT_GE(waited, milliseconds(50));
  EXPECT_TRUE(gate.fallen_back());
}

}  // namespace
}  // namespace sculpt::server
