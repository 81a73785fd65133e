#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "config/server_config.h"
#include "config/seats.h"

namespace sculpt::server {
namespace {

std::string WriteToml(const std::string& name, const std::string& text) {
  const auto p = std::filesystem::temp_directory_path() / ("sculpt_limits_" + name + ".toml");
  std::ofstream(p) << text;
  return p.string();
}

TEST(LimitsConfigTest, ReadsTheConnectionAndFairnessKeys) {
  ServerConfig c;
  const Status s = LoadConfigFile(WriteToml("all", R"([limits]
max_sessions = 300
max_connections_per_source = 7
reserved_sculptor_seats = 3
join_timeout_ms = 2000
idle_timeout_ms = 60000
frame_timeout_ms = 4000
requests_per_second = 12.5
request_burst = 50
source_rate_factor = 2
)"),
                                  &c);
  ASSERT_TRUE(s.ok()) << s;
  EXPECT_EQ(c.limits.max_sessions, 300u);
  EXPECT_EQ(c.limits.max_connections_per_source, 7u);
  EXPECT_EQ(c.limits.reserved_sculptor_seats, 3u);
  EXPECT_EQ(c.limits.join_timeout_ms, 2000);
  EXPECT_EQ(c.limits.idle_timeout_ms, 60000);
  EXPECT_EQ(c.limits.frame_timeout_ms, 4000);
  EXPECT_DOUBLE_EQ(c.limits.requests_per_second, 12.5);
  EXPECT_DOUBLE_EQ(c.limits.request_burst, 50);
  EXPECT_DOUBLE_EQ(c.limits.source_rate_factor, 2);
  EXPECT_TRUE(ValidateConfig(c).ok()) << ValidateConfig(c);
}

TEST(LimitsConfigTest, SampleConfigurationStatesEveryLimit) {
  ServerConfig c;
  ASSERT_TRUE(LoadConfigFile(std::string(SCULPT_SOURCE_DIR) + "/deploy/scene.toml", &c).ok());
  const LimitsConfig d;
  EXPECT_EQ(c.limits.max_sessions, d.max_sessions);
  EXPECT_EQ(c.limits.max_connections_per_source, d.max_connections_per_source);
  EXPECT_EQ(c.limits.reserved_sculptor_seats, d.reserved_sculptor_seats);
  EXPECT_EQ(c.limits.join_timeout_ms, d.join_timeout_ms);
  EXPECT_EQ(c.limits.frame_timeout_ms, d.frame_timeout_ms);
  EXPECT_DOUBLE_EQ(c.limits.requests_per_second, d.requests_per_second);
}

// A small scene keeps seats for viewers: the reservation is at most half of it.
TEST(LimitsConfigTest, ReservedSeatsAreAtMostHalfTheScene) {
  LimitsConfig l;
  l.max_clients_per_scene = 64;
  l.reserved_sculptor_seats = 4;
  EXPECT_EQ(ViewerSeats(l), 60u);
  l.max_clients_per_scene = 2;
  EXPECT_EQ(ViewerSeats(l), 1u);
  l.max_clients_per_scene = 1;
  EXPECT_EQ(ViewerSeats(l), 1u);
  l.reserved_sculptor_seats = 0;
  l.max_clients_per_scene = 5;
  EXPECT_EQ(ViewerSeats(l), 5u);
  ServerConfig c;
  c.limits.max_clients_per_scene = 2;
  EXPECT_TRUE(ValidateConfig(c).ok()) << ValidateConfig(c);
}

TEST(LimitsConfigTest, RejectsAPerSourceCapAboveTheTotal) {
  ServerConfig c;
  c.limits.max_sessions = 10;
  c.limits.max_connections_per_source = 11;
  const Status s = ValidateConfig(c);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("limits.max_connections_per_source"), std::string::npos) << s;
}

TEST(LimitsConfigTest, RejectsAnUnknownLimitKey) {
  ServerConfig c;
  const Status s = LoadConfigFile(WriteToml("unknown", "[limits]\nmax_session = 3\n"), &c);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("max_session"), std::string::npos) << s;
}

}  // namespace
}  // namespace sculpt::server
