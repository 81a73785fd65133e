#include "sculpt/haptics/sculpture_feed.h"

#include <gtest/gtest.h>

#include <memory>

#include "sculpt/haptics/monitored_device.h"
#include "sculpt/haptics/sculpture_snapshot.h"
#include "sculpt/levelset/edit.h"

namespace sculpt::haptics {
namespace {

std::shared_ptr<levelset::Sculpture> Sphere(double radius) {
  levelset::SculptureOptions o;
  o.voxel_size = 0.5;
  auto s = levelset::Sculpture::MakeSphere(o, {0, 0, 0}, radius);
  EXPECT_TRUE(s.ok()) << s.status();
  return std::make_shared<levelset::Sculpture>(std::move(s).value());
}

TEST(SculptureFeedTest, PublishesTheCopyItselfWithTheProducersSequence) {
  SnapshotPublisher publisher;
  SculptureFeed feed(&publisher, /*seal=*/true);
  const auto s = Sphere(6);
  feed.Publish(s, 42);
  feed.Publish(nullptr, 43);  // ignored
  const auto current = publisher.Current();
  ASSERT_EQ(current->version, 1u);
  const auto* snap = dynamic_cast<const SculptureSnapshot*>(current->sdf.get());
  ASSERT_NE(snap, nullptr);
  EXPECT_EQ(&snap->sculpture(), s.get()) << "shared, not copied";
  EXPECT_NEAR(snap->Phi({6, 0, 0}), 0, 0.05);
  const SculptureFeed::Stats st = feed.stats();
  EXPECT_EQ(st.published, 1u);
  EXPECT_EQ(st.last_seq, 42u);
  EXPECT_EQ(st.last_version, 1u);
}

// With a window, each snapshot carries the tool's neighbourhood densely; when the tool leaves
// it between copies, the latest copy is published again around the tool's new place.
TEST(SculptureFeedTest, WindowFollowsTheToolAndIsRecentredWithoutANewCopy) {
  SnapshotPublisher publisher;
  SculptureFeed feed(&publisher, /*seal=*/false);
  Vec3 tool{6, 0, 0};
  feed.SetWindow([&tool] { return tool; }, 2.0);
  EXPECT_FALSE(feed.RecentreWindow());  // nothing published yet
  const auto s = Sphere(6);
  feed.Publish(s, 1);
  const auto* snap = dynamic_cast<const SculptureSnapshot*>(publisher.Current()->sdf.get());
  ASSERT_NE(snap, nullptr);
  EXPECT_GT(snap->window_values(), 8u * 8 * 8);
  tool = {6.2, 0, 0};  // within a quarter of the radius: nothing to do
  EXPECT_FALSE(feed.RecentreWindow());
  tool = {0, 6, 0};
  EXPECT_TRUE(feed.RecentreWindow());
  ASSERT_EQ(publisher.Current()->version, 2u);
  const auto* moved = dynamic_cast<const SculptureSnapshot*>(publisher.Current()->sdf.get());
  ASSERT_NE(moved, nullptr);
  EXPECT_EQ(&moved->sculpture(), s.get()) << "the same copy again";
  EXPECT_EQ(moved->Phi({0, 6, 0}), snap->Phi({0, 6, 0}));
  const SculptureFeed::Stats st = feed.stats();
  EXPECT_EQ(st.windows, 2u);
  EXPECT_EQ(st.recentred, 1u);
  EXPECT_EQ(st.last_version, 2u);
}

TEST(SculptureFeedTest, CopyEditedAfterPublicationIsCountedAndItsTicksFound) {
  SnapshotPublisher publisher;
  SculptureFeed feed(&publisher, /*seal=*/true);
  // The producer breaks its promise: it keeps a writable handle and edits the copy it published.
  const auto torn = Sphere(6);
  feed.Publish(torn, 1);
  ScriptedDevice device([](double) { return Vec3{0, 0, 7}; });
  MonitoredDevice monitor(&device, &publisher, 8);
  monitor.Read(0);
  monitor.ApplyForce({0, 0, 1}, 0);
  levelset::EditRequest cut;
  cut.kind = levelset::EditKind::kSubtract;
  cut.tool = levelset::ToolShape::Sphere({0, 0, 6}, 2);
  ASSERT_TRUE(levelset::ApplyEdit(*torn, cut, levelset::EditSettings{}).ok());
  // Honest copies after it; the torn one is checked when the feed lets it go.
  for (uint64_t seq = 2; seq <= 1 + SculptureFeed::kHeld; ++seq) feed.Publish(Sphere(6), seq);
  monitor.Read(0.001);
  monitor.ApplyForce({0, 0, 0}, 0.001);
  feed.CheckHeld();
  const SculptureFeed::Stats st = feed.stats();
  EXPECT_EQ(st.published, 1 + SculptureFeed::kHeld);
  EXPECT_EQ(st.checked, st.published);
  EXPECT_EQ(st.changed, 1u);
  ASSERT_EQ(feed.changed_versions(), std::vector<uint64_t>{1});
  EXPECT_EQ(monitor.TicksOn(feed.changed_versions()), 1u) << "the tick that read version 1";
  const MonitoredDevice::ForceStats fs = monitor.force_stats();
  EXPECT_EQ(fs.ticks, 2u);
  EXPECT_EQ(fs.contact_ticks, 1u);
  EXPECT_EQ(fs.max_force, 1.0);
  EXPECT_EQ(fs.first_contact_s, 0.0);
  ASSERT_EQ(monitor.trace().size(), 2u);
  EXPECT_EQ(monitor.trace()[0].version, 1u);
  EXPECT_EQ(monitor.trace()[1].version, 1 + SculptureFeed::kHeld);
}

TEST(SculptureFeedTest, WithoutSealsNothingIsHashed) {
  SnapshotPublisher publisher;
  SculptureFeed feed(&publisher, /*seal=*/false);
  const auto s = Sphere(6);
  feed.Publish(s, 1);
  levelset::EditRequest cut;
  cut.kind = levelset::EditKind::kSubtract;
  cut.tool = levelset::ToolShape::Sphere({0, 0, 6}, 2);
  ASSERT_TRUE(levelset::ApplyEdit(*s, cut, levelset::EditSettings{}).ok());
  feed.CheckHeld();
  EXPECT_EQ(feed.stats().checked, 0u);
  EXPECT_EQ(feed.stats().changed, 0u);
  EXPECT_EQ(feed.stats().seal_ms, 0.0);
}

}  // namespace
}  // namespace sculpt::haptics
