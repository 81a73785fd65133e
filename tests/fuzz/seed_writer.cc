/// @brief Writes the seed corpora of the session and leaf_records fuzz targets from real messages:
/// `fuzz_seed_writer tests/fuzz/corpus` (re)writes corpus/session/seed_* and
/// corpus/leaf_records/seed_*. Client messages are built as the client library builds them
/// (PackPoses for strokes); leaf records come from EncodeLeafRecords over a sphere.
#include <zstd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "sculpt/codec/stroke.h"
#include "sculpt/levelset/materials.h"
#include "sculpt/levelset/region.h"
#include "sculpt/levelset/sculpture.h"
#include "sculpt/v1/sculpt.pb.h"
#include "session_input.h"

namespace {

namespace fs = std::filesystem;
namespace v1 = sculpt::v1;
using namespace sculpt::fuzz;

void Write(const fs::path& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << bytes;
  std::printf("%s: %zu bytes\n", path.c_str(), bytes.size());
}

std::string S(const v1::ClientMessage& m) {
  std::string s;
  m.SerializeToString(&s);
  return s;
}

v1::ClientMessage Hello(v1::Role role, uint64_t client_id, const std::string& token = "") {
  v1::ClientMessage m;
  v1::Hello* h = m.mutable_hello();
  h->set_protocol_version(1);
  h->set_token(!token.empty()              ? token
               : role == v1::ROLE_VIEWER ? "sculpt-dev-viewer"
                                         : "sculpt-dev-sculptor");
  h->set_role(role);
  h->set_client_name(role == v1::ROLE_VIEWER ? "viewer" : "sculptor");
  h->set_client_id(client_id);
  return m;
}

v1::ClientMessage Join(bool skip_state) {
  v1::ClientMessage m;
  m.mutable_join()->set_scene("default");
  m.mutable_join()->set_skip_state(skip_state);
  return m;
}

void SetVec(v1::Vec3f* v, double x, double y, double z) {
  v->set_x(static_cast<float>(x));
  v->set_y(static_cast<float>(y));
  v->set_z(static_cast<float>(z));
}

v1::ClientMessage Stroke(uint64_t seq, v1::EditKind kind, v1::ToolKind tool, int poses,
                         double z = 4) {
  v1::ClientMessage m;
  v1::Stroke* s = m.mutable_stroke();
  s->set_client_seq(seq);
  s->set_object("clay");
  s->set_kind(kind);
  s->set_tool(tool);
  SetVec(s->mutable_tool_size(), 1, 0.8, 0.6);
  s->set_speed(60);
  s->set_amount(0.5);
  const sculpt::Vec3 origin{0, 0, z};
  SetVec(s->mutable_origin(), origin.x, origin.y, origin.z);
  s->set_t0_ms(1000);
  std::vector<sculpt::codec::Pose> p;
  for (int i = 0; i < poses; ++i) {
    p.push_back({origin + sculpt::Vec3{0.25 * i, 0.15 * i, 0}, static_cast<uint32_t>(8 * i)});
  }
  s->set_pose_count(static_cast<uint32_t>(poses));
  s->set_poses(sculpt::codec::PackPoses(p, origin, 0.5).value());
  return m;
}

v1::ClientMessage Undo(uint64_t seq, bool redo) {
  v1::ClientMessage m;
  m.mutable_undo()->set_client_seq(seq);
  m.mutable_undo()->set_object("clay");
  m.mutable_undo()->set_redo(redo);
  return m;
}

v1::ClientMessage History(uint64_t id, const std::string& author) {
  v1::ClientMessage m;
  m.mutable_history()->set_request_id(id);
  m.mutable_history()->set_object("clay");
  m.mutable_history()->set_author(author);
  m.mutable_history()->set_limit(10);
  return m;
}

v1::ClientMessage Subscribe(v1::ReplicaMode mode, bool box, uint64_t have_seq) {
  v1::ClientMessage m;
  v1::Subscribe* s = m.mutable_subscribe();
  s->set_object("clay");
  s->set_mode(mode);
  s->set_have_seq(have_seq);
  if (box) {
    SetVec(s->mutable_interest()->mutable_min(), -2, -2, 0);
    SetVec(s->mutable_interest()->mutable_max(), 2, 2, 6);
  }
  return m;
}

v1::ClientMessage SetInterest(double lo, double hi) {
  v1::ClientMessage m;
  m.mutable_set_interest()->set_object("clay");
  SetVec(m.mutable_set_interest()->mutable_interest()->mutable_min(), lo, lo, lo);
  SetVec(m.mutable_set_interest()->mutable_interest()->mutable_max(), hi, hi, hi);
  return m;
}

v1::ClientMessage Hover(double z) {
  v1::ClientMessage m;
  SetVec(m.mutable_hover()->mutable_position(), 0, 0, z);
  m.mutable_hover()->set_radius(1);
  return m;
}

v1::ClientMessage Bye() {
  v1::ClientMessage m;
  m.mutable_bye()->set_reason("done");
  return m;
}

v1::ClientMessage ViewerSubscribe() {
  v1::ClientMessage m;
  m.mutable_viewer_subscribe()->set_object("clay");
  m.mutable_viewer_subscribe()->set_max_rate_hz(30);
  return m;
}

v1::ClientMessage Divergence(uint64_t seq) {
  v1::ClientMessage m;
  m.mutable_divergence()->set_object("clay");
  m.mutable_divergence()->set_global_seq(seq);
  m.mutable_divergence()->set_expected_hash(1);
  m.mutable_divergence()->set_actual_hash(2);
  return m;
}

v1::ClientMessage ContourSkin(bool unsubscribe) {
  v1::ClientMessage m;
  m.mutable_contour_subscribe()->set_skin("skin");
  m.mutable_contour_subscribe()->set_unsubscribe(unsubscribe);
  return m;
}

v1::ClientMessage ContourSlice() {
  v1::ClientMessage m;
  v1::ContourSlice* s = m.mutable_contour_subscribe()->mutable_slice();
  s->set_object("clay");
  SetVec(s->mutable_origin(), 0, 0, 0);
  SetVec(s->mutable_u(), 1, 0, 0);
  SetVec(s->mutable_v(), 0, 1, 0);
  s->set_half_extent(6);
  s->set_step(0.25);
  return m;
}

v1::ClientMessage BallEdit(uint64_t seq, v1::SkinBallOp op, uint32_t index, double x, double y,
                           double r, double theta) {
  v1::ClientMessage m;
  v1::SkinBallEdit* e = m.mutable_skin_ball_edit();
  e->set_client_seq(seq);
  e->set_skin("skin");
  e->set_op(op);
  e->set_index(index);
  e->mutable_ball()->set_x(x);
  e->mutable_ball()->set_y(y);
  e->mutable_ball()->set_r(r);
  e->mutable_ball()->set_theta(theta);
  return m;
}

v1::ClientMessage Sweep(uint64_t seq, v1::SkinSweepMode mode, v1::EditKind kind) {
  v1::ClientMessage m;
  v1::SkinSweep* s = m.mutable_skin_sweep();
  s->set_client_seq(seq);
  s->set_skin("skin");
  s->set_object("clay");
  s->set_mode(mode);
  s->set_kind(kind);
  s->set_depth(1);
  s->set_axis_x(0);
  s->set_axis_y(-1);
  s->set_axis_angle(0);
  return m;
}

v1::ClientMessage Paint(uint64_t seq, bool fill) {
  v1::ClientMessage m;
  v1::PaintEdit* p = m.mutable_paint();
  p->set_client_seq(seq);
  p->set_object("clay");
  p->set_tool(v1::TOOL_KIND_SPHERE);
  SetVec(p->mutable_tool_size(), 1.5, 1.5, 1.5);
  SetVec(p->mutable_position(), 0, 0, 4);
  p->set_material(1);
  p->set_weight(0.7);
  if (fill) {
    p->add_fractions(0.25);
    p->add_fractions(0.75);
  }
  return m;
}

v1::ClientMessage ModelIntent(uint64_t seq) {
  v1::ClientMessage m;
  v1::ModelIntent* i = m.mutable_model_intent();
  i->set_client_seq(seq);
  i->set_object("clay");
  i->set_corner(0);
  i->add_offset(1);
  i->add_offset(0);
  i->add_offset(-1);
  i->set_displacement_x(0.1);
  i->set_cell(-1);
  return m;
}

// An input of the session target: byte 0, then the ops.
struct Input {
  explicit Input(bool two, bool materials = false)
      : bytes(1, static_cast<char>((two ? kTwoSessions : 0) | (materials ? kMaterials : 0))) {}
  Input& Send(const v1::ClientMessage& m, bool b = false, bool more = false) {
    AppendOp(&bytes, static_cast<uint8_t>(kMessage | (b ? kSessionB : 0) | (more ? kMoreInRead : 0)),
             S(m));
    return *this;
  }
  Input& Raw(const std::string& payload, bool b = false) {
    AppendOp(&bytes, static_cast<uint8_t>(kMessage | (b ? kSessionB : 0)), payload);
    return *this;
  }
  Input& Op(uint8_t op) {
    AppendOp(&bytes, op);
    return *this;
  }
  Input& Pump() { return Op(kPump); }
  std::string bytes;
};

void WriteSessionSeeds(const fs::path& dir) {
  fs::create_directories(dir);
  const uint64_t a = 0x1111, b = 0x2222;
  Write(dir / "seed_sculpt_undo_history",
        Input(false)
            .Send(Hello(v1::ROLE_SCULPTOR, a))
            .Send(Join(false))
            .Pump()
            .Send(Stroke(1, v1::EDIT_KIND_PRESS, v1::TOOL_KIND_SPHERE, 4))
            .Send(Stroke(2, v1::EDIT_KIND_ADD, v1::TOOL_KIND_CAPSULE, 3, 3.5))
            .Pump()
            .Send(Undo(1, false))
            .Pump()
            .Send(Undo(2, true))
            .Send(History(7, ""))
            .Pump()
            .Send(History(8, "4369"))
            .Send(Stroke(2, v1::EDIT_KIND_ADD, v1::TOOL_KIND_CAPSULE, 3, 3.5))  // a resend
            .Pump()
            .Send(Bye())
            .bytes);
  Write(dir / "seed_strokes_every_kind",
        Input(false)
            .Send(Hello(v1::ROLE_SCULPTOR, a + 1))
            .Send(Join(true))
            .Send(Stroke(1, v1::EDIT_KIND_SUBTRACT, v1::TOOL_KIND_BOX, 2))
            .Send(Stroke(2, v1::EDIT_KIND_SMOOTH, v1::TOOL_KIND_SPHERE, 2))
            .Send(Stroke(3, v1::EDIT_KIND_INFLATE, v1::TOOL_KIND_ELLIPSOID, 1))
            .Send(Stroke(4, v1::EDIT_KIND_DEFLATE, v1::TOOL_KIND_SPHERE, 1))
            .Pump()
            .Send(Hover(4.5))
            .bytes);
  Write(dir / "seed_viewer_replica",
        Input(false)
            .Send(Hello(v1::ROLE_VIEWER, b))
            .Send(Join(true))
            .Send(Subscribe(v1::REPLICA_MODE_LEAF_DELTA, true, 0))
            .Pump()
            .Send(SetInterest(-3, 3))
            .Send(Divergence(1))
            .Send(Stroke(1, v1::EDIT_KIND_PRESS, v1::TOOL_KIND_SPHERE, 1))  // refused: viewer
            .Pump()
            .Send(Bye())
            .bytes);
  Write(dir / "seed_two_sessions",
        Input(true)
            .Send(Hello(v1::ROLE_SCULPTOR, a + 2))
            .Send(Hello(v1::ROLE_VIEWER, b + 1), true)
            .Send(Join(true))
            .Send(Join(true), true)
            .Send(Subscribe(v1::REPLICA_MODE_REPLAY, false, 0), true)
            .Send(ViewerSubscribe(), true)
            .Pump()
            .Send(Stroke(1, v1::EDIT_KIND_PRESS, v1::TOOL_KIND_SPHERE, 3))
            .Send(Hover(4), true)
            .Op(kPresence)
            .Pump()
            .Send(History(1, ""), true)
            .Pump()
            .bytes);
  Write(dir / "seed_skin_contours",
        Input(false)
            .Send(Hello(v1::ROLE_SCULPTOR, a + 3))
            .Send(Join(true))
            .Send(ContourSkin(false))
            .Send(ContourSlice())
            .Pump()
            .Send(BallEdit(1, v1::SKIN_BALL_OP_MOVE, 1, 0, 1.5, 1.1, 0))
            .Send(BallEdit(2, v1::SKIN_BALL_OP_ADD, 3, 3.5, 0.5, 0.8, 0))
            .Send(BallEdit(3, v1::SKIN_BALL_OP_ORIENT, 0, 0, 0, 1, 0.4))
            .Send(BallEdit(4, v1::SKIN_BALL_OP_REMOVE, 3, 0, 0, 1, 0))
            .Pump()
            .Send(Sweep(1, v1::SKIN_SWEEP_MODE_EXTRUDE, v1::EDIT_KIND_ADD))
            .Send(Sweep(2, v1::SKIN_SWEEP_MODE_REVOLVE, v1::EDIT_KIND_SUBTRACT))
            .Pump()
            .Send(ContourSkin(true))
            .bytes);
  Write(dir / "seed_paint_model",
        Input(false, true)
            .Send(Hello(v1::ROLE_SCULPTOR, a + 4))
            .Send(Join(true))
            .Send(Paint(1, false))
            .Send(Paint(2, true))
            .Send(ModelIntent(1))  // refused: clay is not a model
            .Pump()
            .bytes);
  // A client that stops reading: the join's state and the acks queue up, then flow again.
  Write(dir / "seed_stalled_reader",
        Input(true, true)
            .Send(Hello(v1::ROLE_SCULPTOR, a + 5))
            .Op(kStall | (1 << 4))
            .Send(Join(false))
            .Send(Stroke(1, v1::EDIT_KIND_ADD, v1::TOOL_KIND_SPHERE, 8), false, true)
            .Send(Stroke(2, v1::EDIT_KIND_PRESS, v1::TOOL_KIND_SPHERE, 8), false, true)
            .Send(Stroke(3, v1::EDIT_KIND_SUBTRACT, v1::TOOL_KIND_SPHERE, 8))
            .Send(Hello(v1::ROLE_SCULPTOR, a + 6), true)
            .Send(Join(false), true)
            .Send(Subscribe(v1::REPLICA_MODE_LEAF_DELTA, false, 0), true)
            .Pump()
            .Op(kStall)
            .Pump()
            .bytes);
  // Refusals that close the connection or count as violations.
  Write(dir / "seed_refusals",
        Input(true)
            .Send(Join(false))  // before Hello: closed
            .Send(Hello(v1::ROLE_SCULPTOR, a + 7, "wrong-token"), true)
            .bytes);
  Write(dir / "seed_violations",
        Input(false)
            .Send(Hello(v1::ROLE_SCULPTOR, a + 8))
            .Send(Hello(v1::ROLE_SCULPTOR, a + 8))  // repeated
            .Send(Stroke(1, v1::EDIT_KIND_PRESS, v1::TOOL_KIND_SPHERE, 1))  // before join
            .Send(Join(true))
            .Send(Join(true))  // repeated
            .Raw(std::string("\x0a\x03\x08\x01\x12", 5))  // does not parse: closed
            .bytes);
  Write(dir / "seed_stream_ends",
        Input(true)
            .Send(Hello(v1::ROLE_SCULPTOR, a + 9))
            .Op(kEnd | (3 << 4))  // a partial frame buffered
            .Send(Join(true))
            .Op(kEnd | (1 << 4))  // then a frame above the maximum
            .Send(Hello(v1::ROLE_VIEWER, b + 2), true)
            .Op(kSessionB | kEnd | (2 << 4))  // malformed framing
            .bytes);
  Write(dir / "seed_batched_read",
        Input(false)
            .Send(Hello(v1::ROLE_SCULPTOR, a + 10))
            .Send(Join(true))
            .Send(Stroke(1, v1::EDIT_KIND_PRESS, v1::TOOL_KIND_SPHERE, 2), false, true)
            .Send(Undo(1, false), false, true)
            .Send(Bye())
            .bytes);
}

void WriteLeafSeeds(const fs::path& dir) {
  namespace ls = sculpt::levelset;
  fs::create_directories(dir);
  for (int materials = 0; materials < 2; ++materials) {
    ls::SculptureOptions o;
    o.voxel_size = 0.5;
    auto s = ls::Sculpture::MakeSphere(o, {0, 0, 0}, 3).value();
    if (materials) {
      (void)ls::SetMaterials(s, {{"clay", {0.8, 0.5, 0.3}}, {"glaze", {0.2, 0.4, 0.9}}});
    }
    // Leaves of the surface and cells of the uniform inside and outside.
    const std::vector<ls::Int3> cells = {{0, 0, 0}, {-8, -8, -8}, {0, 0, 8}, {-8, 0, 0}, {32, 32, 32}};
    const std::string wire = ls::EncodeLeafRecords(s, cells, nullptr, 3);
    const std::string name = materials ? "slr2" : "slr1";
    const char flags = static_cast<char>(materials);
    Write(dir / ("seed_" + name + "_wire"), std::string(1, flags) + wire);
    // The raw payload (flag 4: the target frames and compresses it).
    std::string raw(*reinterpret_cast<const uint64_t*>(wire.data()), '\0');
    ZSTD_decompress(raw.data(), raw.size(), wire.data() + 8, wire.size() - 8);
    Write(dir / ("seed_" + name + "_raw"), std::string(1, static_cast<char>(flags | 4)) + raw);
    Write(dir / ("seed_" + name + "_raw_clipped"),
          std::string(1, static_cast<char>(flags | 4 | 2)) + raw);
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s CORPUS_DIR (tests/fuzz/corpus)\n", argv[0]);
    return 2;
  }
  const fs::path root(argv[1]);
  WriteSessionSeeds(root / "session");
  WriteLeafSeeds(root / "leaf_records");
  return 0;
}
