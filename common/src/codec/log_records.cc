/// @brief The edit log's records and skin files: domain types to and from their protobuf storage.
#include "sculpt/codec/log_records.h"

#include <string>
#include <utility>

#include "sculpt/codec/stroke.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::codec {
namespace {

template <typename Message>
std::string Tagged(LogTag tag, const Message& m) {
  std::string out(1, static_cast<char>(tag));
  m.AppendToString(&out);
  return out;
}

Status DoesNotParse(uint64_t seq, const char* what) {
  return DataLoss("edit log record " + std::to_string(seq) + " (" + what + ") does not parse");
}

template <typename Message>
bool ParseTagged(std::string_view payload, Message* m) {
  return m->ParseFromArray(payload.data() + 1, static_cast<int>(payload.size() - 1));
}

// The kernel request a sweep record describes; InvalidArgument for a malformed record.
Status SweepFromRecord(const v1::SkinSweepRecord& r, levelset::SweepRequest* q) {
  if (r.plane_size() != 9) {
    return Outside("SkinSweepRecord.plane.size", std::to_string(r.plane_size()), "{9}");
  }
  if (r.outline_size() % 2 != 0) {
    return Outside("SkinSweepRecord.outline.size", std::to_string(r.outline_size()),
                   "even numbers");
  }
  auto p = [&r](int i) { return Vec3{r.plane(i), r.plane(i + 1), r.plane(i + 2)}; };
  q->plane = {p(0), p(3), p(6)};
  q->add = r.kind() == v1::EDIT_KIND_ADD;
  q->mode = r.mode() == v1::SKIN_SWEEP_MODE_REVOLVE ? levelset::SweepRequest::Mode::kRevolve
                                                    : levelset::SweepRequest::Mode::kExtrude;
  q->depth = r.depth();
  if (q->mode == levelset::SweepRequest::Mode::kRevolve) {
    if (r.axis_size() != 4) {
      return Outside("SkinSweepRecord.axis.size", std::to_string(r.axis_size()), "{4}");
    }
    q->axis_point = {r.axis(0), r.axis(1)};
    q->axis_dir = {r.axis(2), r.axis(3)};
  }
  q->outline.reserve(r.outline_size() / 2);
  for (int i = 0; i + 1 < r.outline_size(); i += 2) {
    q->outline.push_back({r.outline(i), r.outline(i + 1)});
  }
  return Status::Ok();
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Encoding

std::string EncodeLogRecord(const StrokePoseRecord& p) {
  v1::EditRecord r = RecordFromEdit(p.edit);
  r.set_global_seq(p.global_seq);
  r.set_client_id(p.client_id);
  r.set_client_seq(p.client_seq);
  r.set_pose_index(p.pose_index);
  r.set_object(p.object);
  r.set_pose_count(p.pose_count);
  r.set_commit_ms(p.commit_ms);
  return r.SerializeAsString();
}

std::string EncodeLogRecord(const PaintRecord& p) {
  v1::PaintRecord r;
  r.set_global_seq(p.global_seq);
  r.set_client_id(p.client_id);
  *r.mutable_edit() = EncodePaintEdit(p.paint);
  return Tagged(LogTag::kPaint, r);
}

std::string EncodeLogRecord(const SweepRecord& s) {
  const levelset::SweepRequest& q = s.request;
  const bool revolve = q.mode == levelset::SweepRequest::Mode::kRevolve;
  v1::SkinSweepRecord r;
  r.set_global_seq(s.global_seq);
  r.set_client_id(s.client_id);
  r.set_client_seq(s.client_seq);
  r.set_object(s.object);
  r.set_mode(revolve ? v1::SKIN_SWEEP_MODE_REVOLVE : v1::SKIN_SWEEP_MODE_EXTRUDE);
  r.set_kind(q.add ? v1::EDIT_KIND_ADD : v1::EDIT_KIND_SUBTRACT);
  r.set_depth(q.depth);
  for (const Vec3& v : {q.plane.origin, q.plane.u, q.plane.v}) {
    r.add_plane(v.x);
    r.add_plane(v.y);
    r.add_plane(v.z);
  }
  for (const levelset::PlanePoint& p : q.outline) {
    r.add_outline(p.x);
    r.add_outline(p.y);
  }
  if (revolve) {
    for (double v : {q.axis_point.x, q.axis_point.y, q.axis_dir.x, q.axis_dir.y}) r.add_axis(v);
  }
  return Tagged(LogTag::kSweep, r);
}

std::string EncodeLogRecord(const ModelRecord& m) {
  v1::ModelRecord r;
  r.set_global_seq(m.global_seq);
  r.set_client_id(m.client_id);
  *r.mutable_intent() = EncodeModelIntent(m.edit);
  r.set_model_version(m.model_version);
  return Tagged(LogTag::kModel, r);
}

std::string EncodeLogRecord(const BallEditRecord& b) {
  v1::SkinEditRecord r;
  r.set_global_seq(b.global_seq);
  r.set_client_id(b.client_id);
  *r.mutable_edit() = EncodeSkinBallEdit(b.edit);
  r.set_skin_version(b.skin_version);
  return Tagged(LogTag::kSkinEdit, r);
}

std::string EncodeLogRecord(const UndoRecord& u) {
  v1::UndoRecord r;
  r.set_global_seq(u.global_seq);
  r.set_client_id(u.client_id);
  v1::UndoRequest* q = r.mutable_request();
  q->set_client_seq(u.client_seq);
  q->set_object(u.object);
  q->set_redo(u.redo);
  r.set_author(u.author);
  r.set_target_book(u.target_book);
  r.set_target_seq(u.target_seq);
  return Tagged(LogTag::kUndo, r);
}

void AppendRecordUser(std::string* payload, std::string_view user) {
  if (user.empty()) return;
  // Every record message declares `string user = 100`; the field is added to the stroke pose's
  // EditRecord (no tag byte) and to a tagged record's message alike.
  v1::EditRecord field;
  field.set_user(std::string(user));
  payload->append(field.SerializeAsString());
}

void AppendRecordEpoch(std::string* payload, uint64_t epoch) {
  if (epoch == 0) return;
  // Every record message declares `uint64 epoch = 16`: the same bytes serve every kind.
  v1::EditRecord field;
  field.set_epoch(epoch);
  payload->append(field.SerializeAsString());
}

// ---------------------------------------------------------------------------------------------
// Decoding

StatusOr<EditLogRecord> DecodeLogRecord(uint64_t seq, std::string_view payload) {
  const char tag = payload.empty() ? '\x08' : payload[0];
  switch (static_cast<LogTag>(tag)) {
    case LogTag::kSweep: {
      v1::SkinSweepRecord r;
      if (!ParseTagged(payload, &r)) return DoesNotParse(seq, "a sweep");
      SweepRecord s;
      s.global_seq = r.global_seq();
      s.client_id = r.client_id();
      s.client_seq = r.client_seq();
      s.object = r.object();
      s.request_status = SweepFromRecord(r, &s.request);
      s.user = r.user();
      s.epoch = r.epoch();
      return EditLogRecord(std::move(s));
    }
    case LogTag::kPaint: {
      v1::PaintRecord r;
      if (!ParseTagged(payload, &r)) return DoesNotParse(seq, "a paint");
      PaintRecord p;
      p.global_seq = r.global_seq();
      p.client_id = r.client_id();
      p.paint = PaintFromRecord(r.edit());
      p.user = r.user();
      p.epoch = r.epoch();
      return EditLogRecord(std::move(p));
    }
    case LogTag::kModel: {
      v1::ModelRecord r;
      if (!ParseTagged(payload, &r)) return DoesNotParse(seq, "a model intent");
      ModelRecord m;
      m.global_seq = r.global_seq();
      m.client_id = r.client_id();
      m.edit = ModelEditFromRecord(r.intent());
      m.model_version = r.model_version();
      m.user = r.user();
      m.epoch = r.epoch();
      return EditLogRecord(std::move(m));
    }
    case LogTag::kSkinEdit: {
      v1::SkinEditRecord r;
      if (!ParseTagged(payload, &r)) return DoesNotParse(seq, "a ball edit");
      BallEditRecord b;
      b.global_seq = r.global_seq();
      b.client_id = r.client_id();
      // The record embeds the edit in its wire form: checked as the live server checked it.
      auto edit = DecodeSkinBallEdit(r.edit());
      if (edit.ok()) {
        b.edit = std::move(edit).value();
      } else {
        b.edit_status = edit.status();
        b.edit.skin = r.edit().skin();
        b.edit.client_seq = r.edit().client_seq();
      }
      b.skin_version = r.skin_version();
      b.user = r.user();
      b.epoch = r.epoch();
      return EditLogRecord(std::move(b));
    }
    case LogTag::kUndo: {
      v1::UndoRecord r;
      if (!ParseTagged(payload, &r)) return DoesNotParse(seq, "an undo");
      UndoRecord u;
      u.global_seq = r.global_seq();
      u.client_id = r.client_id();
      u.client_seq = r.request().client_seq();
      u.object = r.request().object();
      u.redo = r.request().redo();
      u.author = r.author();
      u.target_book = r.target_book();
      u.target_seq = r.target_seq();
      u.user = r.user();
      u.epoch = r.epoch();
      return EditLogRecord(std::move(u));
    }
  }
  v1::EditRecord r;
  if (!r.ParseFromArray(payload.data(), static_cast<int>(payload.size()))) {
    return DataLoss("edit log record " + std::to_string(seq) + " does not parse");
  }
  StrokePoseRecord p;
  p.global_seq = r.global_seq();
  p.client_id = r.client_id();
  p.client_seq = r.client_seq();
  p.object = r.object();
  p.pose_index = r.pose_index();
  p.pose_count = r.pose_count();
  p.commit_ms = r.commit_ms();
  p.user = r.user();
  p.epoch = r.epoch();
  p.edit = EditFromRecord(r);
  return EditLogRecord(std::move(p));
}

levelset::EditRequest AsLogged(const levelset::EditRequest& edit) {
  return EditFromRecord(RecordFromEdit(edit));
}

Paint AsLogged(const Paint& paint) { return PaintFromRecord(EncodePaintEdit(paint)); }

// ---------------------------------------------------------------------------------------------
// Skin files

std::string EncodeSavedSkin(const SavedSkin& s) {
  v1::SavedSkin saved;
  saved.set_seq(s.seq);
  saved.set_version(s.version);
  for (const SkinBall& o : s.balls) {
    v1::SkinBall* b = saved.add_balls();
    b->set_x(o.x);
    b->set_y(o.y);
    b->set_r(o.r);
    b->set_theta(o.theta);
  }
  for (const auto& [id, seq] : s.last_edit_seq) (*saved.mutable_last_edit_seq())[id] = seq;
  for (const auto& [id, seq] : s.last_sweep_seq) (*saved.mutable_last_sweep_seq())[id] = seq;
  return saved.SerializeAsString();
}

StatusOr<SavedSkin> DecodeSavedSkin(std::string_view bytes) {
  v1::SavedSkin saved;
  if (!saved.ParseFromArray(bytes.data(), static_cast<int>(bytes.size()))) {
    return DataLoss("skin file does not parse");
  }
  SavedSkin s;
  s.seq = saved.seq();
  s.version = saved.version();
  s.balls.reserve(saved.balls_size());
  for (const v1::SkinBall& b : saved.balls()) s.balls.push_back({b.x(), b.y(), b.r(), b.theta()});
  for (const auto& [id, seq] : saved.last_edit_seq()) s.last_edit_seq[id] = seq;
  for (const auto& [id, seq] : saved.last_sweep_seq()) s.last_sweep_seq[id] = seq;
  return s;
}

}  // namespace sculpt::codec
