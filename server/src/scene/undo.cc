/// @brief Per-author undo and redo on the commit pipeline (issue 15): the Undo op, and the
/// histories every stroke is recorded in (EditHistory, edit_history.h).
#include <spdlog/spdlog.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <future>
#include <iterator>

#include "net/wire_error.h"
#include "scene/answer_once.h"
#include "scene/edit_history.h"
#include "scene/scene.h"
#include "sculpt/codec/log_records.h"
#include "store/durable_file.h"
#include "store/resend_table.h"

namespace sculpt::server {
namespace {

constexpr size_t kMaxNameBytes = 64;

// A history file beside the snapshots: magic, the snapshot seq it belongs to, the payload size,
// CRC32C of the payload, then EditHistory::Serialize's bytes.
constexpr char kHistoryMagic[8] = {'S', 'C', 'L', 'P', 'H', 'I', 'S', 'T'};
constexpr size_t kHistoryHeader = 8 + 8 + 8 + 4;

std::string HistoryPath(const std::string& data_dir, const std::string& object) {
  return (std::filesystem::path(data_dir) / "history" / (object + ".bin")).string();
}

v1::UndoAck Refused(const Status& st, const v1::UndoRequest& r) {
  v1::UndoAck a;
  a.set_client_seq(r.client_seq());
  a.set_redo(r.redo());
  a.set_accepted(false);
  *a.mutable_error() = ToWireError(st, r.client_seq());
  return a;
}

}  // namespace

EditHistory& Scene::HistoryOf(const std::string& object) {
  std::unique_ptr<EditHistory>& h = histories_[object];
  if (!h) {
    EditHistoryOptions o;
    o.depth_per_author = static_cast<int>(config_.limits.undo_depth);
    h = std::make_unique<EditHistory>(o);
  }
  return *h;
}

void Scene::ClearHistories(const std::string& why) {
  for (auto& [object, h] : histories_) {
    if (h) h->Clear(why);
  }
}

// An undo or redo: Prepare checks there is something to take back (a refusal names why and
// changes nothing) and logs the request; Apply runs the history's undo or redo, which restores
// the region and replays the later strokes it reaches, exactly as recovery will (the history is
// rebuilt by recovery from the same records). Replicas get the changed leaves.
struct Scene::UndoOp final : EditOp {
  UndoOp(uint64_t client, v1::UndoRequest r, std::function<void(v1::UndoAck)> d)
      : client(client), request(std::move(r)), done(std::move(d)) {}
  const char* operation() const override { return request.redo() ? "redo" : "undo"; }
  ResendStream stream() const override { return ResendStream::kUndos; }
  uint64_t client_id() const override { return client; }
  uint64_t client_seq() const override { return request.client_seq(); }

  Status Prepare(Scene& scene, uint64_t first_seq, std::vector<std::string>* records) override {
    auto it = scene.sculptures_.find(request.object());
    if (it == scene.sculptures_.end()) {
      return NotFound("UndoRequest.object=" + request.object() + " outside the scene's objects");
    }
    EditHistory& h = scene.HistoryOf(request.object());
    const std::string author = HistoryAuthor(client);
    if (request.redo()) {
      if (h.redo_depth(author) == 0) {
        return FailedPrecondition("UndoRequest.redo=true outside requests with an undone stroke "
                                  "to redo on " + request.object() +
                                  " (none since this client's last undo, or a stroke came after "
                                  "it)");
      }
      SCULPT_RETURN_IF_ERROR(h.RedoTarget(author).status());
    } else {
      // The history says why not (nothing ever, fell off the depth, cleared by a sweep).
      SCULPT_RETURN_IF_ERROR(h.UndoTarget(author).status());
    }
    codec::UndoRecord rec;
    rec.global_seq = first_seq;
    rec.client_id = client;
    rec.client_seq = request.client_seq();
    rec.object = request.object();
    rec.redo = request.redo();
    rec.author = author;
    records->push_back(codec::EncodeLogRecord(rec));
    return Status::Ok();
  }

  Applied Apply(Scene& scene) override {
    Applied a;
    a.object = request.object();
    a.bounds_may_change = true;
    EditHistory& h = scene.HistoryOf(request.object());
    levelset::Sculpture& s = scene.sculptures_.at(request.object());
    const std::string author = HistoryAuthor(client);
    auto out = request.redo() ? h.Redo(s, author) : h.Undo(s, author);
    if (!out.ok()) {
      a.status = out.status();
      return a;
    }
    outcome = *out;
    a.dirty_leaves = out->dirty_leaves;
    depth = {h.undo_depth(author), h.redo_depth(author)};
    return a;
  }

  void Answer(const CommitOutcome& o) override {
    if (!o.status.ok()) {
      v1::UndoAck a = Refused(o.status, request);
      if (o.records > 0) a.set_global_seq(o.global_seq_first);
      return done(a);
    }
    v1::UndoAck a;
    a.set_client_seq(o.client_seq);
    a.set_redo(request.redo());
    a.set_accepted(true);
    a.set_duplicate(o.duplicate);
    if (!o.duplicate) {
      a.set_global_seq(o.global_seq_first);
      a.set_target_seq(outcome.seq);
      a.set_replayed(outcome.replayed);
      for (const auto& [author, n] : outcome.replayed_by) {
        v1::ReplayedEdits* r = a.add_replayed_by();
        r->set_author(author);
        r->set_edits(n);
      }
      a.set_undo_depth(static_cast<uint32_t>(depth.first));
      a.set_redo_depth(static_cast<uint32_t>(depth.second));
    }
    done(a);
  }

  uint64_t client;
  v1::UndoRequest request;
  std::function<void(v1::UndoAck)> done;
  UndoOutcome outcome;
  std::pair<size_t, size_t> depth;
};

void Scene::Undo(uint64_t client_id, v1::UndoRequest request,
                 std::function<void(v1::UndoAck)> done) {
  auto once = AnswerOnce(std::move(done));
  if (request.object().empty() || request.object().size() > kMaxNameBytes) {
    return once(Refused(InvalidArgument("UndoRequest.object=(" +
                                        std::to_string(request.object().size()) +
                                        " bytes) outside names of 1..64 bytes"),
                        request));
  }
  Commit(std::make_shared<UndoOp>(client_id, std::move(request), once));
}

bool Scene::SaveHistories(uint64_t seq) {
  bool saved_all = true;
  std::error_code ec;
  std::filesystem::create_directories(std::filesystem::path(config_.data_dir) / "history", ec);
  for (const auto& [object, sculpture] : sculptures_) {
    const std::string payload = HistoryOf(object).Serialize();
    std::string bytes(kHistoryMagic, sizeof(kHistoryMagic));
    const uint64_t size = payload.size();
    const uint32_t crc = store::Crc32c(payload);
    bytes.append(reinterpret_cast<const char*>(&seq), 8);
    bytes.append(reinterpret_cast<const char*>(&size), 8);
    bytes.append(reinterpret_cast<const char*>(&crc), 4);
    bytes += payload;
    if (const Status s = store::WriteFileDurably(HistoryPath(config_.data_dir, object), bytes);
        !s.ok()) {
      spdlog::error("undo history of {} at seq {} not saved: {}", object, seq, s.ToString());
      saved_all = false;
    }
  }
  return saved_all;
}

void Scene::LoadHistory(const std::string& object, uint64_t snapshot_seq) {
  EditHistory& h = HistoryOf(object);
  if (snapshot_seq == 0) return;  // built from the scene: nothing before it to undo
  const std::string path = HistoryPath(config_.data_dir, object);
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    h.Clear("no undo history was kept with the snapshot at seq " + std::to_string(snapshot_seq));
    return;
  }
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  auto refuse = [&](const std::string& why) {
    spdlog::warn("undo history {}: {}; strokes before seq {} can no longer be undone", path, why,
                 snapshot_seq);
    h.Clear("the undo history kept with the snapshot at seq " + std::to_string(snapshot_seq) +
            " was not usable");
  };
  if (bytes.size() < kHistoryHeader || std::memcmp(bytes.data(), kHistoryMagic, 8) != 0) {
    return refuse("not a history file");
  }
  uint64_t seq = 0, size = 0;
  uint32_t crc = 0;
  std::memcpy(&seq, bytes.data() + 8, 8);
  std::memcpy(&size, bytes.data() + 16, 8);
  std::memcpy(&crc, bytes.data() + 24, 4);
  if (seq != snapshot_seq) {
    return refuse("kept at seq " + std::to_string(seq) + ", the snapshot loaded is at seq " +
                  std::to_string(snapshot_seq));
  }
  const std::string_view payload(bytes.data() + kHistoryHeader, bytes.size() - kHistoryHeader);
  if (size != payload.size() || store::Crc32c(payload) != crc) {
    return refuse("size or checksum mismatch");
  }
  EditHistoryOptions o;
  o.depth_per_author = static_cast<int>(config_.limits.undo_depth);
  auto parsed = EditHistory::Parse(payload, o);
  if (!parsed.ok()) return refuse(parsed.status().ToString());
  h = std::move(parsed).value();
}

void Scene::History(codec::HistoryQuery query, std::function<void(v1::HistoryAnswer)> done) {
  auto once = AnswerOnce(std::move(done));
  auto refuse = [once, id = query.request_id, object = query.object](const Status& st) {
    v1::HistoryAnswer a;
    a.set_request_id(id);
    a.set_object(object);
    *a.mutable_error() = ToWireError(st, 0);
    once(std::move(a));
  };
  Post(CurrentRequester(), "history", refuse, [this, query = std::move(query), once, refuse] {
    if (!sculptures_.count(query.object)) {
      return refuse(
          NotFound("HistoryRequest.object=" + query.object + " outside the scene's objects"));
    }
    const EditHistory& h = HistoryOf(query.object);
    const std::vector<HistoryEntry> entries = h.Entries(query.author);
    v1::HistoryAnswer a;
    a.set_request_id(query.request_id);
    a.set_object(query.object);
    a.set_matching(static_cast<uint32_t>(entries.size()));
    a.set_held(static_cast<uint32_t>(h.size()));
    a.set_cleared(h.cleared_reason());
    for (auto it = entries.rbegin();
         it != entries.rend() && a.entries_size() < static_cast<int>(query.limit); ++it) {
      v1::HistoryEntry* e = a.add_entries();
      e->set_seq(it->seq);
      e->set_author(it->author);
      e->set_kind(codec::EditKindToProto(it->kind));
      e->set_sweep(it->sweep);
      e->set_poses(it->poses);
      e->set_time_ms(it->wall_ms);
      e->set_undone(it->undone);
      e->set_undoable(it->undoable);
    }
    once(std::move(a));
  });
}

std::pair<size_t, size_t> Scene::UndoDepth(const std::string& object, uint64_t client_id) {
  std::promise<std::pair<size_t, size_t>> p;
  auto fail = [&p](const Status&) { p.set_value({0, 0}); };
  Post("undo depth", fail, [&] {
    if (!sculptures_.count(object)) return p.set_value({0, 0});
    EditHistory& h = HistoryOf(object);
    const std::string author = HistoryAuthor(client_id);
    p.set_value({h.undo_depth(author), h.redo_depth(author)});
  });
  return p.get_future().get();
}

}  // namespace sculpt::server
