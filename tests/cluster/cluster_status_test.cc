// `sculpt cluster status` (issue 17) against an etcd and two sculptd members started here on
// loopback: both members are listed with their addresses, the owner and epoch of the scene, a
// standby key when one exists; an etcd that does not answer is a clear error, not a hang.
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "cluster/etcd_client.h"
#include "cluster/processes.h"
#include "cluster/records.h"
#include "net/beast.h"

namespace sculpt::server::cluster {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using sculpt::testing::ChildProcess;
using sculpt::testing::EtcdProcess;
using sculpt::testing::TempDir;
using sculpt::testing::RunResult;
using sculpt::testing::Sculpt;
using sculpt::testing::WaitFor;
using std::chrono::milliseconds;

const Keys kKeys{"t/"};

// The JSON document of --json output (from its first line starting with '{').
json JsonOf(const std::string& out) {
  size_t at = 0;
  if (out.compare(0, 1, "{") != 0) {
    at = out.find("\n{");
    if (at == std::string::npos) return json();
    ++at;
  }
  return json::parse(out.substr(at), nullptr, /*allow_exceptions=*/false);
}

class ClusterStatusTest : public sculpt::testing::EtcdTest {
 protected:
  void TearDown() override {
    members_.clear();  // SIGKILL and reap each sculptd before etcd goes
    EtcdTest::TearDown();
  }

  // A member `name` with the cluster prefix "t/" and lease TTL 2 s; its log beside its data.
  void Start(const std::string& name) {
    const fs::path config = dir_.path() / (name + ".toml");
    std::ofstream(config) << "[cluster]\netcd = [\"" << etcd_->endpoint() << "\"]\nmember = \""
                          << name << "\"\nlease_ttl_ms = 2000\nprefix = \"t/\"\n";
    members_.push_back(std::make_unique<ChildProcess>(
        std::vector<std::string>{std::string(SCULPT_BIN_DIR) + "/sculptd", "serve", "--config",
                                 config.string(), "--listen", "127.0.0.1:0", "--http",
                                 "127.0.0.1:0", "--data",
                                 (dir_.path() / (name + "-data")).string()},
        dir_.path() / (name + ".log")));
  }
  bool HasKey(const std::string& key) {
    auto kv = etcd_client_->Sync(etcd_client_->Get(key));
    return kv.ok() && kv->has_value();
  }
  std::optional<MemberRecord> Member(const std::string& name) {
    auto kv = etcd_client_->Sync(etcd_client_->Get(kKeys.Member(name)));
    if (!kv.ok() || !kv->has_value()) return std::nullopt;
    auto m = DecodeMember((*kv)->value);
    return m.ok() ? std::optional<MemberRecord>(*m) : std::nullopt;
  }

  TempDir dir_{"sculpt-cluster-status"};
  std::vector<std::unique_ptr<ChildProcess>> members_;
};

TEST_F(ClusterStatusTest, ListsBothMembersAndTheOwnerAndEpochOfTheScene) {
  Start("a");
  ASSERT_TRUE(WaitFor([&] { return HasKey(kKeys.Owner("default")); }, milliseconds(10000)))
      << "a did not take the scene; see " << dir_.path() / "a.log";
  Start("b");
  ASSERT_TRUE(WaitFor([&] { return Member("b").has_value(); },
                      sculpt::testing::Scaled(milliseconds(10000))))
      << "b did not register; see " << dir_.path() / "b.log";
  // a's record lists the scene once its next refresh (every TTL/4) has run.
  ASSERT_TRUE(
      WaitFor([&] { return Member("a") && !Member("a")->owns.empty(); }, milliseconds(5000)));
  const MemberRecord a = *Member("a");

  const RunResult r = Sculpt("cluster status --etcd " + etcd_->endpoint() + " --prefix t/ --json");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const json j = JsonOf(r.output);
  ASSERT_TRUE(j.is_object()) << r.output;
  std::set<std::string> names;
  for (const json& m : j["members"]) names.insert(m["name"].get<std::string>());
  EXPECT_EQ(names, (std::set<std::string>{"a", "b"})) << r.output;
  for (const json& m : j["members"]) {
    if (m["name"] != "a") continue;
    EXPECT_EQ(m["tcp"], a.tcp);
    EXPECT_FALSE(m["http"].get<std::string>().empty());
    EXPECT_EQ(m["owns"], json::array({"default"}));
  }
  ASSERT_EQ(j["scenes"].size(), 1u) << r.output;
  const json& scene = j["scenes"][0];
  EXPECT_EQ(scene["scene"], "default");
  EXPECT_EQ(scene["owner"], "a");
  EXPECT_EQ(scene["owner_tcp"], a.tcp);
  EXPECT_EQ(scene["epoch"], 1);
  EXPECT_EQ(scene["state"], "owned");

  // a names b, the only other member, its standby (at a refresh after b registered): shown by
  // its member name. Before that the first listing may or may not have had it.
  ASSERT_TRUE(WaitFor([&] { return HasKey("t/scenes/default/standby"); }, milliseconds(10000)))
      << "a named no standby; see " << dir_.path() / "a.log";
  const RunResult with_standby =
      Sculpt("cluster status --etcd " + etcd_->endpoint() + " --prefix t/ --json");
  ASSERT_EQ(with_standby.exit_code, 0) << with_standby.output;
  EXPECT_EQ(JsonOf(with_standby.output)["scenes"][0]["standby"], "b") << with_standby.output;
  // Once b's copy is loaded, the scene's row says how far b is behind a: nothing, since nobody
  // sculpted. a's synchronous acks (async here) have not fallen back.
  json lagged;
  ASSERT_TRUE(WaitFor(
      [&] {
        const RunResult r =
            Sculpt("cluster status --etcd " + etcd_->endpoint() + " --prefix t/ --json");
        lagged = JsonOf(r.output);
        return lagged.is_object() && lagged["scenes"][0]["standby_lag"].is_number();
      },
      milliseconds(15000)))
      << "no standby lag in the status; see " << dir_.path() / "b.log" << "\n" << lagged.dump();
  EXPECT_EQ(lagged["scenes"][0]["standby_lag"], 0) << lagged.dump();
  EXPECT_EQ(lagged["scenes"][0]["state"], "owned") << lagged.dump();
  for (const json& m : lagged["members"]) {
    EXPECT_EQ(m["acks_async"], false) << lagged.dump();
    if (m["name"] == "b") {
      EXPECT_EQ(m["follows"], "default") << lagged.dump();
    }
  }

  // The table names the same.
  const RunResult table = Sculpt("cluster status --etcd " + etcd_->endpoint() + " --prefix t/");
  ASSERT_EQ(table.exit_code, 0) << table.output;
  EXPECT_NE(table.output.find("2 members, 1 scene"), std::string::npos) << table.output;
  EXPECT_NE(table.output.find(a.tcp), std::string::npos) << table.output;
  bool scene_row = false;
  std::istringstream lines(table.output);
  for (std::string line; std::getline(lines, line);) {
    std::istringstream row(line);
    std::string name, owner, epoch, standby;
    if (row >> name >> owner >> epoch >> standby && name == "default") {
      scene_row = owner == "a" && epoch == "1" && standby == "b";
    }
  }
  EXPECT_TRUE(scene_row) << table.output;

  // Another prefix: an empty cluster, listed as such.
  const RunResult empty = Sculpt("cluster status --etcd " + etcd_->endpoint() + " --prefix none/");
  EXPECT_EQ(empty.exit_code, 0) << empty.output;
  EXPECT_NE(empty.output.find("0 members, 0 scenes"), std::string::npos) << empty.output;
}

// GET `path` from HOST:PORT; the body, empty when the request failed.
std::string HttpGet(const std::string& host_port, const std::string& path) {
  try {
    asio::io_context io;
    tcp::resolver resolver(io);
    beast::tcp_stream stream(io);
    const size_t colon = host_port.rfind(':');
    stream.connect(resolver.resolve(host_port.substr(0, colon), host_port.substr(colon + 1)));
    http::request<http::empty_body> req{http::verb::get, path, 11};
    req.set(http::field::host, host_port);
    http::write(stream, req);
    beast::flat_buffer buffer;
    http::response<http::string_body> res;
    http::read(stream, buffer, res);
    return res.result() == http::status::ok ? res.body() : std::string();
  } catch (const std::exception&) {
    return std::string();
  }
}

// The value of the sample whose line starts with `name_and_labels` followed by a space.
std::optional<double> Sample(const std::string& page, const std::string& name_and_labels) {
  std::istringstream lines(page);
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind(name_and_labels + " ", 0) == 0) {
      return std::stod(line.substr(name_and_labels.size() + 1));
    }
  }
  return std::nullopt;
}

// /metrics of each member says who owns the scene at which epoch, how many members live, and
// (on the owner) how far its standby's copy is durable.
TEST_F(ClusterStatusTest, MetricsShowOwnershipMembersAndTheStandbysProgress) {
  Start("a");
  ASSERT_TRUE(WaitFor([&] { return HasKey(kKeys.Owner("default")); }, milliseconds(10000)))
      << "a did not take the scene; see " << dir_.path() / "a.log";
  Start("b");
  ASSERT_TRUE(WaitFor([&] { return HasKey("t/scenes/default/standby"); }, milliseconds(10000)))
      << "a named no standby; see " << dir_.path() / "a.log";
  ASSERT_TRUE(WaitFor([&] { return Member("a").has_value() && Member("b").has_value(); },
                      milliseconds(5000)));
  const std::string a_http = Member("a")->http, b_http = Member("b")->http;

  // Both read the table at their next refresh (every TTL / 4): wait for it rather than assume.
  std::string a_page, b_page;
  ASSERT_TRUE(WaitFor(
      [&] {
        a_page = HttpGet(a_http, "/metrics");
        return Sample(a_page, "sculpt_cluster_live_members") == 2.0 &&
               Sample(a_page, R"(sculpt_cluster_standby_lag_edits{scene="default",standby="b"})")
                   .has_value();
      },
      milliseconds(10000)))
      << a_page;
  EXPECT_EQ(Sample(a_page, R"(sculpt_cluster_owned_epoch{member="a",scene="default"})"), 1.0)
      << a_page;
  EXPECT_EQ(Sample(a_page, R"(sculpt_cluster_scene_epoch{scene="default"})"), 1.0) << a_page;
  EXPECT_EQ(Sample(a_page, R"(sculpt_cluster_scene_owned{scene="default"})"), 1.0) << a_page;
  EXPECT_TRUE(
      Sample(a_page, R"(sculpt_cluster_standby_durable_seq{scene="default",standby="b"})"))
      << a_page;
  EXPECT_EQ(Sample(a_page, R"(sculpt_cluster_ownership_losses_total{member="a"})"), 0.0)
      << a_page;

  ASSERT_TRUE(WaitFor(
      [&] {
        b_page = HttpGet(b_http, "/metrics");
        return Sample(b_page, "sculpt_cluster_live_members") == 2.0;
      },
      milliseconds(10000)))
      << b_page;
  // b serves the same scene name but does not own it, and reports no standby of its own.
  EXPECT_EQ(Sample(b_page, R"(sculpt_cluster_owned_epoch{member="b",scene="default"})"), 0.0)
      << b_page;
  EXPECT_EQ(Sample(b_page, R"(sculpt_cluster_scene_epoch{scene="default"})"), 1.0) << b_page;
  EXPECT_EQ(b_page.find("sculpt_cluster_standby_lag_edits{"), std::string::npos) << b_page;
  EXPECT_TRUE(Sample(b_page, R"(sculpt_cluster_follow_seq{member="b",scene="default"})")) << b_page;
}

TEST(ClusterStatusNoEtcd, ReportsAnUnreachableEtcdWithAHint) {
  const std::string url = "http://127.0.0.1:" + std::to_string(sculpt::testing::FreePort());
  const auto start = std::chrono::steady_clock::now();
  const RunResult r = Sculpt("cluster status --etcd " + url + " --timeout 0.5");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("cannot read sculpt/ from etcd at " + url), std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("endpoint health"), std::string::npos) << r.output;
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(10));
}

TEST(ClusterStatusNoEtcd, RejectsAMalformedEndpoint) {
  const RunResult r = Sculpt("cluster status --etcd ftp://nowhere");
  EXPECT_EQ(r.exit_code, 2) << r.output;
}

// A check CLI11 refuses (a missing file, a value out of range) exits 2 like every bad option,
// not with CLI11's own code, and names the option.
TEST(ClusterStatusNoEtcd, RefusedOptionsExitTwo) {
  const RunResult missing =
      Sculpt("cluster status --etcd http://127.0.0.1:1 --etcd-ca /nonexistent/ca.pem");
  EXPECT_EQ(missing.exit_code, 2) << missing.output;
  EXPECT_NE(missing.output.find("--etcd-ca"), std::string::npos) << missing.output;
  const RunResult range = Sculpt("cluster status --etcd http://127.0.0.1:1 --timeout 0");
  EXPECT_EQ(range.exit_code, 2) << range.output;
  EXPECT_NE(range.output.find("--timeout"), std::string::npos) << range.output;
}

TEST(ClusterStatusNoEtcd, HelpNamesTheOptions) {
  const RunResult r = Sculpt("cluster status --help");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  for (const char* flag : {"--etcd", "--prefix", "--json", "--timeout"}) {
    EXPECT_NE(r.output.find(flag), std::string::npos) << flag << "\n" << r.output;
  }
  EXPECT_NE(Sculpt("cluster status").exit_code, 0) << "--etcd is required";
}

}  // namespace
}  // namespace sculpt::server::cluster

namespace sculpt::server::cluster {
namespace {

// Members hosting several scenes (their records list each owned and followed scene with its
// sequence): every scene's row shows its owner, standby and the standby's lag for that scene,
// and "acks async" only for the scene whose acks fell back. Records written straight into etcd.
TEST_F(ClusterStatusTest, ShowsEachSceneOfMembersHostingSeveral) {
  MemberRecord a{"a", "127.0.0.1:1", "", {"p", "q", "r"}, {"p", "q"}, 0};
  a.owning = {{"p", 50, false}, {"q", 20, true}};
  a.following = {{"r", 7, false}};
  MemberRecord b{"b", "127.0.0.1:2", "", {"p", "q", "r"}, {"r"}, 0};
  b.owning = {{"r", 10, false}};
  b.following = {{"p", 45, false}, {"q", 20, false}};
  EtcdClient& etcd = *etcd_client_;
  ASSERT_TRUE(etcd.Sync(etcd.Put({kKeys.Member("a"), EncodeMember(a), 0})).ok());
  ASSERT_TRUE(etcd.Sync(etcd.Put({kKeys.Member("b"), EncodeMember(b), 0})).ok());
  for (const auto& [scene, owner, standby] :
       std::vector<std::array<std::string, 3>>{{"p", "a", "b"}, {"q", "a", "b"}, {"r", "b", "a"}}) {
    const std::string tcp = owner == "a" ? a.tcp : b.tcp;
    const std::string owner_record = EncodeOwner({owner, tcp, "", 1});
    ASSERT_TRUE(etcd.Sync(etcd.Put({kKeys.Owner(scene), owner_record, 0})).ok());
    ASSERT_TRUE(etcd.Sync(etcd.Put({kKeys.Epoch(scene), EncodeEpoch({1, owner}), 0})).ok());
    ASSERT_TRUE(etcd.Sync(etcd.Put({kKeys.Standby(scene), EncodeStandby({standby, 1}), 0})).ok());
  }
  const RunResult out =
      Sculpt("cluster status --json --etcd " + etcd_->endpoint() + " --prefix t/");
  ASSERT_EQ(out.exit_code, 0) << out.output;
  const json doc = JsonOf(out.output);
  ASSERT_TRUE(doc.is_object()) << out.output;
  std::map<std::string, json> scenes;
  for (const json& s : doc["scenes"]) scenes[s["scene"].get<std::string>()] = s;
  ASSERT_EQ(scenes.size(), 3u) << out.output;
  EXPECT_EQ(scenes["p"]["owner"], "a");
  EXPECT_EQ(scenes["p"]["standby"], "b");
  EXPECT_EQ(scenes["p"]["standby_lag"], 5) << out.output;
  EXPECT_EQ(scenes["q"]["standby_lag"], 0) << out.output;
  EXPECT_EQ(scenes["r"]["owner"], "b");
  EXPECT_EQ(scenes["r"]["standby_lag"], 3) << out.output;
  EXPECT_EQ(scenes["p"]["state"], "owned");
  EXPECT_NE(scenes["q"]["state"].get<std::string>().find("acks async"), std::string::npos);
  EXPECT_EQ(scenes["r"]["state"], "owned");
  for (const json& m : doc["members"]) {
    if (m["name"] == "b") {
      EXPECT_EQ(m["following"].size(), 2u) << m.dump();
      EXPECT_EQ(m["owning"][0]["scene"], "r") << m.dump();
    }
  }
  // The table: each scene's row with its own lag.
  const RunResult table = Sculpt("cluster status --etcd " + etcd_->endpoint() + " --prefix t/");
  ASSERT_EQ(table.exit_code, 0) << table.output;
  std::map<std::string, std::string> lag;
  std::istringstream lines(table.output);
  for (std::string line; std::getline(lines, line);) {
    std::istringstream row(line);
    std::string name, owner, epoch, standby, l;
    if (row >> name >> owner >> epoch >> standby >> l && epoch == "1") lag[name] = l;
  }
  EXPECT_EQ(lag, (std::map<std::string, std::string>{{"p", "5"}, {"q", "0"}, {"r", "3"}}))
      << table.output;
}

}  // namespace
}  // namespace sculpt::server::cluster
