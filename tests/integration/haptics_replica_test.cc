/// @brief The haptic loop on a client's replica against the real server in-process (issue 5): a
/// scripted device pressing into the sphere feels an outward force; another sculptor carving the
/// material away reaches the replica and the force decays to zero without a spike; the loop runs
/// at about 1 kHz and never reads a snapshot that changed after publication. And `sculpt play
/// --haptics --json` against the same server.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "integration/in_process_server.h"
#include "sculpt/client/client.h"
#include "sculpt/client/replica.h"
#include "sculpt/haptics/haptic_loop.h"
#include "sculpt/haptics/monitored_device.h"
#include "sculpt/haptics/sculpture_feed.h"
#include "sculpt/levelset/region.h"

namespace sculpt::client {
namespace {

namespace fs = std::filesystem;
using std::chrono::milliseconds;
using std::chrono::seconds;

class HapticsReplicaTest : public ::testing::Test {
 protected:
  void SetUp() override {
    // Without compensation a cut leaves the surface exactly where the tool put it, so "no
    // material under the tool" is a fact of geometry rather than of how far the shell moved.
    srv_.config().scene.effects.volume_preservation = "none";
    ASSERT_TRUE(srv_.Start());
    scene_ = &srv_.scene();
    port_ = srv_.port();
    dir_ = srv_.dir();
  }

  std::unique_ptr<Client> Joined(bool skip_state) {
    return srv_.Joined(v1::ROLE_SCULPTOR, skip_state);
  }

  // Runs the `sculpt` binary; returns its exit code, stdout in `out`, stderr in `out`.err
  // (spdlog's default logger writes to stdout).
  int RunSculpt(const std::string& args, const fs::path& out) {
    const std::string cmd = std::string(SCULPT_BIN_DIR) + "/sculpt " + args + " > " + out.string() +
                            " 2> " + out.string() + ".err";
    const int status = std::system(cmd.c_str());
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }

  // Presses into the top of the default sphere (radius 24 at the origin) with `model`, has a
  // second sculptor cut the material under the tool away, and checks what the loop rendered.
  void PressThenCutAway(haptics::ForceModel model) {
    auto a = Joined(/*skip_state=*/true);
    auto b = Joined(/*skip_state=*/false);

    // Declared before the replica: its thread calls into them until it is destroyed.
    haptics::SnapshotPublisher publisher;
    haptics::SculptureFeed feed(&publisher, /*seal=*/true);
    std::mutex mu;
    std::vector<std::pair<uint64_t, uint64_t>> versions;  // (publisher version, replica seq)
    ReplicaOptions ro;
    ro.snapshot_interval = milliseconds(5);
    Replica replica(*a, ro);
    replica.SetSnapshotHandler([&](std::shared_ptr<const levelset::Sculpture> s, uint64_t seq) {
      feed.Publish(std::move(s), seq);
      std::lock_guard<std::mutex> lock(mu);
      versions.emplace_back(feed.stats().last_version, seq);
    });
    ASSERT_TRUE(replica.Start().ok());
    ASSERT_TRUE(replica.WaitLoaded(1, seconds(20)));
    ASSERT_TRUE(replica.WaitIdle(seconds(20)));
    ASSERT_GE(feed.stats().published, 1u) << "the region load is published";

    // Down from 7 units above the top at 20 units/s to 1 unit inside, then held there.
    constexpr double kTop = 24, kDepth = 1;
    haptics::ScriptedDevice device([&](double t) {
      return Vec3{0, 0, std::max(kTop - kDepth, kTop + 7 - 20 * t)};
    });
    haptics::MonitoredDevice monitor(&device, &publisher, /*trace_capacity=*/20000);
    haptics::HapticSettings hs;
    hs.model = model;
    hs.tool_radius = 2;
    auto loop = haptics::HapticLoop::Create(hs, &publisher, &monitor);
    ASSERT_TRUE(loop.ok()) << loop.status();
    ASSERT_TRUE((*loop)->Start().ok());
    std::this_thread::sleep_for(milliseconds(800));  // in contact from 0.4 s on

    // The other sculptor carves a ball of radius 8 out of the top: the tool is left in air.
    StrokeRequest cut;
    cut.kind = v1::EDIT_KIND_SUBTRACT;
    cut.tool_size = {8, 0, 0};
    cut.poses.push_back(codec::Pose{{0, 0, kTop}, 0});
    ASSERT_TRUE(b->SendStroke(cut).ok());
    ASSERT_TRUE(b->WaitAllAcked(seconds(10)));
    const uint64_t cut_seq = scene_->global_seq();
    ASSERT_EQ(cut_seq, 1u);
    ASSERT_TRUE(replica.WaitForSeq(cut_seq, seconds(10)))
        << "replica at seq " << replica.stats().seq << ", " << replica.stats().errors << " errors, "
        << replica.stats().broadcasts_applied << " broadcasts";
    const auto limit = std::chrono::steady_clock::now() + seconds(5);
    while (feed.stats().last_seq < cut_seq && std::chrono::steady_clock::now() < limit) {
      std::this_thread::sleep_for(milliseconds(1));
    }
    ASSERT_GE(feed.stats().last_seq, cut_seq) << "the cut is published without a later edit";
    std::this_thread::sleep_for(milliseconds(300));
    (*loop)->Stop();
    replica.SetSnapshotHandler(nullptr);
    feed.CheckHeld();

    uint64_t cut_version = 0;
    {
      std::lock_guard<std::mutex> lock(mu);
      for (const auto& [version, seq] : versions) {
        if (seq >= cut_seq) {
          cut_version = version;
          break;
        }
      }
    }
    ASSERT_GT(cut_version, 0u);

    const std::vector<haptics::MonitoredDevice::Tick>& trace = monitor.trace();
    ASSERT_GT(trace.size(), 500u);
    double max_before = 0;
    int pressing = 0;
    double first_cut_t = -1;
    for (const auto& tick : trace) {
      const double f = tick.force.Length();
      if (tick.version < cut_version) {
        max_before = std::max(max_before, f);
        if (tick.t >= 0.45) {
          // Held 1 unit deep at the top of the sphere: a force pointing out of it (+z).
          ++pressing;
          ASSERT_GT(f, 0.05) << "t=" << tick.t;
          EXPECT_GT(tick.force.z, 0.98 * f) << "t=" << tick.t;
        }
      } else if (first_cut_t < 0) {
        first_cut_t = tick.t;
      }
    }
    EXPECT_GT(pressing, 200);
    ASSERT_GT(first_cut_t, 0) << "the loop ticked on the cut's snapshot";
    // After the cut: never above what was felt before, and exactly zero once the blend is over.
    // The blend lasts blend_ms worth of ticks from the last snapshot swap (each swap restarts
    // it); counted in ticks, not in time, since a loaded machine stretches the ticks' spacing.
    const int blend_ticks = static_cast<int>(std::lround(hs.blend_ms * 1e-3 * hs.rate_hz));
    int after = 0;
    int since_swap = 0;
    uint64_t version = 0;
    for (const auto& tick : trace) {
      if (tick.version < cut_version) continue;
      since_swap = tick.version == version ? since_swap + 1 : 0;
      version = tick.version;
      EXPECT_LE(tick.force.Length(), max_before + 1e-9) << "spike at t=" << tick.t;
      if (since_swap > blend_ticks + 2) {
        ++after;
        EXPECT_EQ(tick.force.Length(), 0.0) << "t=" << tick.t << ", " << since_swap
                                            << " ticks after the swap to version " << version;
      }
    }
    EXPECT_GT(after, 100);

    const haptics::HapticLoopStats ls = (*loop)->stats();
    EXPECT_GT(ls.rate_hz, 700.0);
    EXPECT_LT(ls.rate_hz, 1010.0);
    EXPECT_GE(ls.snapshots_seen, 2u);
    const haptics::SculptureFeed::Stats fs = feed.stats();
    EXPECT_EQ(fs.checked, fs.published) << "every published copy's seal was checked";
    EXPECT_EQ(fs.changed, 0u);
    EXPECT_EQ(monitor.TicksOn(feed.changed_versions()), 0u) << "ticks that read a torn state";
    // The replica (and so the loop's last snapshot) holds the server's voxels.
    const levelset::VoxelBox held = replica.held();
    EXPECT_EQ(replica.RegionHash(held), scene_->RegionHash("clay", held));
    EXPECT_EQ(levelset::RegionHash(*replica.Snapshot(), held), scene_->RegionHash("clay", held));
    EXPECT_EQ(replica.stats().hash_mismatches, 0u);
  }

  testing_support::InProcessServer srv_{"haptics_replica"};
  server::Scene* scene_ = nullptr;
  uint16_t port_ = 0;
  fs::path dir_;
};

TEST_F(HapticsReplicaTest, ProxyForceDecaysWithoutSpikeWhenAnotherClientCutsTheMaterialAway) {
  PressThenCutAway(haptics::ForceModel::kProxy);
}

TEST_F(HapticsReplicaTest, PenaltyForceDecaysWithoutSpikeWhenAnotherClientCutsTheMaterialAway) {
  PressThenCutAway(haptics::ForceModel::kPenalty);
}

TEST_F(HapticsReplicaTest, PlayHapticsJsonPrintsLoopAndForceStatistics) {
  const std::string server = "--server 127.0.0.1:" + std::to_string(port_);
  for (const std::string extra : {"--model proxy", "--model penalty --interest-radius 10"}) {
    const uint64_t seq_before = scene_->global_seq();
    const fs::path out = dir_ / "haptics.json";
    ASSERT_EQ(
        RunSculpt("play " + server + " --haptics --json --verify-snapshots --duration 1.2 " + extra,
                  out),
        0)
        << extra << ": " << std::ifstream(out.string() + ".err").rdbuf();
    const nlohmann::json r = nlohmann::json::parse(std::ifstream(out));
    EXPECT_TRUE(r["ok"].get<bool>()) << extra;
    EXPECT_GT(r["haptic_ticks"].get<int>(), 800) << extra;
    EXPECT_GT(r["haptic_rate_hz"].get<double>(), 700.0) << extra;
    EXPECT_LT(r["haptic_rate_hz"].get<double>(), 1010.0) << extra;
    for (const char* key :
         {"haptic_period_err_p99_us", "haptic_ticks_over_2ms", "haptic_snapshot_lag_p99_ms",
          "haptic_missed_deadlines", "haptic_tick_cost_p99_us", "haptic_tick_cost_p50_us",
          "haptic_period_err_p50_us", "haptic_ticks_over_budget", "haptic_cpu",
          "snapshot_windows"}) {
      EXPECT_TRUE(r.contains(key) && r[key].is_number()) << extra << " " << key;
    }
    // What the loop got from the OS is reported, whichever it was.
    const std::string sched = r.value("haptic_scheduling", "");
    EXPECT_TRUE(sched == "SCHED_FIFO" || sched == "SCHED_OTHER") << extra << " " << sched;
    EXPECT_TRUE(r.contains("haptic_mlockall") && r["haptic_mlockall"].is_boolean()) << extra;
    EXPECT_EQ(r["haptic_torn_ticks"].get<int>(), 0) << extra;
    EXPECT_EQ(r["snapshots_changed_after_publish"].get<int>(), 0) << extra;
    EXPECT_GT(r["force_max"].get<double>(), 0.0) << extra << ": the built-in path presses in";
    EXPECT_GT(r["force_contact_ticks"].get<int>(), 0) << extra;
    // The strokes were sampled from the device while it touched the clay, and all applied.
    const int poses = r["poses_sent"].get<int>();
    EXPECT_GT(poses, 0) << extra;
    EXPECT_EQ(r["acked"].get<int>(), r["strokes_sent"].get<int>()) << extra;
    EXPECT_EQ(r["refused"].get<int>(), 0) << extra;
    EXPECT_EQ(scene_->global_seq() - seq_before, static_cast<uint64_t>(poses)) << extra;
  }
  EXPECT_EQ(RunSculpt("play " + server + " --haptics --json --interest-radius 10 --duration 0.5",
                      dir_ / "moved.json"),
            0);
  // A proxy damper below stiffness * T / 2 is refused before connecting, naming the field.
  EXPECT_EQ(
      RunSculpt("play " + server + " --haptics --stiffness 100 --damping 0.001", dir_ / "bad.json"),
      2);
  std::string text;
  for (const std::string& path :
       {(dir_ / "bad.json").string(), (dir_ / "bad.json").string() + ".err"}) {
    std::ifstream in(path);
    text.append(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  EXPECT_NE(text.find("HapticSettings.damping=0.001 outside"), std::string::npos) << text;
  // Without --haptics the script is still required.
  EXPECT_EQ(RunSculpt("play " + server, dir_ / "noscript.json"), 2);
}

}  // namespace
}  // namespace sculpt::client
