#include "sculpt/haptics/haptic_settings.h"

#include <gtest/gtest.h>

#include <limits>

namespace sculpt::haptics {
namespace {

TEST(HapticSettingsTest, DefaultsAreValid) {
  EXPECT_TRUE(ValidateHapticSettings(HapticSettings{}).ok());
  HapticSettings p;
  p.model = ForceModel::kPenalty;
  p.damping = 0;  // the penalty model has no damper
  EXPECT_TRUE(ValidateHapticSettings(p).ok());
}

TEST(HapticSettingsTest, RejectsNanStiffness) {
  HapticSettings s;
  s.stiffness = std::numeric_limits<double>::quiet_NaN();
  const Status st = ValidateHapticSettings(s);
  EXPECT_EQ(st.code(), Status::Code::kInvalidArgument);
  EXPECT_NE(st.message().find("HapticSettings.stiffness=nan"), std::string::npos) << st;
}

TEST(HapticSettingsTest, RejectsProxyDampingBelowPassivityBound) {
  HapticSettings s;
  s.stiffness = 10;
  s.rate_hz = 1000;
  s.damping = 0.001;  // below k T / 2 = 0.005
  const Status st = ValidateHapticSettings(s);
  EXPECT_EQ(st.code(), Status::Code::kInvalidArgument);
  EXPECT_NE(st.message().find("HapticSettings.damping=0.001 outside [0.005"), std::string::npos)
      << st;
}

TEST(HapticSettingsTest, RejectsOutOfRangeFields) {
  auto bad = [](auto mutate) {
    HapticSettings s;
    mutate(s);
    return ValidateHapticSettings(s);
  };
  EXPECT_FALSE(bad([](HapticSettings& s) { s.rate_hz = 50; }).ok());
  EXPECT_FALSE(bad([](HapticSettings& s) { s.max_force = 0; }).ok());
  EXPECT_FALSE(bad([](HapticSettings& s) { s.blend_ms = -1; }).ok());
  EXPECT_FALSE(bad([](HapticSettings& s) { s.tool_samples = 0; }).ok());
  EXPECT_FALSE(bad([](HapticSettings& s) { s.tool_radius = -1; }).ok());
  EXPECT_FALSE(bad([](HapticSettings& s) { s.proxy_radius = 1e9; }).ok());
  EXPECT_FALSE(bad([](HapticSettings& s) { s.model = static_cast<ForceModel>(7); }).ok());
}

TEST(HapticSettingsTest, ParsesModelNames) {
  EXPECT_EQ(*ParseForceModel("penalty"), ForceModel::kPenalty);
  EXPECT_EQ(*ParseForceModel("proxy"), ForceModel::kProxy);
  EXPECT_STREQ(ForceModelName(ForceModel::kProxy), "proxy");
  const auto r = ParseForceModel("spring");
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("\"spring\""), std::string::npos);
}

}  // namespace
}  // namespace sculpt::haptics
