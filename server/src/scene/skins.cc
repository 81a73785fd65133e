/// @brief SkinBook (issue 6): ball edits that rebuild only the changed sections, contour
/// subscribers (skins and slices of objects), skin files beside snapshots; and the scene's skin
/// edit kinds on the commit pipeline (ball edits, sweeps of a skin into a sculpture), logged so
/// that recovery replays them. Everything on the Scene runs on the compute thread.
#include "scene/skins.h"

#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <future>
#include <iterator>

#include "scene/answer_once.h"
#include "scene/edit_history.h"
#include "scene/scene.h"
#include "sculpt/codec/contour_frames.h"
#include "sculpt/codec/log_records.h"
#include "sculpt/codec/skin_messages.h"
#include "sculpt/codec/stroke.h"
#include "sculpt/core/check.h"
#include "sculpt/levelset/slice.h"
#include "sculpt/skin/contour_codec.h"
#include "store/durable_file.h"
#include "store/edit_log.h"
#include "store/resend_table.h"

namespace sculpt::server {
namespace {

// The server's wall clock, ms since 1970: when a ball edit was committed (the history view).
uint64_t WallClockMs() {
  return static_cast<uint64_t>(std::chrono::duration_cast<std::chrono::milliseconds>(
                                   std::chrono::system_clock::now().time_since_epoch())
                                   .count());
}

// Slices are quantised to an eighth of their sample spacing.
constexpr double kSliceQuantumPerStep = 1.0 / 8;

// The whole chain, so that a contour subscriber can draw the balls and address them by index.
std::vector<codec::SkinBall> Balls(const skin::Skin& sk) {
  std::vector<codec::SkinBall> out;
  out.reserve(sk.balls().size());
  for (const skin::OrientedBall& b : sk.balls()) out.push_back({b.c.x, b.c.y, b.r, b.theta});
  return out;
}

std::vector<skin::Polyline2> ToPolylines(const std::vector<std::vector<levelset::PlanePoint>>& in) {
  std::vector<skin::Polyline2> out;
  out.reserve(in.size());
  for (const auto& line : in) {
    skin::Polyline2& p = out.emplace_back();
    p.reserve(line.size());
    for (const levelset::PlanePoint& q : line) p.push_back({q.x, q.y});
  }
  return out;
}

// The scene's check of a ball edit's index against the skin it edits (the live path and
// recovery alike).
Status CheckBallIndex(const skin::Skin& sk, const codec::BallEdit& e) {
  const size_t n = sk.balls().size();
  const size_t i = e.index;
  const bool add = e.op == codec::BallOp::kAdd;
  if (add ? i > n : i >= n) {
    return Outside("SkinBallEdit.index", std::to_string(i),
                   std::string("[0, ") + std::to_string(add ? n : n - 1) + "]");
  }
  if (add && n >= kMaxSkinBalls) {
    return Outside("SkinBallEdit.op", "ADD",
                   std::string("skins of at most ") + std::to_string(kMaxSkinBalls) + " balls");
  }
  return Status::Ok();
}

// Applies a ball edit whose index passed CheckBallIndex; the skin names an inadmissible pair.
StatusOr<skin::SkinChange> ApplyBallOp(skin::Skin& sk, const codec::BallEdit& e) {
  const size_t i = e.index;
  switch (e.op) {
    case codec::BallOp::kAdd:
      return sk.InsertBall(i, {{e.x, e.y}, e.r, e.theta});
    case codec::BallOp::kMove: {
      skin::OrientedBall o = sk.balls()[i];
      o.c = {e.x, e.y};
      o.r = e.r;
      return sk.SetBall(i, o);
    }
    case codec::BallOp::kOrient: {
      skin::OrientedBall o = sk.balls()[i];
      o.theta = e.theta;
      return sk.SetBall(i, o);
    }
    case codec::BallOp::kRemove:
      break;
  }
  return sk.RemoveBall(i);
}

std::string SkinFilePath(const std::string& data_dir, const std::string& name) {
  return (std::filesystem::path(data_dir) / "skins" / (name + ".pb")).string();
}
// The skin's undo history of the same round: the skin file's seq (8 bytes), then
// BookHistory::Serialize's bytes.
std::string SkinHistoryPath(const std::string& data_dir, const std::string& name) {
  return (std::filesystem::path(data_dir) / "skins" / (name + ".history")).string();
}

std::string BallEditBytes(const codec::BallEdit& e) {
  codec::BallEditRecord r;
  r.edit = e;
  return codec::EncodeLogRecord(r);
}
StatusOr<codec::BallEdit> BallEditFromBytes(std::string_view bytes) {
  SCULPT_ASSIGN_OR_RETURN(codec::EditLogRecord rec, codec::DecodeLogRecord(0, bytes));
  const auto* r = std::get_if<codec::BallEditRecord>(&rec);
  if (!r) return DataLoss("not a ball edit");
  if (!r->edit_status.ok()) return DataLoss(r->edit_status.message());
  return r->edit;
}
std::string ChainBytes(const skin::Skin& sk) {
  codec::SavedSkin saved;
  for (const skin::OrientedBall& o : sk.balls())
    saved.balls.push_back({o.c.x, o.c.y, o.r, o.theta});
  return codec::EncodeSavedSkin(saved);
}

// Sends one subscriber its slice, from contours already computed.
void SendSlice(const std::string& object, const ReplicaSink& sink, double step,
               const std::vector<std::vector<levelset::PlanePoint>>& lines, uint64_t seq) {
  auto bytes = skin::EncodeContours(ToPolylines(lines), step * kSliceQuantumPerStep);
  if (!bytes.ok()) {
    spdlog::warn("slice of {}: not encoded: {}", object, bytes.status().ToString());
    return;
  }
  codec::ContourUpdateFrame u;
  u.object = object;
  u.data = std::move(bytes).value();
  u.sections = static_cast<uint32_t>(lines.size());
  u.global_seq = seq;
  sink.send(codec::EncodeContourUpdate(std::move(u)));
}

// True when the slice's plane passes through the world box of the changed leaves (the slice
// cannot have changed otherwise).
bool PlaneCrosses(const levelset::SweepPlane& plane, const std::vector<levelset::Int3>& leaves,
                  double dx) {
  if (leaves.empty()) return false;
  Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
  for (const levelset::Int3& l : leaves) {
    lo = {std::min(lo.x, l.x * dx), std::min(lo.y, l.y * dx), std::min(lo.z, l.z * dx)};
    hi = {std::max(hi.x, (l.x + 8) * dx), std::max(hi.y, (l.y + 8) * dx),
          std::max(hi.z, (l.z + 8) * dx)};
  }
  const Vec3 n = plane.u.Cross(plane.v);
  bool below = false, above = false;
  for (int c = 0; c < 8; ++c) {
    const Vec3 p{(c & 1) ? hi.x : lo.x, (c & 2) ? hi.y : lo.y, (c & 4) ? hi.z : lo.z};
    const double d = n.Dot(p - plane.origin);
    below = below || d <= 0;
    above = above || d >= 0;
  }
  return below && above;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Sweeps in the edit log; skin files beside the snapshots

Status ReplaySweep(levelset::Sculpture& sculpture, EditHistory& history, uint64_t seq,
                   const codec::SweepRecord& r) {
  if (!r.request_status.ok()) {
    spdlog::warn("sweep at seq {} not replayed: {}", seq, r.request_status.ToString());
    return Status::Ok();
  }
  // A sweep the live server refused after logging it is refused identically here. The record
  // keeps no commit time: the history view shows the time of a replayed sweep as unknown.
  (void)history.ApplySweep(sculpture, seq, HistoryAuthor(r.client_id), r.request);
  return Status::Ok();
}

Status SaveSkinFile(const std::string& path, const codec::SavedSkin& saved) {
  const std::string bytes = codec::EncodeSavedSkin(saved);
  const std::string tmp = path + ".tmp";
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return Internal("open " + tmp + ": " + std::strerror(errno));
  size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      const std::string why = std::strerror(errno);
      ::close(fd);
      return Internal("write " + tmp + ": " + why);
    }
    done += static_cast<size_t>(n);
  }
  if (::fdatasync(fd) != 0) {
    const std::string why = std::strerror(errno);
    ::close(fd);
    return Internal("sync " + tmp + ": " + why);
  }
  if (::close(fd) != 0) return Internal("close " + tmp + ": " + std::strerror(errno));
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) return Internal("rename " + tmp + ": " + ec.message());
  // The log before this file's seq may be dropped once it is saved: make the rename durable.
  return store::FsyncDirectory(std::filesystem::path(path).parent_path().string());
}

StatusOr<codec::SavedSkin> LoadSkinFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return NotFound("skin file " + path);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  auto saved = codec::DecodeSavedSkin(bytes);
  if (!saved.ok()) return DataLoss("skin file " + path + " does not parse");
  return saved;
}

// ---------------------------------------------------------------------------------------------
// SkinBook

StatusOr<const SkinBook::Entry*> SkinBook::Find(const std::string& field,
                                                const std::string& name) const {
  auto it = skins_.find(name);
  if (it == skins_.end()) return Outside(field, name, "the scene's skins", Status::Code::kNotFound);
  return &it->second;
}

Status SkinBook::Open(const std::vector<SkinConfig>& skins, const std::string& data_dir,
                      ResendFilter* resend) {
  data_dir_ = data_dir;
  skins_.clear();
  slices_.clear();
  for (const SkinConfig& c : skins) {
    std::vector<skin::OrientedBall> balls;
    uint64_t version = 0;
    uint64_t file_seq = 0;
    auto saved = LoadSkinFile(SkinFilePath(data_dir_, c.name));
    if (saved.ok()) {
      for (const codec::SkinBall& b : saved->balls) balls.push_back({{b.x, b.y}, b.r, b.theta});
      version = saved->version;
      file_seq = saved->seq;
      // Files written before the resend table held every edit kind carry their own.
      if (resend != nullptr) {
        for (const auto& [id, seq] : saved->last_edit_seq) {
          resend->Record(ResendStream::kBallEdits, id, seq);
        }
        for (const auto& [id, seq] : saved->last_sweep_seq) {
          resend->Record(ResendStream::kSweeps, id, seq);
        }
      }
    } else if (saved.status().code() != Status::Code::kNotFound) {
      return saved.status();
    } else {
      for (const auto& b : c.balls) balls.push_back({{b[0], b[1]}, b[2], b[3]});
    }
    skin::SkinOptions opt;
    SCULPT_ASSIGN_OR_RETURN(opt.method, skin::ParseMethod(c.method));
    opt.chord_tolerance = c.chord_tolerance;
    auto built = skin::Skin::Build(std::move(balls), opt);
    if (!built.ok()) {
      return InvalidArgument("scene.skins " + c.name + ": " + built.status().message());
    }
    Entry entry{{c.origin, c.u, c.v},
                std::move(built).value(),
                version,
                file_seq,
                {},
                History("ball edit", undo_depth_),
                opt};
    LoadHistory(c.name, entry);
    skins_.emplace(c.name, std::move(entry));
  }
  return Status::Ok();
}

void SkinBook::Replay(uint64_t seq, const codec::BallEditRecord& r) {
  auto it = skins_.find(r.edit.skin);
  if (it == skins_.end()) {
    spdlog::warn("ball edit at seq {} names skin {}, which the scene does not define", seq,
                 r.edit.skin);
    return;
  }
  Entry& entry = it->second;
  if (seq <= entry.file_seq) return;  // the skin file holds it
  skin::Skin before = entry.skin;
  // The codec checked the logged edit as the live server checked it.
  Status st = r.edit_status;
  if (st.ok()) st = CheckBallIndex(entry.skin, r.edit);
  if (st.ok()) st = ApplyBallOp(entry.skin, r.edit).status();
  if (!st.ok()) {
    spdlog::warn("ball edit at seq {} refused on replay: {}", seq, st.ToString());
    return;
  }
  entry.version = r.skin_version;
  // As live: the chain before it is what an undo rebuilds from.
  entry.history.Commit(seq, HistoryAuthor(r.client_id), 0, r.edit, std::move(before));
}

bool SkinBook::Save(uint64_t seq) const { return SaveTo(data_dir_, seq); }

bool SkinBook::SaveTo(const std::string& dir, uint64_t seq) const {
  if (skins_.empty()) return true;
  bool saved_all = true;
  std::error_code ec;
  std::filesystem::create_directories(std::filesystem::path(dir) / "skins", ec);
  for (const auto& [name, entry] : skins_) {
    codec::SavedSkin saved;
    saved.seq = seq;
    saved.version = entry.version;
    for (const skin::OrientedBall& o : entry.skin.balls()) {
      saved.balls.push_back({o.c.x, o.c.y, o.r, o.theta});
    }
    // Written before the log rolls, so the segments a snapshot lets go are already covered.
    if (const Status s = SaveSkinFile(SkinFilePath(dir, name), saved); !s.ok()) {
      spdlog::error("skin {} at seq {} not saved: {}", name, seq, s.ToString());
      saved_all = false;
      continue;
    }
    // Its undo history, for a restart from this file (Open checks the seq matches).
    std::string bytes(reinterpret_cast<const char*>(&seq), sizeof seq);
    bytes += entry.history.Serialize(ChainBytes, BallEditBytes);
    if (const Status s = store::WriteFileDurably(SkinHistoryPath(dir, name), bytes); !s.ok()) {
      spdlog::error("undo history of skin {} at seq {} not saved: {}", name, seq, s.ToString());
      saved_all = false;
    }
  }
  return saved_all;
}

StatusOr<SkinBook::BallEditPlan> SkinBook::PrepareBallEdit(const codec::BallEdit& edit) const {
  SCULPT_ASSIGN_OR_RETURN(const Entry* entry, Find("SkinBallEdit.skin", edit.skin));
  SCULPT_RETURN_IF_ERROR(CheckBallIndex(entry->skin, edit));
  // Admissibility is only known by building the changed sections: on a copy.
  BallEditPlan plan{edit.skin, entry->skin, {}, entry->version + 1};
  auto c = ApplyBallOp(plan.next, edit);
  if (!c.ok()) {
    // The skin names the inadmissible pair (digest Def 2.6); the refusal names the ball.
    return Outside(
        "SkinBallEdit.ball",
        std::string("(") + FormatNumber(edit.x) + ", " + FormatNumber(edit.y) + ", r " +
            FormatNumber(edit.r) + std::string(", theta ") + FormatNumber(edit.theta) +
            ") at index " + std::to_string(edit.index),
        "balls admissible with their neighbours (no contact point inside a neighbour's disk; no "
        "nested, concentric or coincident pair), at least 2 balls: " +
            c.status().message(),
        c.status().code());
  }
  plan.change = std::move(c).value();
  return plan;
}

size_t SkinBook::ApplyBallEdit(BallEditPlan plan, uint64_t seq, const std::string& author,
                               const codec::BallEdit& edit, uint64_t wall_ms) {
  Entry& entry = skins_.at(plan.skin);
  if (!author.empty()) entry.history.Commit(seq, author, wall_ms, edit, std::move(entry.skin));
  entry.skin = std::move(plan.next);
  entry.version = plan.version;
  if (!entry.subs.empty()) {
    auto bytes = skin::EncodeSkinUpdate(entry.skin, plan.change);
    if (!bytes.ok()) {
      spdlog::error("skin {}: update not encoded: {}", plan.skin, bytes.status().ToString());
    } else {
      codec::ContourUpdateFrame u;
      u.skin = plan.skin;
      u.data = std::move(bytes).value();
      u.sections = static_cast<uint32_t>(plan.change.changed.size());
      u.skin_version = entry.version;
      u.balls = Balls(entry.skin);
      auto frame = codec::EncodeContourUpdate(std::move(u));
      for (auto& [id, sink] : entry.subs) sink.send(frame);
    }
  }
  return entry.skin.balls().size();
}

void SkinBook::LoadHistory(const std::string& name, Entry& entry) {
  if (entry.file_seq == 0) return;  // built from the scene: nothing before it to undo
  std::ifstream in(SkinHistoryPath(data_dir_, name), std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  uint64_t seq = 0;
  if (bytes.size() >= sizeof seq) std::memcpy(&seq, bytes.data(), sizeof seq);
  const std::string why = "no undo history of skin " + name + " was kept with its file at seq " +
                          std::to_string(entry.file_seq);
  if (!in || bytes.size() < sizeof seq || seq != entry.file_seq) return entry.history.Clear(why);
  const skin::SkinOptions options = entry.options;
  auto chain = [&options](std::string_view b) -> StatusOr<skin::Skin> {
    SCULPT_ASSIGN_OR_RETURN(codec::SavedSkin saved, codec::DecodeSavedSkin(b));
    std::vector<skin::OrientedBall> balls;
    for (const codec::SkinBall& x : saved.balls) balls.push_back({{x.x, x.y}, x.r, x.theta});
    return skin::Skin::Build(std::move(balls), options);
  };
  const Status s =
      entry.history.Parse(std::string_view(bytes).substr(sizeof seq), chain, BallEditFromBytes);
  if (!s.ok()) {
    spdlog::warn("undo history of skin {}: {}; its earlier ball edits can no longer be undone",
                 name, s.ToString());
    entry.history.Clear(why);
  }
}

void SkinBook::SendWhole(const std::string& name, Entry& entry) {
  if (entry.subs.empty()) return;
  auto bytes = skin::EncodeSkinSnapshot(entry.skin);
  if (!bytes.ok()) {
    spdlog::error("skin {}: snapshot not encoded: {}", name, bytes.status().ToString());
    return;
  }
  codec::ContourUpdateFrame u;
  u.skin = name;
  u.data = std::move(bytes).value();
  u.sections = static_cast<uint32_t>(entry.skin.sections().size());
  u.skin_version = entry.version;
  u.balls = Balls(entry.skin);
  auto frame = codec::EncodeContourUpdate(std::move(u));
  for (auto& [id, sink] : entry.subs) sink.send(frame);
}

namespace {
// A ball edit re-applied by an undo's rebuild: on a copy, kept only when the chain takes it.
bool ReapplyBallEdit(skin::Skin& sk, const codec::BallEdit& e) {
  if (!CheckBallIndex(sk, e).ok()) return false;
  skin::Skin next = sk;
  if (!ApplyBallOp(next, e).ok()) return false;
  sk = std::move(next);
  return true;
}
}  // namespace

StatusOr<uint64_t> SkinBook::UndoTarget(const std::string& skin, const std::string& author,
                                        bool redo) const {
  SCULPT_ASSIGN_OR_RETURN(const Entry* entry, Find("UndoRequest.object", skin));
  return redo ? entry->history.RedoTarget(author) : entry->history.UndoTarget(author);
}

StatusOr<UndoOutcome> SkinBook::Undo(const std::string& skin, const std::string& author, bool redo,
                                     uint64_t at_seq) {
  auto it = skins_.find(skin);
  if (it == skins_.end()) {
    return Outside("UndoRequest.object", skin, "the scene's objects and skins",
                   Status::Code::kNotFound);
  }
  Entry& entry = it->second;
  skin::Skin state = entry.skin;
  auto out = redo ? entry.history.Redo(author, &state, ReapplyBallEdit)
                  : entry.history.Undo(author, at_seq, &state, ReapplyBallEdit);
  if (!out.ok()) return out;
  entry.skin = std::move(state);
  ++entry.version;
  SendWhole(skin, entry);
  return out;
}

void SkinBook::ReplayUndo(uint64_t seq, const codec::UndoRecord& r) {
  auto it = skins_.find(r.object);
  if (it == skins_.end() || seq <= it->second.file_seq) return;
  auto out = Undo(r.object, HistoryAuthor(r.client_id), r.redo, seq);
  if (!out.ok()) {
    spdlog::warn("{} of a ball edit at seq {} refused on replay: {}", r.redo ? "redo" : "undo", seq,
                 out.status().ToString());
  }
}

std::pair<size_t, size_t> SkinBook::UndoDepth(const std::string& skin,
                                              const std::string& author) const {
  auto it = skins_.find(skin);
  if (it == skins_.end()) return {0, 0};
  return {it->second.history.undo_depth(author), it->second.history.redo_depth(author)};
}

StatusOr<std::vector<HistoryEntry>> SkinBook::Entries(const std::string& skin,
                                                      const std::string& author,
                                                      std::string* cleared, size_t* held) const {
  SCULPT_ASSIGN_OR_RETURN(const Entry* entry, Find("HistoryRequest.object", skin));
  *cleared = entry->history.cleared_reason();
  *held = entry->history.size();
  return entry->history.Entries(author);
}

size_t SkinBook::ball_count(const std::string& skin) const {
  auto it = skins_.find(skin);
  return it == skins_.end() ? 0 : it->second.skin.balls().size();
}

uint64_t SkinBook::version(const std::string& skin) const {
  auto it = skins_.find(skin);
  return it == skins_.end() ? 0 : it->second.version;
}

StatusOr<levelset::SweepRequest> SkinBook::SweepRequestFor(
    const codec::SkinSweepRequest& sweep) const {
  SCULPT_ASSIGN_OR_RETURN(const Entry* entry, Find("SkinSweep.skin", sweep.skin));
  levelset::SweepRequest q;
  q.mode = sweep.mode;
  q.add = sweep.add;
  q.depth = sweep.depth;
  q.plane = entry->plane;
  const skin::Polyline2 outline = entry->skin.Outline();
  q.outline.reserve(outline.size());
  for (const skin::Vec2& p : outline) q.outline.push_back({p.x, p.y});
  if (sweep.mode == levelset::SweepRequest::Mode::kRevolve) {
    q.axis_point = {sweep.axis_x, sweep.axis_y};
    q.axis_dir = {std::cos(sweep.axis_angle), std::sin(sweep.axis_angle)};
  }
  return q;
}

void SkinBook::Subscribe(ReplicaSink sink, const codec::ContourRequest& req,
                         const levelset::Sculpture* sculpture, uint64_t seq,
                         const std::function<void(Status)>& answer) {
  const uint64_t session = sink.session_id;
  if (!req.skin.empty()) {
    auto it = skins_.find(req.skin);
    if (it == skins_.end()) {
      return answer(
          Outside("ContourSubscribe.skin", req.skin, "the scene's skins", Status::Code::kNotFound));
    }
    Entry& entry = it->second;
    if (req.unsubscribe) {
      entry.subs.erase(session);
      return answer(Status::Ok());
    }
    auto bytes = skin::EncodeSkinSnapshot(entry.skin);
    if (!bytes.ok()) return answer(bytes.status());
    answer(Status::Ok());
    codec::ContourUpdateFrame u;
    u.skin = req.skin;
    u.data = std::move(bytes).value();
    u.sections = static_cast<uint32_t>(entry.skin.sections().size());
    u.skin_version = entry.version;
    u.balls = Balls(entry.skin);
    sink.send(codec::EncodeContourUpdate(std::move(u)));
    entry.subs[session] = std::move(sink);
    return;
  }
  const std::string& object = req.object;
  if (sculpture == nullptr) {
    return answer(Outside("ContourSubscribe.slice.object", object, "the scene's objects",
                          Status::Code::kNotFound));
  }
  if (req.unsubscribe) {
    if (auto it = slices_.find(object); it != slices_.end()) it->second.erase(session);
    return answer(Status::Ok());
  }
  SliceSub sub;
  sub.sink = std::move(sink);
  sub.request.plane = req.plane;
  sub.request.half_extent = req.half_extent;
  sub.request.step = req.step;
  auto lines = levelset::SliceContours(*sculpture, sub.request);
  if (!lines.ok()) return answer(lines.status());
  answer(Status::Ok());
  SendSlice(object, sub.sink, sub.request.step, *lines, seq);
  slices_[object][session] = std::move(sub);
}

void SkinBook::Unsubscribe(uint64_t session_id) {
  for (auto& [name, entry] : skins_) entry.subs.erase(session_id);
  for (auto& [object, subs] : slices_) subs.erase(session_id);
}

void SkinBook::SendSlices(const std::string& object, const levelset::Sculpture& sculpture,
                          const std::vector<levelset::Int3>& changed, uint64_t seq) {
  auto it = slices_.find(object);
  if (it == slices_.end() || it->second.empty()) return;
  for (auto& [session, sub] : it->second) {
    if (!PlaneCrosses(sub.request.plane, changed, sculpture.voxel_size())) continue;
    auto lines = levelset::SliceContours(sculpture, sub.request);
    if (lines.ok()) SendSlice(object, sub.sink, sub.request.step, *lines, seq);
  }
}

StatusOr<skin::Skin> SkinBook::Copy(const std::string& name) const {
  SCULPT_ASSIGN_OR_RETURN(const Entry* entry, Find("skin", name));
  return entry->skin;
}

size_t SkinBook::subscriber_count() const {
  size_t n = 0;
  for (const auto& [name, entry] : skins_) n += entry.subs.size();
  for (const auto& [object, subs] : slices_) n += subs.size();
  return n;
}

// ---------------------------------------------------------------------------------------------
// The scene's skin edits and contour subscriptions

// A ball edit: Prepare checks it on a copy of the skin, Apply puts the copy in place and sends
// the skin's contour subscribers the sections that changed (SkinBook). Nothing changes before
// the record is in the log.
struct Scene::BallEditOp final : EditOp {
  BallEditOp(uint64_t client, codec::BallEdit e, std::function<void(SkinOutcome)> d)
      : client(client), edit(std::move(e)), done(std::move(d)) {}
  const char* operation() const override { return "ball edit"; }
  ResendStream stream() const override { return ResendStream::kBallEdits; }
  uint64_t client_id() const override { return client; }
  uint64_t client_seq() const override { return edit.client_seq; }

  Status Prepare(Scene& scene, uint64_t first_seq, std::vector<std::string>* records) override {
    SCULPT_ASSIGN_OR_RETURN(SkinBook::BallEditPlan p, scene.skins_.PrepareBallEdit(edit));
    sections = p.change.changed.size();
    codec::BallEditRecord rec;
    rec.global_seq = first_seq;
    rec.client_id = client;
    rec.edit = edit;
    rec.skin_version = p.version;
    records->push_back(codec::EncodeLogRecord(rec));
    plan.emplace(std::move(p));
    seq = first_seq;
    return Status::Ok();
  }

  Applied Apply(Scene& scene) override {
    balls = scene.skins_.ApplyBallEdit(std::move(*plan), seq, HistoryAuthor(client), edit,
                                       WallClockMs());
    plan.reset();
    return Applied{};  // no sculpture changed
  }

  void Duplicate(Scene& scene) override { balls = scene.skins_.ball_count(edit.skin); }

  void Answer(const CommitOutcome& o) override {
    SkinOutcome a;
    a.status = o.status;
    a.client_seq = o.client_seq;
    if (o.status.ok()) {
      a.duplicate = o.duplicate;
      if (!o.duplicate) {
        a.changed_sections = static_cast<uint32_t>(sections);
        a.global_seq = o.global_seq_first;
      }
      a.balls = static_cast<uint32_t>(balls);
    }
    done(std::move(a));
  }

  uint64_t client;
  codec::BallEdit edit;
  std::function<void(SkinOutcome)> done;
  std::optional<SkinBook::BallEditPlan> plan;
  uint64_t seq = 0;
  size_t sections = 0;
  size_t balls = 0;
};

void Scene::EditSkin(uint64_t client_id, codec::BallEdit e, std::function<void(SkinOutcome)> done) {
  Commit(std::make_shared<BallEditOp>(client_id, std::move(e), AnswerOnce(std::move(done))));
}

// A sweep: the skin's outline and plane go into the record (so recovery needs no skin), the
// kernel request is built from the record, checked against the object, and applied from it
// through the object's undo history under its author, exactly as recovery applies the record
// (ReplaySweep), so the author can undo it and an undo of it or past it replays the same after a
// restart. Replicas get the changed leaves (a sweep has no replay form), as for its undo.
struct Scene::SweepOp final : EditOp {
  SweepOp(uint64_t client, codec::SkinSweepRequest s, std::function<void(SkinOutcome)> d)
      : client(client), sweep(std::move(s)), done(std::move(d)) {}
  const char* operation() const override { return "skin sweep"; }
  ResendStream stream() const override { return ResendStream::kSweeps; }
  uint64_t client_id() const override { return client; }
  uint64_t client_seq() const override { return sweep.client_seq; }

  Status Prepare(Scene& scene, uint64_t first_seq, std::vector<std::string>* records) override {
    // The record holds the request as the kernel applies it (its numbers are doubles both ways,
    // so recovery applies the same one).
    SCULPT_ASSIGN_OR_RETURN(levelset::SweepRequest q, scene.skins_.SweepRequestFor(sweep));
    auto obj = scene.sculptures_.find(sweep.object);
    if (obj == scene.sculptures_.end()) {
      return Outside("SkinSweep.object", sweep.object, "the scene's objects",
                     Status::Code::kNotFound);
    }
    SCULPT_RETURN_IF_ERROR(levelset::ValidateSweep(obj->second, q));
    codec::SweepRecord rec;
    rec.global_seq = first_seq;
    rec.client_id = client;
    rec.client_seq = sweep.client_seq;
    rec.object = sweep.object;
    rec.request = q;
    request = std::move(q);
    records->push_back(codec::EncodeLogRecord(rec));
    seq = first_seq;
    return Status::Ok();
  }

  Applied Apply(Scene& scene) override {
    Applied a;
    a.object = sweep.object;
    a.bounds_may_change = true;
    // A sweep the kernel refuses changes nothing and is not recorded.
    auto res = scene.HistoryOf(sweep.object)
                   .ApplySweep(scene.sculptures_.at(sweep.object), seq, HistoryAuthor(client),
                               request, WallClockMs());
    if (!res.ok()) {
      a.status = res.status();
      return a;
    }
    volume_after = res->volume_after;
    a.dirty_leaves = std::move(res->dirty_leaves);
    dirty_leaves = a.dirty_leaves.size();
    return a;
  }

  void Answer(const CommitOutcome& o) override {
    SkinOutcome a;
    a.status = o.status;
    a.client_seq = o.client_seq;
    if (o.status.ok()) {
      a.duplicate = o.duplicate;
      if (!o.duplicate) {
        a.volume_after = volume_after;
        a.dirty_leaves = static_cast<uint32_t>(dirty_leaves);
      }
    }
    // Also for a sweep the kernel refused after it was logged: it holds that sequence.
    if (o.records > 0) a.global_seq = o.global_seq_first;
    done(std::move(a));
  }

  uint64_t client;
  codec::SkinSweepRequest sweep;
  std::function<void(SkinOutcome)> done;
  levelset::SweepRequest request;
  uint64_t seq = 0;
  double volume_after = 0;
  size_t dirty_leaves = 0;
};

void Scene::SweepSkin(uint64_t client_id, codec::SkinSweepRequest s,
                      std::function<void(SkinOutcome)> done) {
  Commit(std::make_shared<SweepOp>(client_id, std::move(s), AnswerOnce(std::move(done))));
}

void Scene::SubscribeContours(ReplicaSink sink, codec::ContourRequest req,
                              std::function<void(Status)> done) {
  auto once = AnswerOnce(std::move(done));
  auto fail = [once](const Status& st) { once(st); };
  const uint64_t who = CurrentRequester();
  Post(who, "contours", fail, [this, sink = std::move(sink), req = std::move(req), once]() mutable {
    // The scene decides which effects it computes: without contours, no skin contour or slice
    // is encoded for anyone (principle 2 of ARCHITECTURE.md).
    if (!config_.scene.effects.contours && !req.unsubscribe) {
      return once(Outside("scene.effects.contours", "false",
                          "{true}: this scene computes no skin contours or slices (set contours = "
                          "true under [scene.effects])",
                          Status::Code::kFailedPrecondition));
    }
    const levelset::Sculpture* sculpture = nullptr;
    if (req.skin.empty()) {
      auto it = sculptures_.find(req.object);
      if (it != sculptures_.end()) sculpture = &it->second;
    }
    skins_.Subscribe(std::move(sink), req, sculpture, applied_seq_.load(), once);
  });
}

void Scene::UnsubscribeContours(uint64_t session_id) {
  Post(CurrentRequester(), "contour unsubscribe",
       [this, session_id] { skins_.Unsubscribe(session_id); });
}

StatusOr<skin::Skin> Scene::SkinCopy(const std::string& name) {
  std::promise<StatusOr<skin::Skin>> p;
  auto fail = [&p](const Status& st) { p.set_value(st); };
  Post("skin copy", fail, [&] { p.set_value(skins_.Copy(name)); });
  return p.get_future().get();
}

}  // namespace sculpt::server
