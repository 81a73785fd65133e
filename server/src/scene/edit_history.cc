/// @brief EditHistory: per-author undo/redo by pre-images and ordered replay (issue 15).
#include "scene/edit_history.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <tuple>
#include <type_traits>
#include <unordered_set>

#include "scene/paint.h"
#include "sculpt/codec/log_records.h"
#include "sculpt/core/check.h"
#include "sculpt/levelset/materials.h"

namespace sculpt::server {
namespace {

using levelset::CellImage;
using levelset::Int3;
using levelset::ReplayState;
using levelset::VoxelBox;

bool CellLess(const Int3& a, const Int3& b) {
  return std::tie(a.z, a.y, a.x) < std::tie(b.z, b.y, b.x);
}

uint64_t Key(const Int3& o) {
  const uint64_t x = static_cast<uint64_t>((o.x >> 3) + (1 << 20)) & 0x1FFFFF;
  const uint64_t y = static_cast<uint64_t>((o.y >> 3) + (1 << 20)) & 0x1FFFFF;
  const uint64_t z = static_cast<uint64_t>((o.z >> 3) + (1 << 20)) & 0x1FFFFF;
  return x | (y << 21) | (z << 42);
}

bool SameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// Whether an edit's result depends on the tracked scalars, not only on the voxels it reads:
// shell compensation aims the volume of its block at the reference volume, so it reads both;
// reinit_every_k makes the reinitialisation depend on the edit counter.
bool ReadsVolume(const levelset::EditRequest& r, const levelset::EditSettings& s) {
  return (r.kind == levelset::EditKind::kPress || r.kind == levelset::EditKind::kSmooth) &&
         s.compensation != levelset::CompensationRegion::kNone;
}

std::string Quoted(const std::string& s) { return "\"" + s + "\""; }

// The serialized history: this magic, then the sizes of the structs written as they are in
// memory (a build with other layouts refuses the bytes rather than misreading them). SEH2 adds
// each record's commit time after its seq; SEH1 files (without it) still load, times unknown.
// SEH3 adds a paint per record (its PaintRecord bytes), the sequence of the undo that took it
// back, and the fraction grids in each pre-image.
constexpr char kMagic[4] = {'S', 'E', 'H', '3'};
constexpr char kMagicV2[4] = {'S', 'E', 'H', '2'};
constexpr char kMagicV1[4] = {'S', 'E', 'H', '1'};

// The voxels a paint reads and may write: its tool's box, one voxel wider (the kernel's own
// box, materials.cc, pads by one) and one more for rounding.
VoxelBox PaintBox(const levelset::Sculpture& sculpture, const codec::Paint& paint) {
  const levelset::Aabb b = levelset::ToolBounds(paint.Tool());
  const double dx = sculpture.voxel_size();
  auto lo = [dx](double v) { return static_cast<int>(std::floor(v / dx)) - 2; };
  auto hi = [dx](double v) { return static_cast<int>(std::ceil(v / dx)) + 2; };
  return VoxelBox{{lo(b.min.x), lo(b.min.y), lo(b.min.z)}, {hi(b.max.x), hi(b.max.y), hi(b.max.z)}};
}

// The kernel's paint as an edit result: fractions only, no tracked scalar moves.
StatusOr<levelset::EditResult> PaintAsEdit(levelset::Sculpture& sculpture,
                                           const codec::Paint& paint) {
  SCULPT_ASSIGN_OR_RETURN(levelset::MaterialEditResult m, ApplyPaint(sculpture, paint));
  levelset::EditResult r;
  r.changed = m.changed_voxels > 0;
  r.dirty_leaves = std::move(m.dirty_leaves);
  r.changed_voxels = m.changed_voxels;
  r.volume_before = r.volume_after = sculpture.volume();
  r.reference_volume = sculpture.reference_volume();
  r.elapsed_ms = m.elapsed_ms;
  return r;
}

std::string PaintBytes(const codec::Paint& paint) {
  codec::PaintRecord rec;
  rec.paint = paint;
  return codec::EncodeLogRecord(rec);
}
static_assert(std::is_trivially_copyable_v<levelset::EditRequest>);
static_assert(std::is_trivially_copyable_v<levelset::EditSettings>);
static_assert(std::is_trivially_copyable_v<ReplayState>);

template <typename T>
void Put(std::string& s, const T& v) {
  s.append(reinterpret_cast<const char*>(&v), sizeof v);
}
void PutString(std::string& s, const std::string& v) {
  Put(s, static_cast<uint32_t>(v.size()));
  s.append(v);
}
template <typename T>
bool Get(std::string_view& s, T* v) {
  if (s.size() < sizeof(T)) return false;
  std::memcpy(v, s.data(), sizeof(T));
  s.remove_prefix(sizeof(T));
  return true;
}
bool GetString(std::string_view& s, std::string* v) {
  uint32_t n = 0;
  if (!Get(s, &n) || s.size() < n) return false;
  v->assign(s.data(), n);
  s.remove_prefix(n);
  return true;
}

void PutSweep(std::string& s, const levelset::SweepRequest& r) {
  Put(s, static_cast<uint8_t>(r.mode));
  Put(s, static_cast<uint8_t>(r.add));
  Put(s, r.plane);
  Put(s, r.depth);
  Put(s, r.axis_point);
  Put(s, r.axis_dir);
  Put(s, static_cast<uint32_t>(r.outline.size()));
  for (const levelset::PlanePoint& p : r.outline) Put(s, p);
}
bool GetSweep(std::string_view& s, levelset::SweepRequest* r) {
  uint8_t mode = 0, add = 0;
  uint32_t n = 0;
  if (!Get(s, &mode) || !Get(s, &add) || !Get(s, &r->plane) || !Get(s, &r->depth) ||
      !Get(s, &r->axis_point) || !Get(s, &r->axis_dir) || !Get(s, &n) ||
      n > s.size() / sizeof(levelset::PlanePoint) || mode > 1) {
    return false;
  }
  r->mode = static_cast<levelset::SweepRequest::Mode>(mode);
  r->add = add != 0;
  r->outline.resize(n);
  for (levelset::PlanePoint& p : r->outline) Get(s, &p);
  return true;
}

}  // namespace

// The leaf cells whose contents in the order being rebuilt may differ from what the sculpture
// held before the call (the affected region), with their bounding box for a quick reject.
class EditHistory::CellSet {
 public:
  bool Contains(const Int3& c) const { return keys_.count(Key(c)) != 0; }
  void Insert(const Int3& c) {
    if (!keys_.insert(Key(c)).second) return;
    cells_.push_back(c);
    if (box_.Empty()) {
      box_ = {c, {c.x + 7, c.y + 7, c.z + 7}};
    } else {
      box_.min = {std::min(box_.min.x, c.x), std::min(box_.min.y, c.y), std::min(box_.min.z, c.z)};
      box_.max = {std::max(box_.max.x, c.x + 7), std::max(box_.max.y, c.y + 7),
                  std::max(box_.max.z, c.z + 7)};
    }
  }
  void Insert(const std::vector<Int3>& cells) {
    for (const Int3& c : cells) Insert(c);
  }
  const VoxelBox& box() const { return box_; }
  std::vector<Int3> Sorted() const {
    std::vector<Int3> out = cells_;
    std::sort(out.begin(), out.end(), CellLess);
    return out;
  }

 private:
  std::unordered_set<uint64_t> keys_;
  std::vector<Int3> cells_;
  VoxelBox box_;
};

Status ValidateEditHistoryOptions(const EditHistoryOptions& o) {
  SCULPT_RETURN_IF_ERROR(CheckRange("depth_per_author", o.depth_per_author, 1, 4096));
  SCULPT_RETURN_IF_ERROR(CheckRange("max_edits", o.max_edits, 1, 1000000));
  SCULPT_RETURN_IF_ERROR(CheckRange("max_bytes", static_cast<double>(o.max_bytes),
                                    static_cast<double>(1 << 20), 64.0 * (1ull << 30)));
  return Status::Ok();
}

EditHistory::EditHistory(EditHistoryOptions options) : options_(options) {}

PreparedEdit EditHistory::Prepare(const levelset::Sculpture& sculpture,
                                  const std::vector<levelset::EditRequest>& requests,
                                  const levelset::EditSettings& settings) const {
  PreparedEdit p;
  p.requests = requests;
  p.settings = settings;
  p.before = levelset::CaptureReplayState(sculpture);
  if (requests.empty()) {
    p.not_undoable = "an empty batch";
    return p;
  }
  const levelset::EditFootprint f = levelset::FootprintOf(sculpture, requests, settings);
  if (f.whole_object) {
    p.not_undoable = "compensation=global reads and writes the whole object";
    return p;
  }
  p.footprint = VoxelBox{f.min, f.max};
  p.image = CellImage::Capture(sculpture, p.footprint);
  return p;
}

PreparedEdit EditHistory::PrepareSweep(const levelset::Sculpture& sculpture,
                                       const levelset::SweepRequest& request) const {
  PreparedEdit p;
  p.sweep = request;
  p.before = levelset::CaptureReplayState(sculpture);
  const levelset::EditFootprint f = levelset::SweepFootprintOf(sculpture, request);
  p.footprint = VoxelBox{f.min, f.max};
  p.image = CellImage::Capture(sculpture, p.footprint);
  return p;
}

StatusOr<levelset::EditResult> EditHistory::ApplySweep(levelset::Sculpture& sculpture, uint64_t seq,
                                                       const std::string& author,
                                                       const levelset::SweepRequest& request,
                                                       uint64_t wall_ms) {
  SCULPT_RETURN_IF_ERROR(levelset::ValidateSweep(sculpture, request));
  PreparedEdit p = PrepareSweep(sculpture, request);
  p.wall_ms = wall_ms;
  StatusOr<levelset::EditResult> res = levelset::ApplySweep(sculpture, request);
  if (res.ok()) Commit(std::move(p), seq, author, *res, sculpture);
  return res;
}

PreparedEdit EditHistory::PreparePaint(const levelset::Sculpture& sculpture,
                                       const codec::Paint& paint) const {
  PreparedEdit p;
  p.paint = paint;
  p.before = levelset::CaptureReplayState(sculpture);
  p.footprint = PaintBox(sculpture, paint);
  p.image = CellImage::Capture(sculpture, p.footprint);
  return p;
}

StatusOr<levelset::EditResult> EditHistory::ApplyPaint(levelset::Sculpture& sculpture, uint64_t seq,
                                                       const std::string& author,
                                                       const codec::Paint& paint,
                                                       uint64_t wall_ms) {
  // The kernel checks the paint before it writes anything: a refusal records nothing.
  PreparedEdit p = PreparePaint(sculpture, paint);
  p.wall_ms = wall_ms;
  StatusOr<levelset::EditResult> res = PaintAsEdit(sculpture, paint);
  if (res.ok()) Commit(std::move(p), seq, author, *res, sculpture);
  return res;
}

void EditHistory::Commit(PreparedEdit prepared, uint64_t seq, const std::string& author,
                         const levelset::EditResult& result,
                         const levelset::Sculpture& sculpture) {
  if (!prepared.not_undoable.empty()) {
    Clear("edit " + std::to_string(seq) + " cannot be undone: " + prepared.not_undoable);
    return;
  }
  Record r;
  r.seq = seq;
  r.wall_ms = prepared.wall_ms;
  r.author = author;
  r.requests = std::move(prepared.requests);
  r.sweep = std::move(prepared.sweep);
  r.paint = std::move(prepared.paint);
  r.settings = prepared.settings;
  r.footprint = prepared.footprint;
  r.before = prepared.before;
  r.after = levelset::CaptureReplayState(sculpture);
  r.volume_change = result.volume_change;
  r.island_volume_removed = result.island_volume_removed;
  r.reinitialised = result.reinit_passes > 0;
  r.image = std::move(prepared.image);
  r.image.Keep(result.dirty_leaves);  // what it wrote: the kernel writes only changed leaves
  const uint64_t id = first_id_ + records_.size();
  bytes_ += RecordBytes(r);
  records_.push_back(std::move(r));

  AuthorStacks& a = authors_[author];
  // A new stroke ends the author's redo chain: those edits stay out of the order for good.
  for (uint64_t rid : a.redo) {
    Record& dead = At(rid);
    dead.stack = Stack::kNone;
    bytes_ -= RecordBytes(dead);
    dead.image.Clear();
    bytes_ += RecordBytes(dead);
  }
  a.redo.clear();
  a.undo.push_back(id);
  if (a.undo.size() > static_cast<size_t>(options_.depth_per_author)) {
    At(a.undo.front()).stack = Stack::kNone;
    a.undo.erase(a.undo.begin());
    ++a.fell_off;
  }
  Trim();
}

StatusOr<levelset::EditResult> EditHistory::Apply(
    levelset::Sculpture& sculpture, uint64_t seq, const std::string& author,
    const std::vector<levelset::EditRequest>& requests,
    const levelset::ValidEditSettings& settings, uint64_t wall_ms) {
  PreparedEdit p = Prepare(sculpture, requests, settings);
  p.wall_ms = wall_ms;
  StatusOr<levelset::EditResult> res = levelset::ApplyEdits(sculpture, requests, settings);
  if (res.ok()) Commit(std::move(p), seq, author, *res, sculpture);
  return res;
}

std::string EditHistory::Serialize() const {
  std::string out(kMagic, 4);
  Put(out, static_cast<uint32_t>(sizeof(levelset::EditRequest)));
  Put(out, static_cast<uint32_t>(sizeof(levelset::EditSettings)));
  Put(out, first_id_);
  PutString(out, cleared_);
  Put(out, static_cast<uint32_t>(records_.size()));
  for (const Record& r : records_) {
    Put(out, r.seq);
    Put(out, r.wall_ms);
    PutString(out, r.author);
    Put(out, static_cast<uint8_t>(r.sweep.has_value()));
    if (r.sweep) PutSweep(out, *r.sweep);
    Put(out, static_cast<uint8_t>(r.paint.has_value()));
    if (r.paint) PutString(out, PaintBytes(*r.paint));
    Put(out, r.undone_at);
    Put(out, static_cast<uint32_t>(r.requests.size()));
    for (const levelset::EditRequest& q : r.requests) Put(out, q);
    Put(out, r.settings);
    const int32_t box[6] = {r.footprint.min.x, r.footprint.min.y, r.footprint.min.z,
                            r.footprint.max.x, r.footprint.max.y, r.footprint.max.z};
    Put(out, box);
    Put(out, r.before);
    Put(out, r.after);
    Put(out, r.volume_change);
    Put(out, r.island_volume_removed);
    const uint8_t flags[3] = {static_cast<uint8_t>(r.reinitialised),
                              static_cast<uint8_t>(r.active), static_cast<uint8_t>(r.stack)};
    Put(out, flags);
    r.image.AppendTo(out);
  }
  // Authors in name order, so equal histories serialize equally.
  std::map<std::string, const AuthorStacks*> sorted;
  for (const auto& [name, a] : authors_) sorted[name] = &a;
  Put(out, static_cast<uint32_t>(sorted.size()));
  for (const auto& [name, a] : sorted) {
    PutString(out, name);
    Put(out, a->fell_off);
    for (const std::vector<uint64_t>* ids : {&a->undo, &a->redo}) {
      Put(out, static_cast<uint32_t>(ids->size()));
      for (uint64_t id : *ids) Put(out, id);
    }
  }
  return out;
}

StatusOr<EditHistory> EditHistory::Parse(std::string_view in, EditHistoryOptions options) {
  SCULPT_RETURN_IF_ERROR(ValidateEditHistoryOptions(options));
  EditHistory h(options);
  uint32_t req_size = 0, set_size = 0, n = 0;
  if (in.size() < 4 ||
      (std::memcmp(in.data(), kMagic, 4) != 0 && std::memcmp(in.data(), kMagicV2, 4) != 0 &&
       std::memcmp(in.data(), kMagicV1, 4) != 0)) {
    return DataLoss("edit history: magic outside {SEH1, SEH2, SEH3}");
  }
  const bool v3 = std::memcmp(in.data(), kMagic, 4) == 0;
  const bool has_times = v3 || std::memcmp(in.data(), kMagicV2, 4) == 0;
  in.remove_prefix(4);
  if (!Get(in, &req_size) || !Get(in, &set_size) || !Get(in, &h.first_id_) ||
      !GetString(in, &h.cleared_) || !Get(in, &n)) {
    return DataLoss("edit history: header truncated");
  }
  if (req_size != sizeof(levelset::EditRequest) || set_size != sizeof(levelset::EditSettings)) {
    return DataLoss("edit history: struct sizes " + std::to_string(req_size) + "/" +
                    std::to_string(set_size) + " outside {" +
                    std::to_string(sizeof(levelset::EditRequest)) + "/" +
                    std::to_string(sizeof(levelset::EditSettings)) + "} (another build wrote it)");
  }
  for (uint32_t i = 0; i < n; ++i) {
    const std::string where = "edit history: record " + std::to_string(i);
    Record r;
    uint32_t nreq = 0;
    uint8_t has_sweep = 0;
    if (!Get(in, &r.seq) || (has_times && !Get(in, &r.wall_ms)) || !GetString(in, &r.author) ||
        !Get(in, &has_sweep)) {
      return DataLoss(where + " truncated");
    }
    if (has_sweep) {
      r.sweep.emplace();
      if (!GetSweep(in, &*r.sweep)) return DataLoss(where + ": sweep truncated");
    }
    uint8_t has_paint = 0;
    if (v3) {
      std::string bytes;
      if (!Get(in, &has_paint)) return DataLoss(where + " truncated");
      if (has_paint) {
        if (!GetString(in, &bytes)) return DataLoss(where + ": paint truncated");
        auto rec = codec::DecodeLogRecord(0, bytes);
        const auto* paint = rec.ok() ? std::get_if<codec::PaintRecord>(&*rec) : nullptr;
        if (!paint) return DataLoss(where + ": paint does not parse");
        r.paint = paint->paint;
      }
      if (!Get(in, &r.undone_at)) return DataLoss(where + " truncated");
    }
    if (!Get(in, &nreq)) return DataLoss(where + " truncated");
    const bool no_requests = has_sweep || has_paint;
    if ((has_sweep && has_paint) || (no_requests && nreq != 0) ||
        (!no_requests && (nreq == 0 || nreq > levelset::kMaxEditsPerBatch))) {
      return Outside(where + ": requests", std::to_string(nreq),
                     std::string("{0} (a sweep or a paint) or [1, ") +
                         std::to_string(levelset::kMaxEditsPerBatch) + "]",
                     Status::Code::kDataLoss);
    }
    r.requests.resize(nreq);
    int32_t box[6];
    uint8_t flags[3];
    bool ok = true;
    for (levelset::EditRequest& q : r.requests) ok = ok && Get(in, &q);
    ok = ok && Get(in, &r.settings) && Get(in, &box) && Get(in, &r.before) && Get(in, &r.after) &&
         Get(in, &r.volume_change) && Get(in, &r.island_volume_removed) && Get(in, &flags);
    if (!ok) return DataLoss(where + " truncated");
    if (flags[2] > static_cast<uint8_t>(Stack::kRedo)) {
      return Outside(where + ": stack", std::to_string(flags[2]), "[0, 2]",
                     Status::Code::kDataLoss);
    }
    r.footprint = VoxelBox{{box[0], box[1], box[2]}, {box[3], box[4], box[5]}};
    r.reinitialised = flags[0] != 0;
    r.active = flags[1] != 0;
    r.stack = static_cast<Stack>(flags[2]);
    StatusOr<CellImage> img = CellImage::ReadFrom(in, /*with_fractions=*/v3);
    if (!img.ok()) return DataLoss(where + ": " + img.status().message());
    r.image = std::move(img).value();
    h.bytes_ += RecordBytes(r);
    h.records_.push_back(std::move(r));
  }
  uint32_t nauthors = 0;
  if (!Get(in, &nauthors)) return DataLoss("edit history: authors truncated");
  const uint64_t end_id = h.first_id_ + h.records_.size();
  for (uint32_t i = 0; i < nauthors; ++i) {
    std::string name;
    AuthorStacks a;
    if (!GetString(in, &name) || !Get(in, &a.fell_off)) {
      return DataLoss("edit history: author " + std::to_string(i) + " truncated");
    }
    for (std::vector<uint64_t>* ids : {&a.undo, &a.redo}) {
      uint32_t k = 0;
      if (!Get(in, &k) || k > in.size() / 8) {
        return DataLoss("edit history: stacks of author " + Quoted(name) + " truncated");
      }
      ids->resize(k);
      for (uint64_t& id : *ids) {
        Get(in, &id);
        if (id < h.first_id_ || id >= end_id || h.records_[id - h.first_id_].author != name) {
          return Outside(std::string("edit history: author ") + Quoted(name) + " stack id",
                         std::to_string(id),
                         std::string("its records in [") + std::to_string(h.first_id_) + ", " +
                             std::to_string(end_id) + ")",
                         Status::Code::kDataLoss);
        }
      }
    }
    h.authors_[name] = std::move(a);
  }
  if (!in.empty()) {
    return DataLoss("edit history: " + std::to_string(in.size()) + " bytes after the end");
  }
  h.Trim();
  return h;
}

void EditHistory::Clear(const std::string& why) {
  records_.clear();
  first_id_ = 0;
  bytes_ = 0;
  authors_.clear();
  cleared_ = why;
}

uint64_t EditHistory::RecordBytes(const Record& r) {
  return sizeof(Record) + r.author.capacity() +
         r.requests.capacity() * sizeof(levelset::EditRequest) + r.image.MemoryBytes() +
         (r.paint ? sizeof(codec::Paint) + r.paint->object.capacity() +
                        r.paint->fractions.capacity() * sizeof(double)
                  : 0);
}

void EditHistory::DropFront() {
  Record& r = records_.front();
  const uint64_t id = first_id_;
  if (r.stack != Stack::kNone) {
    AuthorStacks& a = authors_[r.author];
    auto& stack = r.stack == Stack::kUndo ? a.undo : a.redo;
    stack.erase(std::remove(stack.begin(), stack.end(), id), stack.end());
    ++a.fell_off;
  }
  bytes_ -= RecordBytes(r);
  records_.pop_front();
  ++first_id_;
}

void EditHistory::Trim() {
  // Edits before the oldest one anybody can still undo or redo are never replayed again.
  while (!records_.empty() && records_.front().stack == Stack::kNone) DropFront();
  while (records_.size() > static_cast<size_t>(options_.max_edits) ||
         (bytes_ > options_.max_bytes && records_.size() > 1)) {
    DropFront();
    while (!records_.empty() && records_.front().stack == Stack::kNone) DropFront();
  }
}

size_t EditHistory::undo_depth(const std::string& author) const {
  auto it = authors_.find(author);
  return it == authors_.end() ? 0 : it->second.undo.size();
}

size_t EditHistory::redo_depth(const std::string& author) const {
  auto it = authors_.find(author);
  return it == authors_.end() ? 0 : it->second.redo.size();
}

std::vector<HistoryEntry> EditHistory::Entries(const std::string& author) const {
  std::vector<HistoryEntry> out;
  for (const Record& r : records_) {
    if (!author.empty() && r.author != author) continue;
    HistoryEntry e;
    e.seq = r.seq;
    e.author = r.author;
    if (r.sweep) {
      e.sweep = true;
      e.kind = r.sweep->add ? levelset::EditKind::kAdd : levelset::EditKind::kSubtract;
      e.kind_name = r.sweep->add ? "sweep-add" : "sweep-subtract";
    } else if (r.paint) {
      e.paint = true;
      e.kind_name = r.paint->fractions.empty() ? "paint" : "fill";
    } else {
      e.kind = r.requests.front().kind;
      e.kind_name = levelset::EditKindName(e.kind);
    }
    e.poses = static_cast<uint32_t>(r.requests.size());
    e.undone = !r.active;
    e.undoable = r.stack == Stack::kUndo;
    e.wall_ms = r.wall_ms;
    out.push_back(e);
  }
  return out;
}

StatusOr<uint64_t> EditHistory::UndoTarget(const std::string& author) const {
  auto it = authors_.find(author);
  if (it == authors_.end() || it->second.undo.empty()) {
    const uint64_t fell = it == authors_.end() ? 0 : it->second.fell_off;
    if (fell > 0) {
      const std::string depth = std::to_string(options_.depth_per_author);
      return FieldViolation(
          Status::Code::kOutOfRange, "author", Quoted(author),
          "authors with an edit within depth_per_author=" + depth,
          "undo: author=" + Quoted(author) + " has no edit left within depth_per_author=" + depth +
              " (" + std::to_string(fell) +
              " older edits fell off the history, which keeps the last " + depth + " per author, " +
              std::to_string(options_.max_edits) + " edits and " +
              std::to_string(options_.max_bytes >> 20) + " MiB in all)");
    }
    return FieldViolation(Status::Code::kFailedPrecondition, "author", Quoted(author),
                          "authors with an edit to undo",
                          "undo: author=" + Quoted(author) + " has nothing to undo" +
                              (cleared_.empty() ? "" : " (history cleared: " + cleared_ + ")"));
  }
  return records_[it->second.undo.back() - first_id_].seq;
}

StatusOr<uint64_t> EditHistory::RedoTarget(const std::string& author) const {
  auto it = authors_.find(author);
  if (it == authors_.end() || it->second.redo.empty()) {
    return FieldViolation(
        Status::Code::kFailedPrecondition, "author", Quoted(author),
        "authors with an undone edit to redo",
        "redo: author=" + Quoted(author) + " has nothing to redo (no undo since its last edit)");
  }
  return records_[it->second.redo.back() - first_id_].seq;
}

uint64_t EditHistory::RedoUndoneAt(const std::string& author) const {
  auto it = authors_.find(author);
  if (it == authors_.end() || it->second.redo.empty()) return 0;
  return records_[it->second.redo.back() - first_id_].undone_at;
}

StatusOr<UndoOutcome> EditHistory::Undo(levelset::Sculpture& sculpture, const std::string& author,
                                        uint64_t at_seq) {
  SCULPT_RETURN_IF_ERROR(UndoTarget(author).status());
  const uint64_t id = authors_[author].undo.back();
  SCULPT_ASSIGN_OR_RETURN(UndoOutcome out, Rebuild(sculpture, id, /*activate=*/false));
  // `it` may not survive Rebuild's bookkeeping of other authors: look the author up again.
  AuthorStacks& a = authors_[author];
  a.undo.pop_back();
  a.redo.push_back(id);
  At(id).stack = Stack::kRedo;
  At(id).undone_at = at_seq;
  return out;
}

StatusOr<UndoOutcome> EditHistory::Redo(levelset::Sculpture& sculpture,
                                        const std::string& author) {
  SCULPT_RETURN_IF_ERROR(RedoTarget(author).status());
  const uint64_t id = authors_[author].redo.back();
  SCULPT_ASSIGN_OR_RETURN(UndoOutcome out, Rebuild(sculpture, id, /*activate=*/true));
  AuthorStacks& a = authors_[author];
  a.redo.pop_back();
  a.undo.push_back(id);
  At(id).stack = Stack::kUndo;
  return out;
}

bool EditHistory::NeedsReplay(const Record& r, const ReplayState& state,
                              const CellSet& region) const {
  if (!r.sweep && !r.paint && ReadsVolume(r.requests.front(), r.settings) &&
      !(SameBits(state.volume, r.before.volume) &&
        SameBits(state.reference_volume, r.before.reference_volume))) {
    return true;
  }
  if (!r.paint && r.settings.reinit_every_k > 0 &&
      state.edits_since_reinit != r.before.edits_since_reinit) {
    return true;
  }
  if (!region.box().Intersects(r.footprint)) return false;
  for (const Int3& c : levelset::AllLeafCells(r.footprint)) {
    if (region.Contains(c)) return true;
  }
  return false;
}

ReplayState EditHistory::Transfer(const Record& r, const ReplayState& state) {
  // An edit not replayed wrote the same voxels as before; only the scalars it leaves behind move
  // with the state it starts from, by the kernel's own arithmetic (edit.cc): the volume grows by
  // the change of its block, the reference follows the volume for edits that add or remove
  // material on purpose and drops by removed islands otherwise (a compensated edit reads both
  // and is replayed unless they are unchanged, in which case its old result stands).
  if (SameBits(state.volume, r.before.volume) &&
      SameBits(state.reference_volume, r.before.reference_volume) &&
      state.edits_since_reinit == r.before.edits_since_reinit) {
    return r.after;
  }
  if (r.paint) return state;  // a paint moves no tracked scalar
  ReplayState out;
  out.volume = state.volume + r.volume_change;
  if (r.sweep) {
    // ApplySweep: volume += change; reference += change; the counter is not touched.
    out.reference_volume = state.reference_volume + r.volume_change;
    out.edits_since_reinit = state.edits_since_reinit;
    return out;
  }
  switch (r.requests.front().kind) {
    case levelset::EditKind::kAdd:
    case levelset::EditKind::kSubtract:
    case levelset::EditKind::kInflate:
    case levelset::EditKind::kDeflate:
      out.reference_volume = state.reference_volume + (out.volume - state.volume);
      break;
    case levelset::EditKind::kPress:
    case levelset::EditKind::kSmooth:
      out.reference_volume = state.reference_volume - r.island_volume_removed;
      break;
  }
  if (r.reinitialised) {
    out.edits_since_reinit = 0;
  } else {
    out.edits_since_reinit =
        state.edits_since_reinit + (r.after.edits_since_reinit - r.before.edits_since_reinit);
  }
  return out;
}

Status EditHistory::ReplayOne(levelset::Sculpture& sculpture, size_t index, bool rewind_self,
                              ReplayState& state, CellSet& region, UndoOutcome& out) {
  Record& r = records_[index];
  // The cells it reads that are not in the region hold what the old order left at its end; set
  // them to what they held at this edit's place: the pre-image of the first later writer (still
  // in the order) of each, or the current contents when none wrote it since. They join the region.
  std::vector<Int3> need;
  for (const Int3& c : levelset::AllLeafCells(r.footprint)) {
    if (!region.Contains(c)) need.push_back(c);
  }
  std::vector<Int3> take;
  for (size_t m = rewind_self ? index : index + 1; m < records_.size() && !need.empty(); ++m) {
    const Record& w = records_[m];
    if (!w.active || w.image.cell_count() == 0) continue;
    take.clear();
    auto keep = need.begin();
    for (const Int3& c : need) {
      if (w.image.Holds(c)) {
        take.push_back(c);
      } else {
        *keep++ = c;
      }
    }
    need.erase(keep, need.end());
    if (take.empty()) continue;
    w.image.Restore(sculpture, take);
    region.Insert(take);
  }

  bytes_ -= RecordBytes(r);
  r.image = CellImage::Capture(sculpture, r.footprint);
  r.before = state;
  StatusOr<levelset::EditResult> res = Status(Status::Code::kInternal, "unset");
  if (r.sweep) {
    levelset::RestoreReplayState(sculpture, state);
    res = levelset::ApplySweep(sculpture, *r.sweep);
  } else if (r.paint) {
    levelset::RestoreReplayState(sculpture, state);
    res = PaintAsEdit(sculpture, *r.paint);
  } else {
    res = levelset::ReplayEdits(sculpture, r.requests, r.settings, state);
  }
  if (!res.ok()) {
    bytes_ += RecordBytes(r);
    return Internal("undo: replaying edit " + std::to_string(r.seq) + " failed: " +
                    res.status().ToString());
  }
  r.image.Keep(res->dirty_leaves);
  bytes_ += RecordBytes(r);
  region.Insert(res->dirty_leaves);
  r.after = levelset::CaptureReplayState(sculpture);
  r.volume_change = res->volume_change;
  r.island_volume_removed = res->island_volume_removed;
  r.reinitialised = res->reinit_passes > 0;
  state = r.after;
  return Status::Ok();
}

StatusOr<UndoOutcome> EditHistory::Rebuild(levelset::Sculpture& sculpture, uint64_t id,
                                           bool activate) {
  const auto t0 = std::chrono::steady_clock::now();
  const size_t t = id - first_id_;
  Record& target = records_[t];
  UndoOutcome out;
  out.seq = target.seq;
  out.author = target.author;
  CellSet region;
  ReplayState state = target.before;
  if (activate) {
    // Put back at its place: its cells are rewound from the later writers' pre-images (its own
    // image is stale, taken in an order it has since left), then it runs again.
    SCULPT_RETURN_IF_ERROR(ReplayOne(sculpture, t, /*rewind_self=*/false, state, region, out));
    target.active = true;
  } else {
    // The leaves it wrote go back to what they held before it.
    target.image.RestoreAll(sculpture);
    region.Insert(target.image.Cells());
    target.active = false;
  }
  for (size_t k = t + 1; k < records_.size(); ++k) {
    Record& r = records_[k];
    if (!r.active) {
      r.before = state;  // where it would start if redone
      continue;
    }
    if (NeedsReplay(r, state, region)) {
      SCULPT_RETURN_IF_ERROR(ReplayOne(sculpture, k, /*rewind_self=*/true, state, region, out));
      ++out.replayed;
      ++out.replayed_by[r.author];
    } else {
      const ReplayState after = Transfer(r, state);
      r.before = state;
      r.after = after;
      state = after;
    }
  }
  levelset::RestoreReplayState(sculpture, state);
  out.state = state;
  out.dirty_leaves = region.Sorted();
  out.elapsed_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace sculpt::server
