// FairQueue (server/src/scene/fair_queue.h): the order in which the compute thread serves jobs,
// asserted as orders (costs are given, not timed).
#include "scene/fair_queue.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace sculpt::server {
namespace {

using Queue = FairQueue<std::string>;

// Serves everything, each client job costing `cost(job)`; returns the jobs in service order.
template <typename Cost>
std::vector<std::string> Drain(Queue& q, Cost cost) {
  std::vector<std::string> order;
  while (!q.empty()) {
    uint64_t who = 0;
    order.push_back(q.Pop(&who));
    q.Done(cost(order.back()));
  }
  return order;
}

// "a" + "7" without g++ 12's false -Wrestrict on `const char* + std::string&&` (bug 105329).
std::string Name(const char* prefix, uint64_t i) {
  return std::string(prefix).append(std::to_string(i));
}

size_t IndexOf(const std::vector<std::string>& order, const std::string& job) {
  for (size_t i = 0; i < order.size(); ++i) {
    if (order[i] == job) return i;
  }
  return order.size();
}

TEST(FairQueueTest, ABacklogOfFiftyDelaysAnotherRequestersSingleJobByAtMostOneJob) {
  Queue q;
  for (int i = 0; i < 50; ++i) q.Push(1, Name("a", i));
  // a0 is in service when b's job arrives.
  uint64_t who = 0;
  EXPECT_EQ(q.Pop(&who), "a0");
  EXPECT_EQ(who, 1u);
  q.Push(2, "b0");
  q.Done(30);
  const std::vector<std::string> order = Drain(q, [](const std::string&) { return 30; });
  EXPECT_EQ(order.front(), "b0") << "b waited for more than the job of a in service";
  EXPECT_EQ(q.passed_over(), 1u) << "b's job, and only it, went ahead of older ones (a1)";
}

TEST(FairQueueTest, AJobArrivingBehindABacklogIsServedNextWhateverTheBacklogsCost) {
  Queue q;
  for (int i = 0; i < 50; ++i) q.Push(1, Name("a", i));  // heavy: 500 each
  q.Push(2, "b0");                                                  // cheap
  const std::vector<std::string> order =
      Drain(q, [](const std::string& j) { return j[0] == 'a' ? 500 : 1; });
  EXPECT_LE(IndexOf(order, "b0"), 1u) << "at most one job of a before b's";
  EXPECT_GE(q.passed_over(), 1u) << "b's later job went ahead of a's older ones";
}

TEST(FairQueueTest, EachRequestersJobsKeepTheirOrder) {
  Queue q;
  for (int i = 0; i < 20; ++i) {
    q.Push(1 + i % 3, std::to_string(1 + i % 3).append(":").append(std::to_string(i)));
  }
  const std::vector<std::string> order =
      Drain(q, [](const std::string& j) { return j[0] == '1' ? 100 : 7; });
  ASSERT_EQ(order.size(), 20u);
  for (char r : {'1', '2', '3'}) {
    int last = -1;
    for (const std::string& j : order) {
      if (j[0] != r) continue;
      const int i = std::stoi(j.substr(2));
      EXPECT_GT(i, last) << "requester " << r << " reordered";
      last = i;
    }
  }
}

TEST(FairQueueTest, SharesByCostNotByCount) {
  // a's jobs cost 10, b's cost 1: while both are busy, b runs about ten jobs per job of a.
  Queue q;
  for (int i = 0; i < 10; ++i) q.Push(1, Name("a", i));
  for (int i = 0; i < 100; ++i) q.Push(2, Name("b", i));
  const std::vector<std::string> order =
      Drain(q, [](const std::string& j) { return j[0] == 'a' ? 10 : 1; });
  // Among the first 55 served, the costs are shared evenly: 5 of a's (50) and 50 of b's (50).
  int a = 0;
  for (size_t i = 0; i < 55; ++i) a += order[i][0] == 'a';
  EXPECT_GE(a, 4);
  EXPECT_LE(a, 6);
}

TEST(FairQueueTest, IdleTimeBanksNoCredit) {
  Queue q;
  // b runs alone for a long time (cost 1000), then a arrives with a backlog: a gets no credit
  // for having been idle, and b none for what it ran before a came: they alternate.
  q.Push(2, "b0");
  uint64_t who = 0;
  q.Pop(&who);
  q.Done(1000);
  for (int i = 1; i <= 5; ++i) q.Push(2, Name("b", i));
  for (int i = 0; i < 5; ++i) q.Push(1, Name("a", i));
  const std::vector<std::string> order = Drain(q, [](const std::string&) { return 10; });
  // b ran alone and the queue emptied: no debt is carried into the next busy period.
  EXPECT_LE(IndexOf(order, "a0"), 1u);
  EXPECT_LE(IndexOf(order, "b1"), 1u);
}

TEST(FairQueueTest, ADebtRunUpWhileOthersWaitedIsKeptWhenTheRequesterComesBack) {
  Queue q;
  q.Push(1, "a0");
  for (int i = 0; i < 5; ++i) q.Push(2, Name("b", i));
  uint64_t who = 0;
  EXPECT_EQ(q.Pop(&who), "a0");
  q.Done(100);  // a ran 100 while b waited, then went idle
  q.Push(1, "a1");
  const std::vector<std::string> order = Drain(q, [](const std::string&) { return 1; });
  EXPECT_EQ(order.back(), "a1") << "a came back and went ahead of b despite its debt";
}

TEST(FairQueueTest, PriorityJobsGoFirstAndOrderedJobsSeeEveryEarlierJob) {
  Queue q;
  q.Push(1, "a0");
  q.Push(1, "a1");
  q.PushOrdered("flush");  // must see a0, a1
  q.Push(2, "b0");         // posted after the flush: after it
  q.PushPriority("mesh");  // ahead of all
  q.PushPriority("mesh2");
  const std::vector<std::string> order = Drain(q, [](const std::string&) { return 5; });
  const std::vector<std::string> want = {"mesh", "mesh2", "a0", "a1", "flush", "b0"};
  EXPECT_EQ(order, want);
}

TEST(FairQueueTest, OrderedJobsKeepTheirOrderAndRequesterZeroIsOrdered) {
  Queue q;
  q.Push(Queue::kSystem, "s0");
  q.Push(3, "c0");
  q.PushOrdered("s1");
  q.Push(Queue::kSystem, "s2");
  const std::vector<std::string> order = Drain(q, [](const std::string&) { return 5; });
  const std::vector<std::string> want = {"s0", "c0", "s1", "s2"};
  EXPECT_EQ(order, want);
}

TEST(FairQueueTest, ManyRequestersWithOneJobEachAreServedInArrivalOrder) {
  // Equal virtual starts: ties go by posting order (round robin over new arrivals).
  Queue q;
  for (uint64_t r = 1; r <= 10; ++r) q.Push(r, Name("r", r));
  const std::vector<std::string> order = Drain(q, [](const std::string&) { return 3; });
  for (size_t i = 0; i < order.size(); ++i) EXPECT_EQ(order[i], Name("r", i + 1));
  EXPECT_EQ(q.passed_over(), 0u);
  EXPECT_EQ(q.waiting_requesters(), 0u);
}

}  // namespace
}  // namespace sculpt::server
