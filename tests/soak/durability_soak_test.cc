/// @brief The bounded-log soak (ctest label `soak`, run by hand with `make soak`): 200,000 edits
/// with a snapshot every 5,000 through the in-process scene; the log directory stays bounded,
/// start-up afterwards is short, RSS stays flat. SCULPT_SOAK_EDITS overrides the edit count.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <future>
#include <string>

#include "scene/scene.h"
#include "sculpt/codec/stroke.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::server {
namespace {

namespace fs = std::filesystem;

uint64_t DirBytes(const fs::path& dir) {
  uint64_t total = 0;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (e.is_regular_file()) total += e.file_size();
  }
  return total;
}

uint64_t RssBytes() {
  std::ifstream in("/proc/self/statm");
  uint64_t pages = 0, resident = 0;
  in >> pages >> resident;
  return resident * static_cast<uint64_t>(::sysconf(_SC_PAGESIZE));
}

// A small press stroke of `poses` poses somewhere on the clay sphere's surface.
codec::DecodedStroke Stroke(Scene& scene, uint64_t client_seq, int poses) {
  v1::Stroke s;
  s.set_client_seq(client_seq);
  s.set_object("clay");
  s.set_kind(v1::EDIT_KIND_PRESS);
  s.set_tool(v1::TOOL_KIND_SPHERE);
  s.mutable_tool_size()->set_x(1.5f);
  s.set_speed(60);
  const double a = 0.61803398875 * static_cast<double>(client_seq);
  const double z = std::fmod(0.37 * static_cast<double>(client_seq), 2.0) - 1.0;
  const double r = 12.8 * std::sqrt(1 - z * z);
  const Vec3 at{r * std::cos(a), r * std::sin(a), 12.8 * z};
  s.mutable_origin()->set_x(static_cast<float>(at.x));
  s.mutable_origin()->set_y(static_cast<float>(at.y));
  s.mutable_origin()->set_z(static_cast<float>(at.z));
  std::vector<codec::Pose> p;
  for (int i = 0; i < poses; ++i) p.push_back({at + Vec3{0.2 * i, 0.1 * i, 0}, uint32_t(8 * i)});
  const Vec3 origin{s.origin().x(), s.origin().y(), s.origin().z()};
  s.set_pose_count(static_cast<uint32_t>(poses));
  s.set_poses(codec::PackPoses(p, origin, 0.5).value());
  auto limits = scene.LimitsFor("clay");
  EXPECT_TRUE(limits.ok());
  auto decoded = codec::DecodeStroke(s, *limits);
  EXPECT_TRUE(decoded.ok()) << decoded.status();
  return std::move(decoded).value();
}

TEST(DurabilitySoak, TwoHundredThousandEditsKeepTheLogBoundedAndStartUpShort) {
  uint64_t edits = 200000;
  if (const char* env = std::getenv("SCULPT_SOAK_EDITS")) edits = std::strtoull(env, nullptr, 10);
  constexpr int kPoses = 4;
  constexpr uint64_t kEvery = 5000;
  const fs::path data = fs::temp_directory_path() / ("sculpt_soak_" + std::to_string(getpid()));
  fs::remove_all(data);
  ServerConfig config;
  config.data_dir = data.string();
  config.snapshot_every_edits = kEvery;
  config.snapshot_every_seconds = 0;
  uint64_t max_log = 0, max_dir = 0, rss_quarter = 0, rss_end = 0, live = 0;
  const auto t0 = std::chrono::steady_clock::now();
  {
    auto scene = Scene::Open(config);
    ASSERT_TRUE(scene.ok()) << scene.status();
    const uint64_t strokes = edits / kPoses;
    std::promise<void> last;
    for (uint64_t i = 1; i <= strokes; ++i) {
      const bool final = i == strokes;
      (*scene)->Submit(7, Stroke(**scene, i, kPoses), [final, &last](const StrokeOutcome& o) {
        EXPECT_TRUE(o.status.ok()) << o.status;
        if (final) last.set_value();
      });
      if (i % 64 == 0) max_log = std::max(max_log, DirBytes(data / "log"));
      if (i % (kEvery / kPoses) == 0) {
        (*scene)->Flush();  // bounds the queue; the snapshot round has finished
        max_log = std::max(max_log, DirBytes(data / "log"));
        max_dir = std::max(max_dir, DirBytes(data));
        if (i * kPoses == edits / 4 / kEvery * kEvery) rss_quarter = RssBytes();
        if (i % (50000 / kPoses) == 0) {
          std::printf("[ soak     ] %llu edits, log %llu bytes, data dir %llu bytes, RSS %.1f MB\n",
                      static_cast<unsigned long long>(i * kPoses),
                      static_cast<unsigned long long>(DirBytes(data / "log")),
                      static_cast<unsigned long long>(DirBytes(data)), RssBytes() / 1048576.0);
        }
      }
    }
    last.get_future().wait();
    (*scene)->Flush();
    // A tail just short of the next count-triggered snapshot, then a stop without one (as a
    // kill would leave it): the restart replays it.
    for (uint64_t i = strokes + 1; i < strokes + kEvery / kPoses; ++i) {
      (*scene)->Submit(7, Stroke(**scene, i, kPoses), [](const StrokeOutcome&) {});
    }
    (*scene)->Flush();
    max_log = std::max(max_log, DirBytes(data / "log"));
    rss_end = RssBytes();
    live = (*scene)->StateHash("clay");
  }
  const double run_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const auto t1 = std::chrono::steady_clock::now();
  auto again = Scene::Open(config);
  const double startup_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
  ASSERT_TRUE(again.ok()) << again.status();
  EXPECT_EQ((*again)->StateHash("clay"), live);
  std::printf("[ figures  ] %llu edits in %.0f s; log dir max %llu bytes; data dir max %llu bytes; "
              "RSS %.1f MB at 1/4, %.1f MB at the end; start-up after %.3f s (%s)\n",
              static_cast<unsigned long long>(edits), run_s,
              static_cast<unsigned long long>(max_log), static_cast<unsigned long long>(max_dir),
              rss_quarter / 1048576.0, rss_end / 1048576.0, startup_s,
              (*again)->recovery_summary().c_str());
  // The log holds at most the two rounds the trim keeps plus the one being written: 3 x 5,000
  // records of at most 128 bytes each (fewer: snapshots also come after 1 s of apply time).
  EXPECT_LE(max_log, 3 * kEvery * 128);
  EXPECT_LT(startup_s, 2.0);
  if (rss_quarter > 0) {
    EXPECT_LE(rss_end, rss_quarter + rss_quarter / 4 + (32u << 20)) << "RSS grows";
  }
  again->reset();
  fs::remove_all(data);
}

}  // namespace
}  // namespace sculpt::server
