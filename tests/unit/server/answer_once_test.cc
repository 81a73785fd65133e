#include "scene/answer_once.h"

#include <gtest/gtest.h>

#include <atomic>
#include <string>
#include <thread>
#include <vector>

namespace sculpt::server {
namespace {

TEST(AnswerOnceTest, ForwardsOnlyTheFirstCallOfAnyCopy) {
  std::vector<std::string> got;
  auto once =
      AnswerOnce(std::function<void(std::string)>([&](std::string s) { got.push_back(s); }));
  auto copy = once;
  copy("first");
  once("second");
  copy("third");
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0], "first");
}

TEST(AnswerOnceTest, OneOfManyConcurrentCallersWins) {
  std::atomic<int> calls{0};
  auto once = AnswerOnce(std::function<void(int)>([&](int) { ++calls; }));
  std::vector<std::thread> threads;
  for (int i = 0; i < 8; ++i) {
    threads.emplace_back([once, i] {
      for (int k = 0; k < 100; ++k) once(i);
    });
  }
  for (auto& t : threads) t.join();
  EXPECT_EQ(calls.load(), 1);
}

TEST(AnswerOnceTest, AnEmptyCallbackIsAnsweredWithoutCalling) {
  auto once = AnswerOnce(std::function<void(int)>());
  once(1);  // must not throw std::bad_function_call
  SUCCEED();
}

}  // namespace
}  // namespace sculpt::server
