/// @brief BookHistory: per-author undo and redo of the small edits a scene keeps in books (a
/// skin's ball edits, a model's intents; issue 15), by keeping each edit's state before it and
/// replaying the later ones in order.
#ifndef SCULPT_SERVER_SCENE_BOOK_HISTORY_H_
#define SCULPT_SERVER_SCENE_BOOK_HISTORY_H_

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <deque>
#include <map>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "scene/edit_history.h"
#include "sculpt/core/check.h"
#include "sculpt/core/status.h"

namespace sculpt::server {

/// The undo history of one book entry (a skin, a model): its edits in global order, each with
/// the entry's whole state before it (these states are small: a chain of balls, a hyperpatch
/// model), whether it is in the order now, and each author's undo and redo stacks. Undo takes
/// the author's newest edit out of the order and Redo puts the most recently undone one back;
/// both rebuild the state from the changed edit's state before it by re-applying every later
/// edit still in the order, with the book's own apply, so the result is the state a fresh replay
/// of the log without (or with) that edit gives. A later edit that the rebuilt state refuses
/// (an index past the end, an inadmissible ball, an invalid model) is skipped, as a fresh replay
/// refuses it.
/// Thread safety: not thread-safe; the scene's compute thread owns it with its book.
template <typename State, typename Edit>
class BookHistory {
 public:
  /// `kind_name` is what the history view calls its edits ("ball edit", "model intent").
  BookHistory(const char* kind_name, size_t depth_per_author, size_t max_edits = 1024)
      : kind_name_(kind_name),
        depth_(std::max<size_t>(depth_per_author, 1)),
        max_edits_(std::max<size_t>(max_edits, 1)) {}

  /// Records an edit just applied at `seq` by `author` (its state before it in `before`), as
  /// the author's newest undoable edit; the author's redo stack is dropped, as a new stroke does.
  void Commit(uint64_t seq, const std::string& author, uint64_t wall_ms, Edit edit, State before) {
    for (Record& r : records_) {
      if (r.author == author && r.stack == Stack::kRedo) r.stack = Stack::kDead;
    }
    records_.push_back({seq, wall_ms, author, std::move(edit), std::move(before)});
    size_t undoable = 0;
    for (auto it = records_.rbegin(); it != records_.rend(); ++it) {
      if (it->author != author || it->stack != Stack::kUndo) continue;
      if (++undoable > depth_) {
        it->stack = Stack::kDead;  // fell off the author's depth
        ++fell_off_[author];
      }
    }
    Trim();
  }

  /// The sequence of the edit Undo(author) would take back. FailedPrecondition when the author
  /// has nothing to undo (naming why the history was last cleared); OutOfRange when its edits
  /// within reach fell off the depth.
  StatusOr<uint64_t> UndoTarget(const std::string& author) const {
    const Record* r = Newest(author, Stack::kUndo);
    if (r) return r->seq;
    auto fell = fell_off_.find(author);
    if (fell != fell_off_.end() && fell->second > 0) {
      return FieldViolation(
          Status::Code::kOutOfRange, "author", "\"" + author + "\"",
          "authors with an edit within depth_per_author=" + std::to_string(depth_),
          "undo: author=\"" + author + "\" has no " + kind_name_ +
              " left within depth_per_author=" + std::to_string(depth_));
    }
    return FieldViolation(Status::Code::kFailedPrecondition, "author", "\"" + author + "\"",
                          "authors with an edit to undo",
                          "undo: author=\"" + author + "\" has nothing to undo" +
                              (cleared_.empty() ? "" : " (history cleared: " + cleared_ + ")"));
  }
  /// The sequence of the edit Redo(author) would put back; FailedPrecondition when none.
  StatusOr<uint64_t> RedoTarget(const std::string& author) const {
    const Record* r = Newest(author, Stack::kRedo);
    if (r) return r->seq;
    return FieldViolation(Status::Code::kFailedPrecondition, "author", "\"" + author + "\"",
                          "authors with an undone edit to redo",
                          "redo: author=\"" + author + "\" has nothing to redo");
  }
  /// The sequence of the undo that took back RedoTarget(author)'s edit (0: none).
  uint64_t RedoUndoneAt(const std::string& author) const {
    const Record* r = Newest(author, Stack::kRedo);
    return r ? r->undone_at : 0;
  }

  /// Takes back the author's newest undoable edit (`at_seq`: the undo's own sequence) and
  /// rebuilds `state` without it; `apply(State&, const Edit&)` returns false when the state
  /// refuses an edit (then unchanged). UndoTarget's errors, nothing changed.
  template <typename ApplyFn>
  StatusOr<UndoOutcome> Undo(const std::string& author, uint64_t at_seq, State* state,
                             ApplyFn apply) {
    SCULPT_RETURN_IF_ERROR(UndoTarget(author).status());
    Record* r = const_cast<Record*>(Newest(author, Stack::kUndo));
    r->stack = Stack::kRedo;
    r->active = false;
    r->undone_at = at_seq;
    return Rebuild(r, state, apply);
  }
  /// Puts back the author's most recently undone edit at its place in the order.
  template <typename ApplyFn>
  StatusOr<UndoOutcome> Redo(const std::string& author, State* state, ApplyFn apply) {
    SCULPT_RETURN_IF_ERROR(RedoTarget(author).status());
    Record* r = const_cast<Record*>(Newest(author, Stack::kRedo));
    r->stack = Stack::kUndo;
    r->active = true;
    r->undone_at = 0;
    return Rebuild(r, state, apply);
  }

  /// Forgets every edit; `why` is quoted by later "nothing to undo" errors.
  void Clear(const std::string& why) {
    records_.clear();
    fell_off_.clear();
    cleared_ = why;
  }

  /// The history as bytes to keep beside the book's file of a snapshot round, so a restart from
  /// that file undoes what was undoable before it: `put_state(const State&)` and
  /// `put_edit(const Edit&)` return each one's bytes.
  template <typename PutState, typename PutEdit>
  std::string Serialize(PutState put_state, PutEdit put_edit) const {
    std::string out("SBH1");
    PutString(out, cleared_);
    Put(out, static_cast<uint32_t>(fell_off_.size()));
    for (const auto& [author, n] : fell_off_) {
      PutString(out, author);
      Put(out, n);
    }
    Put(out, static_cast<uint32_t>(records_.size()));
    for (const Record& r : records_) {
      Put(out, r.seq);
      Put(out, r.wall_ms);
      Put(out, r.undone_at);
      const uint8_t flags[2] = {static_cast<uint8_t>(r.active), static_cast<uint8_t>(r.stack)};
      Put(out, flags);
      PutString(out, r.author);
      PutString(out, put_edit(r.edit));
      PutString(out, put_state(r.before));
    }
    return out;
  }
  /// Replaces the history with what Serialize wrote; `get_state(std::string_view)` and
  /// `get_edit(std::string_view)` return StatusOr of each. DataLoss naming what is truncated or
  /// malformed (the history is then empty, `cleared` saying so).
  template <typename GetState, typename GetEdit>
  Status Parse(std::string_view in, GetState get_state, GetEdit get_edit) {
    Clear("its saved history did not parse");
    std::deque<Record> records;
    std::map<std::string, uint64_t> fell_off;
    std::string cleared;
    uint32_t n = 0;
    if (in.substr(0, 4) != "SBH1") return DataLoss("book history: magic outside {SBH1}");
    in.remove_prefix(4);
    if (!GetString(in, &cleared) || !Get(in, &n)) return DataLoss("book history: header truncated");
    for (uint32_t i = 0; i < n; ++i) {
      std::string author;
      uint64_t count = 0;
      if (!GetString(in, &author) || !Get(in, &count)) {
        return DataLoss("book history: fell-off counts truncated");
      }
      fell_off[author] = count;
    }
    if (!Get(in, &n)) return DataLoss("book history: record count truncated");
    for (uint32_t i = 0; i < n; ++i) {
      uint64_t seq = 0, wall_ms = 0, undone_at = 0;
      uint8_t flags[2];
      std::string author, edit, state;
      if (!Get(in, &seq) || !Get(in, &wall_ms) || !Get(in, &undone_at) || !Get(in, &flags) ||
          !GetString(in, &author) || !GetString(in, &edit) || !GetString(in, &state) ||
          flags[1] > static_cast<uint8_t>(Stack::kDead)) {
        return DataLoss("book history: record " + std::to_string(i) + " truncated or malformed");
      }
      auto e = get_edit(std::string_view(edit));
      if (!e.ok())
        return DataLoss("book history: record " + std::to_string(i) +
                        ": edit: " + e.status().message());
      auto st = get_state(std::string_view(state));
      if (!st.ok())
        return DataLoss("book history: record " + std::to_string(i) +
                        ": state: " + st.status().message());
      records.push_back(Record{seq, wall_ms, std::move(author), std::move(e).value(),
                               std::move(st).value(), flags[0] != 0, static_cast<Stack>(flags[1]),
                               undone_at});
    }
    if (!in.empty()) return DataLoss("book history: bytes after the end");
    records_ = std::move(records);
    fell_off_ = std::move(fell_off);
    cleared_ = std::move(cleared);
    return Status::Ok();
  }

  size_t undo_depth(const std::string& author) const { return Count(author, Stack::kUndo); }
  size_t redo_depth(const std::string& author) const { return Count(author, Stack::kRedo); }
  size_t size() const { return records_.size(); }
  const std::string& cleared_reason() const { return cleared_; }
  /// The held edits, oldest first; only `author`'s when it is not empty.
  std::vector<HistoryEntry> Entries(const std::string& author = {}) const {
    std::vector<HistoryEntry> out;
    for (const Record& r : records_) {
      if (!author.empty() && r.author != author) continue;
      HistoryEntry e;
      e.seq = r.seq;
      e.author = r.author;
      e.kind_name = kind_name_;
      e.undone = !r.active;
      e.undoable = r.stack == Stack::kUndo;
      e.wall_ms = r.wall_ms;
      out.push_back(std::move(e));
    }
    return out;
  }

 private:
  enum class Stack : uint8_t { kUndo, kRedo, kDead };
  struct Record {
    uint64_t seq = 0;
    uint64_t wall_ms = 0;
    std::string author;
    Edit edit;
    State before;  // the state it starts from in the current order
    bool active = true;
    Stack stack = Stack::kUndo;
    uint64_t undone_at = 0;
  };

  // The author's newest edit on `stack`: by sequence for undo, by the undo's sequence for redo.
  const Record* Newest(const std::string& author, Stack stack) const {
    const Record* best = nullptr;
    for (const Record& r : records_) {
      if (r.author != author || r.stack != stack) continue;
      if (!best || (stack == Stack::kRedo ? r.undone_at >= best->undone_at : true)) best = &r;
    }
    return best;
  }
  size_t Count(const std::string& author, Stack stack) const {
    return static_cast<size_t>(
        std::count_if(records_.begin(), records_.end(),
                      [&](const Record& r) { return r.author == author && r.stack == stack; }));
  }

  template <typename T>
  static void Put(std::string& s, const T& v) {
    s.append(reinterpret_cast<const char*>(&v), sizeof v);
  }
  static void PutString(std::string& s, const std::string& v) {
    Put(s, static_cast<uint32_t>(v.size()));
    s.append(v);
  }
  template <typename T>
  static bool Get(std::string_view& s, T* v) {
    if (s.size() < sizeof(T)) return false;
    std::memcpy(v, s.data(), sizeof(T));
    s.remove_prefix(sizeof(T));
    return true;
  }
  static bool GetString(std::string_view& s, std::string* v) {
    uint32_t n = 0;
    if (!Get(s, &n) || s.size() < n) return false;
    v->assign(s.data(), n);
    s.remove_prefix(n);
    return true;
  }

  template <typename ApplyFn>
  StatusOr<UndoOutcome> Rebuild(Record* from, State* state, ApplyFn apply) {
    const auto t0 = std::chrono::steady_clock::now();
    UndoOutcome out;
    out.seq = from->seq;
    out.author = from->author;
    State s = from->before;
    auto start = records_.begin();
    while (&*start != from) ++start;
    for (auto it = start; it != records_.end(); ++it) {
      it->before = s;
      if (!it->active) continue;
      // Refused by the rebuilt state: skipped, as a fresh replay of the log refuses it.
      (void)apply(s, it->edit);
      if (&*it != from) {
        ++out.replayed;
        ++out.replayed_by[it->author];
      }
    }
    *state = std::move(s);
    out.elapsed_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    return out;
  }

  void Trim() {
    // Edits before the oldest one anybody can still undo or redo are never rebuilt again.
    while (!records_.empty() &&
           (records_.front().stack == Stack::kDead || records_.size() > max_edits_)) {
      if (records_.front().stack != Stack::kDead) ++fell_off_[records_.front().author];
      records_.pop_front();
    }
  }

  std::string kind_name_;
  size_t depth_;
  size_t max_edits_;
  std::deque<Record> records_;
  std::map<std::string, uint64_t> fell_off_;
  std::string cleared_;
};

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_SCENE_BOOK_HISTORY_H_
