#include "sculpt/haptics/haptic_loop.h"

#include <gtest/gtest.h>

#include <pthread.h>
#include <sched.h>

#include <chrono>
#include <mutex>
#include <cmath>
#include <thread>

#include "unit/haptics/field_helpers.h"

namespace sculpt::haptics {

// Reaches SnapshotPublisher's mutex, to stand for a publisher held inside Publish.
class SnapshotPublisherTestPeer {
 public:
  static std::unique_lock<std::mutex> Lock(SnapshotPublisher& p) {
    return std::unique_lock<std::mutex>(p.publish_mu_);
  }
};

namespace {

using namespace std::chrono_literals;

TEST(SnapshotPublisherTest, VersionsIncreaseAndOldOnesAreReleased) {
  SnapshotPublisher pub;
  EXPECT_EQ(pub.Current()->version, 0u);
  EXPECT_EQ(pub.Current()->sdf, nullptr);
  std::weak_ptr<const SdfSampler> first;
  {
    auto f = testing::Floor(0, 8);
    first = f;
    pub.Publish(f);
  }
  EXPECT_EQ(pub.Current()->version, 1u);
  for (size_t i = 0; i < SnapshotPublisher::kRetained; ++i) pub.Publish(testing::Floor(1, 8));
  EXPECT_EQ(pub.Current()->version, 1 + SnapshotPublisher::kRetained);
  EXPECT_TRUE(first.expired());  // freed on the publishing thread once out of the retained set
}

TEST(SnapshotPublisherTest, TryUpdateTakesOnlyANewerSnapshot) {
  SnapshotPublisher pub;
  std::shared_ptr<const Snapshot> held = pub.Current();
  EXPECT_FALSE(pub.TryUpdate(&held));  // nothing published yet
  EXPECT_EQ(held->version, 0u);
  const auto floor = testing::Floor(0, 8);
  pub.Publish(floor);
  EXPECT_EQ(pub.latest_version(), 1u);
  EXPECT_TRUE(pub.TryUpdate(&held));
  EXPECT_EQ(held->version, 1u);
  EXPECT_EQ(held->sdf, floor);
  EXPECT_FALSE(pub.TryUpdate(&held));
  pub.Publish(nullptr);
  pub.Publish(floor);
  EXPECT_TRUE(pub.TryUpdate(&held));  // straight to the latest, skipping version 2
  EXPECT_EQ(held->version, 3u);
}

// The loop's side never waits for a publisher: while one holds the publishers' mutex (inside
// Publish), TryUpdate gives up at once (the loop keeps its snapshot for the tick) and takes the
// new one after.
TEST(SnapshotPublisherTest, TryUpdateNeverWaitsForAPublisherInsidePublish) {
  SnapshotPublisher pub;
  pub.Publish(testing::Floor(0, 8));
  std::shared_ptr<const Snapshot> held = pub.Current();
  pub.Publish(testing::Floor(1, 8));
  ASSERT_EQ(held->version, 1u);
  ASSERT_EQ(pub.latest_version(), 2u);
  {
    std::unique_lock<std::mutex> inside = SnapshotPublisherTestPeer::Lock(pub);
    const auto t0 = std::chrono::steady_clock::now();
    for (int i = 0; i < 1000; ++i) EXPECT_FALSE(pub.TryUpdate(&held));
    // The calls above would hang, not fail, if TryUpdate waited; the time is only a report.
    EXPECT_LT(std::chrono::steady_clock::now() - t0, 1s);
    EXPECT_EQ(held->version, 1u);
  }
  EXPECT_TRUE(pub.TryUpdate(&held));
  EXPECT_EQ(held->version, 2u);
}

TEST(HapticLoopTest, RejectsNullDeviceAndBadSettings) {
  SnapshotPublisher pub;
  EXPECT_FALSE(HapticLoop::Create(HapticSettings{}, &pub, nullptr).ok());
  ScriptedDevice dev([](double) { return Vec3{}; });
  HapticSettings bad;
  bad.rate_hz = 0;
  const auto r = HapticLoop::Create(bad, &pub, &dev);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("HapticSettings.rate_hz=0"), std::string::npos);
}

// The thread runs for a fifth of a second: it ticks near its rate, sees the snapshots published
// meanwhile, renders a force, counts NaN samples, and exposes the pose to the stroke sampler.
TEST(HapticLoopTest, TicksRendersAndCountsOnItsOwnThread) {
  SnapshotPublisher pub;
  pub.Publish(testing::Floor(0));
  // Device: 1 deep in the floor, with a dropout every 50th millisecond.
  ScriptedDevice dev([](double t) {
    const long ms = std::lround(t * 1000);
    return ms % 50 == 25 ? Vec3{NAN, 0, 0} : Vec3{0.001 * ms, 0, -1};
  });
  HapticSettings s;
  auto loop = HapticLoop::Create(s, &pub, &dev);
  ASSERT_TRUE(loop.ok()) << loop.status();
  ASSERT_TRUE((*loop)->Start().ok());
  EXPECT_FALSE((*loop)->Start().ok());
  std::this_thread::sleep_for(80ms);
  pub.Publish(testing::Floor(0.5));
  std::this_thread::sleep_for(120ms);
  const DeviceSample pose = (*loop)->SamplePose();
  (*loop)->Stop();
  const HapticLoopStats st = (*loop)->stats();
  EXPECT_FALSE((*loop)->running());
  EXPECT_GT(st.ticks, 100u);  // 200 ms at 1 kHz, with room for a loaded machine
  EXPECT_GT(st.rate_hz, 500);
  EXPECT_LT(st.rate_hz, 1100);
  EXPECT_EQ(st.snapshots_seen, 2u);
  EXPECT_GE(st.snapshot_lag_max_ms, 0);
  EXPECT_GT(st.nan_samples, 0u);
  EXPECT_GT(st.tick_cost_max_us, 0);
  EXPECT_LE(st.tick_cost_p50_us, st.tick_cost_p99_us);
  EXPECT_LE(st.tick_cost_p99_us, st.tick_cost_max_us);
  EXPECT_TRUE(st.contact);
  EXPECT_GT(st.last_force.z, 0);
  EXPECT_TRUE(pose.position.IsFinite());
  EXPECT_NEAR(pose.position.z, -1, 1e-12);
  EXPECT_GT(dev.last_force().z, 0);
}

// The loop reports what it got from the OS: SCHED_FIFO where it may (root here), SCHED_OTHER
// when it does not ask; pinned to the last allowed CPU when there are two or more.
TEST(HapticLoopTest, ReportsSchedulingClassMemoryLockAndCpu) {
  cpu_set_t allowed;
  CPU_ZERO(&allowed);
  ASSERT_EQ(sched_getaffinity(0, sizeof(allowed), &allowed), 0);
  int last = -1;
  for (int c = 0; c < CPU_SETSIZE; ++c) {
    if (CPU_ISSET(c, &allowed)) last = c;
  }
  for (bool realtime : {true, false}) {
    SnapshotPublisher pub;
    pub.Publish(testing::Floor(0));
    ScriptedDevice dev([](double) { return Vec3{0, 0, 1}; });
    HapticLoopOptions o;
    o.realtime = realtime;
    auto loop = HapticLoop::Create(HapticSettings{}, &pub, &dev, o);
    ASSERT_TRUE(loop.ok()) << loop.status();
    EXPECT_EQ((*loop)->cpu(), CPU_COUNT(&allowed) >= 2 ? last : -1);
    EXPECT_TRUE((*loop)->stats().scheduling.empty());  // not started yet
    ASSERT_TRUE((*loop)->Start().ok());
    std::this_thread::sleep_for(30ms);
    (*loop)->Stop();
    const HapticLoopStats st = (*loop)->stats();
    if (realtime) {
      EXPECT_TRUE(st.scheduling == "SCHED_FIFO" || st.scheduling == "SCHED_OTHER")
          << st.scheduling;
      if (st.scheduling == "SCHED_FIFO") {
        EXPECT_GT(st.priority, 0);
      }
    } else {
      EXPECT_EQ(st.scheduling, "SCHED_OTHER");
    }
    EXPECT_EQ(st.cpu, (*loop)->cpu());
    EXPECT_EQ(st.ticks_over_budget, 0u);  // no budget set: never cut short
  }
}

TEST(HapticLoopTest, PinThreadAwayFromCpuLeavesTheLoopsCpuOut) {
  EXPECT_FALSE(PinThreadAwayFromCpu(-1));
  cpu_set_t allowed;
  CPU_ZERO(&allowed);
  ASSERT_EQ(sched_getaffinity(0, sizeof(allowed), &allowed), 0);
  int first = -1;
  for (int c = 0; c < CPU_SETSIZE && first < 0; ++c) {
    if (CPU_ISSET(c, &allowed)) first = c;
  }
  // On a thread of its own, so the test's thread keeps its affinity.
  std::thread t([&] {
    const bool pinned = PinThreadAwayFromCpu(first);
    EXPECT_EQ(pinned, CPU_COUNT(&allowed) >= 2);
    cpu_set_t now;
    CPU_ZERO(&now);
    ASSERT_EQ(pthread_getaffinity_np(pthread_self(), sizeof(now), &now), 0);
    EXPECT_EQ(CPU_ISSET(first, &now) != 0, !pinned);
  });
  t.join();
}

}  // namespace
}  // namespace sculpt::haptics
