/// @brief Replicas against the real server in-process (issue 4): concurrent sculptors and every
/// kind of replica converge to the server's voxels; a dropped connection resyncs by leaf
/// versions; a moving interest box ends equal over its new region; bad subscriptions are refused
/// with field, value and range while the server keeps serving.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <memory>
#include <string>
#include <thread>

#include "integration/in_process_server.h"
#include "sculpt/client/client.h"
#include "sculpt/client/mesh_view.h"
#include "sculpt/client/replica.h"
#include "sculpt/levelset/region.h"
#include "sculpt/mesh/chunk_mesher.h"

namespace sculpt::client {
namespace {

namespace fs = std::filesystem;
using std::chrono::milliseconds;
using std::chrono::seconds;

using testing_support::PressArc;

class ReplicaTest : public ::testing::Test {
 protected:
  void SetUp() override { ASSERT_TRUE(srv_.Start()); }

  std::unique_ptr<Client> Joined(v1::Role role, bool skip_state) {
    return srv_.Joined(role, skip_state);
  }

  // True once the replica's voxels over `box` equal the server's (polled: a partial replica
  // sees only the edits touching its region, so no sequence number tells it is done).
  bool Converges(const Replica& r, const levelset::VoxelBox& box, seconds limit = seconds(20)) {
    const auto end = std::chrono::steady_clock::now() + limit;
    while (std::chrono::steady_clock::now() < end) {
      if (r.RegionHash(box) == srv_.scene().RegionHash("clay", box)) return true;
      std::this_thread::sleep_for(milliseconds(50));
    }
    return false;
  }

  levelset::VoxelBox Box(const levelset::Aabb& world) {
    const double dx = srv_.config().scene.voxel_size;
    return {{int(std::floor(world.min.x / dx)), int(std::floor(world.min.y / dx)),
             int(std::floor(world.min.z / dx))},
            {int(std::ceil(world.max.x / dx)), int(std::ceil(world.max.y / dx)),
             int(std::ceil(world.max.z / dx))}};
  }

  testing_support::InProcessServer srv_{"replica"};
};

TEST_F(ReplicaTest, ConcurrentSculptorsAndEveryReplicaKindConverge) {
  constexpr int kStrokes = 25;
  auto a = Joined(v1::ROLE_SCULPTOR, true);
  auto b = Joined(v1::ROLE_SCULPTOR, true);
  auto c = Joined(v1::ROLE_VIEWER, true);
  auto d = Joined(v1::ROLE_VIEWER, true);
  Replica ra(*a, {});
  Replica rb(*b, {});
  ReplicaOptions delta;
  delta.mode = v1::REPLICA_MODE_LEAF_DELTA;
  Replica rc(*c, delta);
  ReplicaOptions part;
  part.interest = levelset::Aabb{{15, -10, 5}, {25, 10, 15}};
  Replica rd(*d, part);
  for (Replica* r : {&ra, &rb, &rc, &rd}) ASSERT_TRUE(r->Start().ok());
  // Subscriptions are ordered with strokes on the server: wait until each region is loaded, so
  // every stroke below reaches every replica as an edit.
  for (Replica* r : {&ra, &rb, &rc, &rd}) ASSERT_TRUE(r->WaitLoaded(1, seconds(20)));

  // Overlapping arcs (z = 2 and z = -2 with a 2.5 tool) at the same time.
  auto send = [](Client* cl, double z) {
    for (int i = 0; i < kStrokes; ++i) EXPECT_TRUE(cl->SendStroke(PressArc(z, i)).ok());
  };
  std::thread ta(send, a.get(), 2.0);
  std::thread tb(send, b.get(), -2.0);
  ta.join();
  tb.join();
  ASSERT_TRUE(a->WaitAllAcked(seconds(30)));
  ASSERT_TRUE(b->WaitAllAcked(seconds(30)));
  const uint64_t seq = srv_.scene().global_seq();
  ASSERT_EQ(seq, 2u * kStrokes * 4);
  for (Replica* r : {&ra, &rb, &rc}) {
    ASSERT_TRUE(r->WaitForSeq(seq, seconds(30)));
    const levelset::VoxelBox held = r->held();
    ASSERT_FALSE(held.Empty());
    EXPECT_EQ(r->RegionHash(held), srv_.scene().RegionHash("clay", held));
    EXPECT_EQ(r->stats().hash_mismatches, 0u);
    EXPECT_EQ(r->stats().errors, 0u);
  }
  EXPECT_EQ(ra.stats().broadcasts_applied, 2u * kStrokes);
  EXPECT_EQ(rc.stats().deltas_applied, 2u * kStrokes);
  EXPECT_EQ(rc.stats().broadcasts_applied, 0u);
  // The partial replica: equal over its interest, and it saw only part of the strokes.
  EXPECT_TRUE(Converges(rd, Box(*part.interest)));
  EXPECT_LT(rd.stats().broadcasts_applied + rd.stats().deltas_applied, 2u * kStrokes);
  EXPECT_GT(rd.stats().broadcasts_applied + rd.stats().deltas_applied, 0u);
  EXPECT_EQ(srv_.scene().replication_stats().divergences.load(), 0u);
  // Replay moves far fewer bytes than leaf deltas for the same edits.
  EXPECT_LT(ra.stats().bytes * 5, rc.stats().bytes);
}

TEST_F(ReplicaTest, DroppedConnectionResyncsToTheServerState) {
  auto a = Joined(v1::ROLE_SCULPTOR, true);
  auto c = Joined(v1::ROLE_VIEWER, true);
  Replica rc(*c, {});
  ASSERT_TRUE(rc.Start().ok());
  ASSERT_TRUE(rc.WaitLoaded(1, seconds(20)));
  for (int i = 0; i < 10; ++i) ASSERT_TRUE(a->SendStroke(PressArc(5, i)).ok());
  ASSERT_TRUE(a->WaitAllAcked(seconds(20)));
  ASSERT_TRUE(rc.WaitForSeq(srv_.scene().global_seq(), seconds(20)));
  const uint64_t before = rc.stats().seq;
  // Mid-stream: the replica's connection drops while the sculptor goes on.
  c->DropConnection();
  for (int i = 10; i < 30; ++i) ASSERT_TRUE(a->SendStroke(PressArc(5, i)).ok());
  ASSERT_TRUE(a->WaitAllAcked(seconds(20)));
  EXPECT_EQ(rc.stats().seq, before);
  ASSERT_TRUE(c->Reconnect().ok());
  ASSERT_TRUE(rc.Resubscribe().ok());
  ASSERT_TRUE(rc.WaitForSeq(srv_.scene().global_seq(), seconds(20)));
  const levelset::VoxelBox held = rc.held();
  EXPECT_EQ(rc.RegionHash(held), srv_.scene().RegionHash("clay", held));
  EXPECT_EQ(rc.stats().region_loads, 1u);  // the resync sent leaves by version, not the region
  EXPECT_EQ(rc.stats().hash_mismatches, 0u);
  // And it keeps replaying afterwards.
  for (int i = 30; i < 35; ++i) ASSERT_TRUE(a->SendStroke(PressArc(5, i)).ok());
  ASSERT_TRUE(a->WaitAllAcked(seconds(20)));
  ASSERT_TRUE(rc.WaitForSeq(srv_.scene().global_seq(), seconds(20)));
  EXPECT_EQ(rc.RegionHash(held), srv_.scene().RegionHash("clay", held));
}

TEST_F(ReplicaTest, InterestMovingAcrossTheObjectWhileOthersEditEndsEqual) {
  auto a = Joined(v1::ROLE_SCULPTOR, true);
  auto c = Joined(v1::ROLE_VIEWER, true);
  ReplicaOptions part;
  part.interest = levelset::Aabb{{15, -10, -15}, {25, 10, -5}};
  Replica rc(*c, part);
  ASSERT_TRUE(rc.Start().ok());
  ASSERT_TRUE(rc.WaitLoaded(1, seconds(20)));
  const levelset::Aabb boxes[] = {{{-5, 10, -15}, {10, 25, -5}},
                                  {{-25, -5, -15}, {-10, 15, -5}},
                                  {{-10, -25, -15}, {10, -10, -5}}};
  int stroke = 0;
  for (const levelset::Aabb& next : boxes) {
    for (int i = 0; i < 12; ++i) ASSERT_TRUE(a->SendStroke(PressArc(-10, stroke++)).ok());
    ASSERT_TRUE(rc.MoveInterest(next).ok());
    for (int i = 0; i < 12; ++i) ASSERT_TRUE(a->SendStroke(PressArc(-10, stroke++)).ok());
    ASSERT_TRUE(a->WaitAllAcked(seconds(30)));
    EXPECT_TRUE(Converges(rc, Box(next))) << "interest " << next.min.x << "," << next.min.y;
  }
  EXPECT_EQ(rc.stats().region_loads, 4u);
  EXPECT_EQ(rc.stats().hash_mismatches, 0u);
}

TEST_F(ReplicaTest, BadSubscriptionsAreRefusedAndOthersKeepBeingServed) {
  auto a = Joined(v1::ROLE_SCULPTOR, true);
  auto c = Joined(v1::ROLE_VIEWER, true);
  auto refuse = [&](v1::ClientMessage m, const std::string& field) {
    c->DrainEvents();
    ASSERT_TRUE(c->SendMessage(m).ok());
    // Other events (presence, scene info) may arrive first on a loaded machine: wait for the
    // error, so that it is not left to be read as the next refusal's.
    auto e = c->NextEvent(seconds(5));
    for (int i = 0; i < 50 && e.has_value() && e->type != Event::Type::kError; ++i) {
      e = c->NextEvent(seconds(5));
    }
    ASSERT_TRUE(e.has_value()) << field;
    ASSERT_EQ(e->type, Event::Type::kError) << field;
    EXPECT_EQ(e->error.field(), field);
    EXPECT_FALSE(e->error.allowed_range().empty()) << field;
  };
  v1::ClientMessage m;
  v1::Subscribe* s = m.mutable_subscribe();
  s->set_object("clay");
  s->set_mode(v1::REPLICA_MODE_REPLAY);
  // A negative box (max below min).
  s->mutable_interest()->mutable_min()->set_x(10);
  s->mutable_interest()->mutable_max()->set_x(-10);
  refuse(m, "Subscribe.interest.max.x");
  // A huge box.
  s->mutable_interest()->mutable_min()->set_x(-1e6f);
  s->mutable_interest()->mutable_max()->set_x(1e6f);
  refuse(m, "Subscribe.interest.max.x");
  // Not finite.
  s->mutable_interest()->mutable_min()->set_y(NAN);
  refuse(m, "Subscribe.interest.min");
  s->clear_interest();
  // A sequence the server never had.
  s->set_have_seq(1u << 30);
  refuse(m, "Subscribe.have_seq");
  s->set_have_seq(0);
  s->set_mode(static_cast<v1::ReplicaMode>(7));
  refuse(m, "Subscribe.mode");
  s->set_mode(v1::REPLICA_MODE_REPLAY);
  s->set_object("nothing");
  refuse(m, "Subscribe.object");
  // SetInterest without a subscription.
  v1::ClientMessage si;
  si.mutable_set_interest()->set_object("clay");
  refuse(si, "SetInterest.object");
  // Garbage divergence reports are only logged; the sculptor is still served.
  ASSERT_TRUE(a->SendStroke(PressArc(0, 0)).ok());
  ASSERT_TRUE(a->WaitAllAcked(seconds(10)));
  // A replica whose have_seq predates what the server knows loads its region anew.
  Replica r(*c, {});
  ASSERT_TRUE(r.Start().ok());
  ASSERT_TRUE(r.WaitForSeq(srv_.scene().global_seq(), seconds(20)));
  EXPECT_EQ(r.RegionHash(r.held()), srv_.scene().RegionHash("clay", r.held()));
}

TEST_F(ReplicaTest, ViewerMeshChunksFollowTheEditsAndMatchTheWholeMesh) {
  auto a = Joined(v1::ROLE_SCULPTOR, true);
  // Effects only where asked: edits with no viewer mesh nothing.
  for (int i = 0; i < 5; ++i) ASSERT_TRUE(a->SendStroke(PressArc(3, i)).ok());
  ASSERT_TRUE(a->WaitAllAcked(seconds(20)));
  std::this_thread::sleep_for(milliseconds(300));
  EXPECT_EQ(srv_.scene().mesh_stats().chunks_encoded.load(), 0u);

  auto v = Joined(v1::ROLE_VIEWER, true);
  MeshView view(*v, "clay", /*decode_on_receipt=*/true);
  ASSERT_TRUE(view.Subscribe(30).ok());
  auto whole_faces = [&] {
    uint64_t n = 0;
    srv_.scene().Inspect("clay", [&](const levelset::Sculpture& s) { n = mesh::MeshWhole(s).face_count(); });
    return n;
  };
  auto wait_equal = [&] {
    const uint64_t want = whole_faces();
    const auto end = std::chrono::steady_clock::now() + seconds(20);
    while (std::chrono::steady_clock::now() < end && view.FaceCount() != want) {
      std::this_thread::sleep_for(milliseconds(50));
    }
    return view.FaceCount() == want;
  };
  ASSERT_TRUE(wait_equal()) << view.FaceCount() << " faces in chunks";
  const uint64_t initial_chunks = view.stats().chunks_received;
  EXPECT_GT(initial_chunks, 10u);
  // Edits: only the chunks they touch come again, at a newer version.
  for (int i = 5; i < 15; ++i) ASSERT_TRUE(a->SendStroke(PressArc(3, i)).ok());
  ASSERT_TRUE(a->WaitAllAcked(seconds(20)));
  ASSERT_TRUE(wait_equal());
  std::this_thread::sleep_for(milliseconds(200));
  const MeshViewStats st = view.stats();
  EXPECT_GT(st.chunks_received, initial_chunks);
  EXPECT_LT(st.chunks_received - initial_chunks, initial_chunks);  // not everything again
  EXPECT_EQ(st.max_version, srv_.scene().global_seq());
  EXPECT_FALSE(st.decode_ms.empty());
  auto assembled = view.Assemble();
  ASSERT_TRUE(assembled.ok()) << assembled.status();
  EXPECT_EQ(assembled->face_count(), whole_faces());
  // A bad rate is refused by field; the viewer stays connected.
  auto w = Joined(v1::ROLE_VIEWER, true);
  v1::ClientMessage m;
  m.mutable_viewer_subscribe()->set_object("clay");
  m.mutable_viewer_subscribe()->set_max_rate_hz(1e6f);
  ASSERT_TRUE(w->SendMessage(m).ok());
  // Other events (presence, scene info) may arrive first on a loaded machine: wait for the error.
  auto e = w->NextEvent(seconds(5));
  for (int i = 0; i < 50 && e.has_value() && e->type != Event::Type::kError; ++i) {
    e = w->NextEvent(seconds(5));
  }
  ASSERT_TRUE(e.has_value());
  ASSERT_EQ(e->type, Event::Type::kError);
  EXPECT_EQ(e->error.field(), "ViewerSubscribe.max_rate_hz");
}

// A replica that fell behind before a server restart asks for a sequence whose leaf versions
// the new process does not have: it gets its region anew and ends equal.
TEST_F(ReplicaTest, StaleSequenceAfterAServerRestartLoadsTheRegionAnew) {
  auto a = Joined(v1::ROLE_SCULPTOR, true);
  auto c = Joined(v1::ROLE_VIEWER, true);
  Replica rc(*c, {});
  ASSERT_TRUE(rc.Start().ok());
  ASSERT_TRUE(rc.WaitLoaded(1, seconds(20)));
  for (int i = 0; i < 5; ++i) ASSERT_TRUE(a->SendStroke(PressArc(4, i)).ok());
  ASSERT_TRUE(a->WaitAllAcked(seconds(20)));
  ASSERT_TRUE(rc.WaitForSeq(srv_.scene().global_seq(), seconds(20)));
  c->DropConnection();
  for (int i = 5; i < 12; ++i) ASSERT_TRUE(a->SendStroke(PressArc(4, i)).ok());
  ASSERT_TRUE(a->WaitAllAcked(seconds(20)));
  a.reset();
  // Restart: a new scene recovers from the same data directory (log replay) on a new port.
  srv_.Stop();
  ASSERT_TRUE(srv_.Start());
  ASSERT_EQ(srv_.scene().global_seq(), 12u * 4);
  ASSERT_TRUE(c->Connect("127.0.0.1", srv_.port()).ok());
  ASSERT_TRUE(c->Hello("sculpt-dev-viewer", v1::ROLE_VIEWER, "t", c->client_id()).ok());
  ASSERT_TRUE(c->Join().ok());
  ASSERT_TRUE(rc.Resubscribe().ok());  // have_seq 20: older than what the new process vouches for
  ASSERT_TRUE(rc.WaitLoaded(2, seconds(20)));
  ASSERT_TRUE(rc.WaitIdle(seconds(20)));
  const levelset::VoxelBox held = rc.held();
  EXPECT_EQ(rc.RegionHash(held), srv_.scene().RegionHash("clay", held));
  EXPECT_EQ(rc.stats().hash_mismatches, 0u);
  // A box far outside the object is a valid interest: an empty region, equal to the server's.
  ASSERT_TRUE(rc.MoveInterest(levelset::Aabb{{900, 900, 900}, {910, 910, 910}}).ok());
  ASSERT_TRUE(rc.WaitLoaded(3, seconds(20)));
  ASSERT_TRUE(rc.WaitIdle(seconds(20)));
  EXPECT_EQ(rc.RegionHash(rc.held()), srv_.scene().RegionHash("clay", rc.held()));
}

// In a scene with materials, a viewer's assembled mesh carries one colour per vertex, each in
// [0, 1], and the unpainted clay shows material 0's colour.
TEST(ReplicaColoursTest, AssembledViewerMeshCarriesTheMaterialColours) {
  testing_support::InProcessServer srv("replica_colours");
  srv.config().scene.materials = {{"clay", {0.8, 0.5, 0.3}}, {"gold", {1.0, 0.85, 0.1}}};
  ASSERT_TRUE(srv.Start());
  auto v = srv.Joined(v1::ROLE_VIEWER, true);
  MeshView view(*v, "clay");
  ASSERT_TRUE(view.Subscribe(30).ok());
  const auto end = std::chrono::steady_clock::now() + seconds(20);
  while (std::chrono::steady_clock::now() < end && view.ChunkCount() < 10) {
    std::this_thread::sleep_for(milliseconds(50));
  }
  std::this_thread::sleep_for(milliseconds(300));
  auto m = view.Assemble();
  ASSERT_TRUE(m.ok()) << m.status();
  ASSERT_GT(m->vertex_count(), 100u);
  ASSERT_EQ(m->colours.size(), m->positions.size());
  for (size_t i = 0; i < m->colours.size(); i += 3) {
    EXPECT_NEAR(m->colours[i], 0.8f, 0.01f);
    EXPECT_NEAR(m->colours[i + 1], 0.5f, 0.01f);
    EXPECT_NEAR(m->colours[i + 2], 0.3f, 0.01f);
    if (::testing::Test::HasFailure()) break;
  }
}

// `sculpt export --server --format glb`: the server's current state as a glTF binary whose
// mesh is Draco-compressed (KHR_draco_mesh_compression), after edits.
TEST_F(ReplicaTest, ExportFromTheServerAsGlbCarriesDracoCompression) {
  auto a = Joined(v1::ROLE_SCULPTOR, true);
  for (int i = 0; i < 5; ++i) ASSERT_TRUE(a->SendStroke(PressArc(0, i)).ok());
  ASSERT_TRUE(a->WaitAllAcked(seconds(20)));
  const fs::path out = srv_.dir() / "state.glb";
  const std::string cmd = "SCULPT_TOKEN=sculpt-dev-viewer " + std::string(SCULPT_BIN_DIR) +
                          "/sculpt export --server 127.0.0.1:" + std::to_string(srv_.port()) +
                          " --format glb --out " +
                          out.string() + " > " + (srv_.dir() / "export.log").string() + " 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  std::ifstream in(out, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string bytes = ss.str();
  ASSERT_GT(bytes.size(), 1000u);
  EXPECT_EQ(bytes.substr(0, 4), "glTF");  // GLB magic
  uint32_t version = 0, length = 0;
  std::memcpy(&version, bytes.data() + 4, 4);
  std::memcpy(&length, bytes.data() + 8, 4);
  EXPECT_EQ(version, 2u);
  EXPECT_EQ(length, bytes.size());
  EXPECT_NE(bytes.find("KHR_draco_mesh_compression"), std::string::npos);
  // A bad format is refused with a non-zero exit.
  const std::string bad = std::string(SCULPT_BIN_DIR) + "/sculpt export --server 127.0.0.1:" +
                          std::to_string(srv_.port()) + " --format gltfx --out " +
                          (srv_.dir() / "x.gltfx").string() + " > /dev/null 2>&1";
  EXPECT_NE(std::system(bad.c_str()), 0);
}

}  // namespace
}  // namespace sculpt::client
