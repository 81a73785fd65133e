#include "sculpt/haptics/haptic_device.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <fstream>

namespace sculpt::haptics {
namespace {

std::string TempPath(const char* name) {
  return ::testing::TempDir() + "/" + name + "_" + std::to_string(::getpid());
}

TEST(RecordedDeviceTest, SaveLoadRoundTripAndInterpolates) {
  const std::string path = TempPath("traj.txt");
  ASSERT_TRUE(RecordedDevice::Save(path, {{0.0, {0, 0, 0}}, {1.0, {2, 4, 6}}}).ok());
  auto d = RecordedDevice::Load(path);
  ASSERT_TRUE(d.ok()) << d.status();
  EXPECT_EQ(d->points().size(), 2u);
  const DeviceSample s = d->Read(0.25);
  EXPECT_NEAR(s.position.x, 0.5, 1e-12);
  EXPECT_NEAR(s.position.z, 1.5, 1e-12);
  EXPECT_EQ(d->Read(5.0).position, (Vec3{2, 4, 6}));   // held at the end
  EXPECT_EQ(d->Read(-1.0).position, (Vec3{0, 0, 0}));  // and at the start
  d->ApplyForce({1, 2, 3}, 0.5);
  ASSERT_EQ(d->forces().size(), 1u);
  std::remove(path.c_str());
}

TEST(RecordedDeviceTest, ReplaysNanAsDropout) {
  const std::string path = TempPath("nan.txt");
  {
    std::ofstream out(path);
    out << "# t x y z\n0 0 0 0\n0.001 nan 0 0\n\n0.002 1 1 1\n";
  }
  auto d = RecordedDevice::Load(path);
  ASSERT_TRUE(d.ok()) << d.status();
  EXPECT_TRUE(std::isnan(d->Read(0.001).position.x));
  EXPECT_TRUE(d->Read(0.002).position.IsFinite());
  std::remove(path.c_str());
}

TEST(RecordedDeviceTest, RejectsMalformedLine) {
  const std::string path = TempPath("bad.txt");
  {
    std::ofstream out(path);
    out << "0 0 0 0\n0.1 1 two 3\n";
  }
  auto d = RecordedDevice::Load(path);
  ASSERT_FALSE(d.ok());
  EXPECT_NE(d.status().message().find(":2:"), std::string::npos) << d.status();
  std::remove(path.c_str());
}

TEST(RecordedDeviceTest, RejectsDecreasingTimes) {
  auto d = RecordedDevice::FromPoints({{0.0, {}}, {0.5, {}}, {0.4, {}}});
  ASSERT_FALSE(d.ok());
  EXPECT_NE(d.status().message().find("points[2].t=0.4 outside (0.5, inf)"), std::string::npos)
      << d.status();
}

TEST(RecordedDeviceTest, RejectsMissingFile) {
  EXPECT_EQ(RecordedDevice::Load("/nonexistent/traj.txt").status().code(),
            Status::Code::kNotFound);
}

TEST(SpringMassHandTest, FallsUnderGravityAndReactsToForce) {
  SpringMassHand::Params p;
  p.mass = 0.1;
  p.gravity = {0, 0, -10};
  SpringMassHand hand(p, {0, 0, 0});
  for (int i = 0; i <= 100; ++i) hand.ApplyForce({}, i * 1e-3);
  // 0.1 s of free fall: v = -1, z ~ -0.05.
  EXPECT_NEAR(hand.velocity().z, -1.0, 1e-9);
  EXPECT_NEAR(hand.position().z, -0.05, 1e-3);
  // A force of m g upwards holds it: the speed stops changing.
  const double v = hand.velocity().z;
  for (int i = 101; i <= 200; ++i) hand.ApplyForce({0, 0, 1.0}, i * 1e-3);
  EXPECT_NEAR(hand.velocity().z, v, 1e-9);
}

TEST(SpringMassHandTest, HandSpringFollowsIntent) {
  SpringMassHand::Params p;
  p.mass = 0.05;
  p.hand_stiffness = 50;
  p.hand_damping = 2;
  SpringMassHand hand(p, {0, 0, 0}, [](double) { return Vec3{1, 0, 0}; });
  for (int i = 0; i <= 3000; ++i) hand.ApplyForce({}, i * 1e-3);
  EXPECT_NEAR(hand.position().x, 1.0, 1e-3);
}

TEST(ScriptedDeviceTest, FollowsItsPath) {
  ScriptedDevice d([](double t) { return Vec3{t, 2 * t, 0}; });
  EXPECT_EQ(d.Read(0.5).position, (Vec3{0.5, 1.0, 0}));
  d.ApplyForce({0, 0, 3}, 0.5);
  EXPECT_EQ(d.last_force(), (Vec3{0, 0, 3}));
}

}  // namespace
}  // namespace sculpt::haptics
