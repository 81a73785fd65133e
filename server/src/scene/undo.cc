/// @brief Per-author undo and redo on the commit pipeline (issue 15): the Undo op, and the
/// histories every stroke is recorded in (EditHistory, edit_history.h).
#include <spdlog/spdlog.h>

#include <algorithm>
#include <charconv>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <future>
#include <iterator>

#include "scene/answer_once.h"
#include "scene/edit_history.h"
#include "scene/history_file.h"
#include "scene/scene.h"
#include "sculpt/codec/log_records.h"
#include "store/durable_file.h"
#include "store/resend_table.h"

namespace sculpt::server {

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
// changes nothing), chooses which history holds the author's newest edit (the object's strokes,
// paints and sweeps, its model's intents, or, when the request names a skin, the skin's ball edits)
// and logs the request with that choice; Apply runs that history's undo or redo, which restores
// the region and replays the later strokes it reaches (or rebuilds the skin or model), exactly
// as recovery will (the histories are rebuilt by recovery from the same records). Replicas get
// the changed leaves.
struct Scene::UndoOp final : EditOp {
  UndoOp(uint64_t client, codec::UndoCommand c, std::function<void(UndoCommandOutcome)> d)
      : client(client), command(std::move(c)), done(std::move(d)) {}
  const char* operation() const override { return command.redo ? "redo" : "undo"; }
  ResendStream stream() const override { return ResendStream::kUndos; }
  uint64_t client_id() const override { return client; }
  uint64_t client_seq() const override { return command.client_seq; }

  Status Prepare(Scene& scene, uint64_t first_seq, std::vector<std::string>* records) override {
    const std::string author = HistoryAuthor(client);
    const bool redo = command.redo;
    StatusOr<uint64_t> target = Status(Status::Code::kInternal, "unset");
    if (scene.sculptures_.count(command.object)) {
      EditHistory& h = scene.HistoryOf(command.object);
      target = redo ? h.RedoTarget(author) : h.UndoTarget(author);
      book = codec::kUndoObjectBook;
      if (scene.models_.has_model(command.object)) {
        // The author's newest edit of any kind: by sequence for an undo, by when it was undone
        // for a redo.
        uint64_t undone_at = 0;
        auto m = scene.models_.UndoTarget(command.object, author, redo, &undone_at);
        if (m.ok() &&
            (!target.ok() || (redo ? undone_at > h.RedoUndoneAt(author) : *m > *target))) {
          target = m;
          book = codec::kUndoModelBook;
        }
      }
    } else if (scene.skins_.has_skin(command.object)) {
      target = scene.skins_.UndoTarget(command.object, author, redo);
      book = codec::kUndoSkinBook;
    } else {
      return Outside("UndoRequest.object", command.object, "the scene's objects and skins",
                     Status::Code::kNotFound);
    }
    if (!target.ok()) {
      if (redo && target.status().code() == Status::Code::kFailedPrecondition) {
        return Outside("UndoRequest.redo", "true",
                       std::string("requests with an undone edit to redo on ") + command.object +
                           " (none since this client's last undo, or an edit came after it)",
                       Status::Code::kFailedPrecondition);
      }
      // The history says why not (nothing ever, fell off the depth, its snapshot history unusable).
      return target.status();
    }
    seq = first_seq;
    codec::UndoRecord rec;
    rec.global_seq = first_seq;
    rec.client_id = client;
    rec.client_seq = command.client_seq;
    rec.object = command.object;
    rec.redo = command.redo;
    rec.author = author;
    rec.target_book = book;
    rec.target_seq = *target;
    records->push_back(codec::EncodeLogRecord(rec));
    return Status::Ok();
  }

  Applied Apply(Scene& scene) override {
    Applied a;
    const std::string author = HistoryAuthor(client);
    const std::string& name = command.object;
    if (book == codec::kUndoSkinBook) {
      // A skin's chain changed, no voxels: nothing to replicate but the contour update.
      auto out = scene.skins_.Undo(name, author, command.redo, seq);
      if (!out.ok()) {
        a.status = out.status();
        return a;
      }
      outcome = *out;
      depth = scene.skins_.UndoDepth(name, author);
      return a;
    }
    EditHistory& h = scene.HistoryOf(name);
    if (book == codec::kUndoModelBook) {
      // The model changed; the voxelised object is not re-voxelised (as for the intent itself).
      auto out = scene.models_.Undo(name, author, command.redo, seq);
      if (!out.ok()) {
        a.status = out.status();
        return a;
      }
      outcome = *out;
    } else {
      a.object = name;
      a.bounds_may_change = true;
      levelset::Sculpture& s = scene.sculptures_.at(name);
      auto out = command.redo ? h.Redo(s, author) : h.Undo(s, author, seq);
      if (!out.ok()) {
        a.status = out.status();
        return a;
      }
      outcome = *out;
      a.dirty_leaves = out->dirty_leaves;
    }
    const auto m = scene.models_.UndoDepth(name, author);
    depth = {h.undo_depth(author) + m.first, h.redo_depth(author) + m.second};
    return a;
  }

  void Answer(const CommitOutcome& o) override {
    UndoCommandOutcome a;
    a.status = o.status;
    a.client_seq = command.client_seq;
    a.redo = command.redo;
    if (!o.status.ok()) {
      if (o.records > 0) a.global_seq = o.global_seq_first;
      return done(std::move(a));
    }
    a.duplicate = o.duplicate;
    if (!o.duplicate) {
      a.global_seq = o.global_seq_first;
      a.target_seq = outcome.seq;
      a.replayed = outcome.replayed;
      a.replayed_by = outcome.replayed_by;
      a.undo_depth = static_cast<uint32_t>(depth.first);
      a.redo_depth = static_cast<uint32_t>(depth.second);
    }
    done(std::move(a));
  }

  uint64_t client;
  codec::UndoCommand command;
  std::function<void(UndoCommandOutcome)> done;
  uint32_t book = codec::kUndoObjectBook;  // which history it takes from (UndoRecord.target_book)
  uint64_t seq = 0;
  UndoOutcome outcome;
  std::pair<size_t, size_t> depth;
};

void Scene::Undo(uint64_t client_id, codec::UndoCommand command,
                 std::function<void(UndoCommandOutcome)> done) {
  Commit(std::make_shared<UndoOp>(client_id, std::move(command), AnswerOnce(std::move(done))));
}

void Scene::LoadHistory(const std::string& object, uint64_t snapshot_seq) {
  EditHistory& h = HistoryOf(object);
  if (snapshot_seq == 0) return;  // built from the scene: nothing before it to undo
  std::string path = HistoryFilePath(config_.data_dir, object, snapshot_seq);
  if (!std::filesystem::exists(path)) path = LegacyHistoryFilePath(config_.data_dir, object);
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    h.Clear("no undo history was kept with the snapshot at seq " + std::to_string(snapshot_seq));
    return;
  }
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EditHistoryOptions o;
  o.depth_per_author = static_cast<int>(config_.limits.undo_depth);
  auto parsed = ParseHistoryFile(bytes, snapshot_seq, o);
  if (!parsed.ok()) {
    spdlog::warn("undo history {}: {}; strokes before seq {} can no longer be undone", path,
                 parsed.status().ToString(), snapshot_seq);
    h.Clear("the undo history kept with the snapshot at seq " + std::to_string(snapshot_seq) +
            " was not usable");
    return;
  }
  h = std::move(parsed).value();
}

void Scene::NameAuthor(uint64_t client_id, std::string user) {
  std::lock_guard<std::mutex> lock(authors_mu_);
  auto [it, added] = author_users_.insert_or_assign(client_id, std::move(user));
  if (!added) return;
  author_order_.push_back(client_id);
  if (author_order_.size() > kMaxNamedAuthors) {
    author_users_.erase(author_order_.front());
    author_order_.pop_front();
  }
}

std::string Scene::AuthorUser(uint64_t client_id) const {
  std::lock_guard<std::mutex> lock(authors_mu_);
  auto it = author_users_.find(client_id);
  return it == author_users_.end() ? std::string() : it->second;
}

void Scene::History(codec::HistoryQuery query, std::function<void(HistoryOutcome)> done) {
  auto once = AnswerOnce(std::move(done));
  auto refuse = [once, id = query.request_id, object = query.object](const Status& st) {
    HistoryOutcome a;
    a.status = st;
    a.request_id = id;
    a.object = object;
    once(std::move(a));
  };
  Post(CurrentRequester(), "history", refuse, [this, query = std::move(query), once, refuse] {
    std::vector<HistoryEntry> entries;
    HistoryOutcome a;
    // The edits filed under `author` (every author's when empty).
    const auto gather = [&](const std::string& author) -> Status {
      entries.clear();
      if (sculptures_.count(query.object)) {
        const EditHistory& h = HistoryOf(query.object);
        entries = h.Entries(author);
        a.held = static_cast<uint32_t>(h.size());
        a.cleared = h.cleared_reason();
        // The model's intents among the strokes and paints, in global order.
        std::vector<HistoryEntry> intents = models_.Entries(query.object, author);
        a.held += static_cast<uint32_t>(intents.size());
        entries.insert(entries.end(), intents.begin(), intents.end());
        std::stable_sort(entries.begin(), entries.end(), [](const HistoryEntry& x,
                                                            const HistoryEntry& y) {
          return x.seq < y.seq;
        });
      } else if (skins_.has_skin(query.object)) {
        size_t held = 0;
        auto e = skins_.Entries(query.object, author, &a.cleared, &held);
        if (!e.ok()) return e.status();
        entries = std::move(e).value();
        a.held = static_cast<uint32_t>(held);
      } else {
        return Outside("HistoryRequest.object", query.object, "the scene's objects and skins",
                       Status::Code::kNotFound);
      }
      return Status::Ok();
    };
    // An entry's author is the client id its edits are filed under (HistoryAuthor).
    const auto UserOf = [this](const HistoryEntry& e) {
      uint64_t id = 0;
      const char* end = e.author.data() + e.author.size();
      const auto [p, ec] = std::from_chars(e.author.data(), end, id);
      return ec == std::errc() && p == end ? AuthorUser(id) : std::string();
    };
    if (Status s = gather(query.author); !s.ok()) return refuse(s);
    if (entries.empty() && !query.author.empty()) {
      // A user's name (named users): the edits of every client it sculpted from.
      if (Status s = gather(""); !s.ok()) return refuse(s);
      std::erase_if(entries, [&](const HistoryEntry& e) { return UserOf(e) != query.author; });
    }
    for (HistoryEntry& e : entries) {
      e.user = UserOf(e);
      e.epoch = EpochAt(e.seq);
    }
    a.request_id = query.request_id;
    a.object = query.object;
    a.matching = static_cast<uint32_t>(entries.size());
    for (auto it = entries.rbegin(); it != entries.rend() && a.entries.size() < query.limit; ++it) {
      a.entries.push_back(*it);
    }
    once(std::move(a));
  });
}

std::pair<size_t, size_t> Scene::UndoDepth(const std::string& object, uint64_t client_id) {
  std::promise<std::pair<size_t, size_t>> p;
  auto fail = [&p](const Status&) { p.set_value({0, 0}); };
  Post("undo depth", fail, [&] {
    const std::string author = HistoryAuthor(client_id);
    if (!sculptures_.count(object)) return p.set_value(skins_.UndoDepth(object, author));
    EditHistory& h = HistoryOf(object);
    const auto m = models_.UndoDepth(object, author);
    p.set_value({h.undo_depth(author) + m.first, h.redo_depth(author) + m.second});
  });
  return p.get_future().get();
}

}  // namespace sculpt::server
