/// @brief Hyperpatch models as scene objects (issue 7, seed 001 §10.4-10.5): the content hash,
/// model files beside snapshots, ModelBook (intents checked on a copy, applied, replayed past a
/// file's seq), and the scene's model edit kind on the commit pipeline (expand deterministically,
/// check validity after ordering, log, apply, ack once durable). The Scene's part runs on the
/// compute thread.
#include "scene/models.h"

#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <future>
#include <sstream>

#include "scene/answer_once.h"
#include "scene/scene.h"
#include "sculpt/codec/model_messages.h"
#include "sculpt/core/check.h"
#include "sculpt/hetero/model_io.h"
#include "sculpt/hetero/validity.h"
#include "store/durable_file.h"
#include "store/edit_log.h"
#include "store/resend_table.h"

namespace sculpt::server {
namespace {

constexpr const char* kModelFileHeader = "sculpt-model-state";

// The server's wall clock, ms since 1970: when an intent was committed (the history view).
uint64_t WallClockMs() {
  return static_cast<uint64_t>(std::chrono::duration_cast<std::chrono::milliseconds>(
                                   std::chrono::system_clock::now().time_since_epoch())
                                   .count());
}

// The library names fields "intent.*"; on the wire they are the message's.
Status Rename(const Status& s) {
  auto renamed = [](std::string t) {
    if (t.rfind("intent.", 0) == 0) t = "ModelIntent." + t.substr(7);
    return t;
  };
  const Status::Violation* v = s.violation();
  if (v == nullptr) return Status(s.code(), renamed(s.message()));
  return FieldViolation(s.code(), renamed(v->field), v->value, v->allowed_range,
                        renamed(s.message()));
}

template <typename T>
void Mix(uint64_t* h, const T& v) {
  unsigned char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  for (unsigned char c : b) {
    *h ^= c;
    *h *= 1099511628211ull;
  }
}

}  // namespace

uint64_t ModelHash(const hetero::CompositeModel& model) {
  uint64_t h = 14695981039346656037ull;
  Mix(&h, static_cast<int64_t>(model.materials()));
  Mix(&h, static_cast<uint64_t>(model.coefficient_count()));
  for (uint32_t c = 0; c < model.coefficient_count(); ++c) {
    const Vec3& p = model.position(c);
    Mix(&h, p.x);
    Mix(&h, p.y);
    Mix(&h, p.z);
    for (double a : model.fractions(c)) Mix(&h, a);
  }
  Mix(&h, static_cast<uint64_t>(model.cell_count()));
  for (size_t i = 0; i < model.cell_count(); ++i) {
    for (uint32_t q : model.cell(static_cast<int>(i)).coef) Mix(&h, q);
  }
  for (const auto& [corner, f] : model.all_corner_flags()) {
    Mix(&h, corner);
    Mix(&h, static_cast<uint8_t>((f.geometry_c1 ? 1 : 0) | (f.material_c1 ? 2 : 0)));
  }
  return h;
}

// ---------------------------------------------------------------------------------------------
// Model files beside the snapshots


Status SaveModelFile(const std::string& path, uint64_t seq, uint64_t version,
                     const hetero::CompositeModel& model) {
  const std::string text = std::string(kModelFileHeader) + " " + std::to_string(seq) + " " +
                           std::to_string(version) + "\n" + hetero::ModelToJson(model);
  const std::string tmp = path + ".tmp";
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return Internal("open " + tmp + ": " + std::strerror(errno));
  size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      const std::string why = std::strerror(errno);
      ::close(fd);
      return Internal("write " + tmp + ": " + why);
    }
    done += static_cast<size_t>(n);
  }
  if (::fdatasync(fd) != 0 || ::close(fd) != 0) {
    return Internal("sync " + tmp + ": " + std::strerror(errno));
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) return Internal("rename " + tmp + ": " + ec.message());
  // The log before this file's seq may be dropped once it is saved: make the rename durable.
  return store::FsyncDirectory(std::filesystem::path(path).parent_path().string());
}

StatusOr<SavedModel> LoadModelFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return NotFound("model file " + path);
  std::string header;
  std::getline(in, header);
  std::istringstream hs(header);
  std::string tag;
  SavedModel out;
  if (!(hs >> tag >> out.seq >> out.version) || tag != kModelFileHeader) {
    return DataLoss("model file " + path + ": bad header '" + header + "'");
  }
  const std::string body((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  auto m = hetero::ModelFromJson(body);
  if (!m.ok()) return DataLoss("model file " + path + ": " + m.status().message());
  out.model = std::move(m).value();
  return out;
}

// ---------------------------------------------------------------------------------------------
// ModelBook

namespace {
std::string ModelFilePath(const std::string& data_dir, const std::string& object) {
  return (std::filesystem::path(data_dir) / "models" / (object + ".json")).string();
}
// The model's undo history of the same round: the model file's seq (8 bytes), then
// BookHistory::Serialize's bytes.
std::string ModelHistoryPath(const std::string& data_dir, const std::string& object) {
  return (std::filesystem::path(data_dir) / "models" / (object + ".history")).string();
}
std::string IntentBytes(const hetero::EditIntent& intent) {
  codec::ModelRecord r;
  r.edit.intent = intent;
  return codec::EncodeLogRecord(r);
}
StatusOr<hetero::EditIntent> IntentFromBytes(std::string_view bytes) {
  SCULPT_ASSIGN_OR_RETURN(codec::EditLogRecord rec, codec::DecodeLogRecord(0, bytes));
  const auto* r = std::get_if<codec::ModelRecord>(&rec);
  if (!r) return DataLoss("not a model intent");
  return r->edit.intent;
}
}  // namespace

Status ModelBook::Open(const std::vector<ObjectConfig>& objects, const std::string& data_dir) {
  data_dir_ = data_dir;
  models_.clear();
  for (const ObjectConfig& o : objects) {
    if (o.primitive != "model") continue;
    Entry entry;
    auto saved = LoadModelFile(ModelFilePath(data_dir_, o.name));
    if (saved.ok()) {
      entry.model = std::move(saved->model);
      entry.version = saved->version;
      entry.file_seq = saved->seq;
    } else if (saved.status().code() == Status::Code::kNotFound) {
      auto m = hetero::LoadModel(o.model);
      if (!m.ok()) {
        return Status(m.status().code(), "scene.objects " + o.name + ".model=" + o.model + ": " +
                                             m.status().message());
      }
      entry.model = std::move(m).value();
    } else {
      return saved.status();
    }
    entry.history = History("model intent", undo_depth_);
    if (entry.file_seq > 0) {
      // The undo history kept with the model file of the same round (none: nothing to undo).
      std::ifstream in(ModelHistoryPath(data_dir_, o.name), std::ios::binary);
      const std::string bytes((std::istreambuf_iterator<char>(in)),
                              std::istreambuf_iterator<char>());
      uint64_t seq = 0;
      if (bytes.size() >= sizeof seq) std::memcpy(&seq, bytes.data(), sizeof seq);
      Status s = FailedPrecondition("no undo history was kept with the model file at seq " +
                                    std::to_string(entry.file_seq));
      if (in && bytes.size() >= sizeof seq && seq == entry.file_seq) {
        auto state = [](std::string_view b) -> StatusOr<State> {
          SCULPT_ASSIGN_OR_RETURN(hetero::CompositeModel m, hetero::ModelFromJson(std::string(b)));
          return State{std::move(m), hetero::ValidityChecker{}};
        };
        s = entry.history.Parse(std::string_view(bytes).substr(sizeof seq), state, IntentFromBytes);
      }
      if (!s.ok()) {
        spdlog::warn("model {}: {}; its earlier intents can no longer be undone", o.name,
                     s.ToString());
        entry.history.Clear(s.message());
      }
    }
    models_[o.name] = std::move(entry);
  }
  return Status::Ok();
}

void ModelBook::Replay(uint64_t seq, const codec::ModelRecord& r) {
  auto it = models_.find(r.edit.object);
  if (it == models_.end() || seq <= it->second.file_seq) return;
  Entry& entry = it->second;
  State before{entry.model, entry.checker};
  // Checked when it was made.
  auto out = hetero::ApplyIntent(&entry.model, &entry.checker, r.edit.intent);
  if (!out.ok() || !out->applied) {
    spdlog::warn("model intent at seq {} refused on replay: {}", seq,
                 out.ok() ? out->rejection.ToString() : out.status().ToString());
    return;
  }
  entry.version = r.model_version;
  // As live: the model before it is what an undo rebuilds from.
  entry.history.Commit(seq, HistoryAuthor(r.client_id), 0, r.edit.intent, std::move(before));
}

bool ModelBook::Save(uint64_t seq) const { return SaveTo(data_dir_, seq); }

bool ModelBook::SaveTo(const std::string& dir, uint64_t seq) const {
  if (models_.empty()) return true;
  bool saved_all = true;
  std::error_code ec;
  std::filesystem::create_directories(std::filesystem::path(dir) / "models", ec);
  for (const auto& [name, entry] : models_) {
    // Written before the log rolls, so the segments a snapshot lets go are already covered.
    if (const Status s = SaveModelFile(ModelFilePath(dir, name), seq, entry.version, entry.model);
        !s.ok()) {
      spdlog::error("model {} at seq {} not saved: {}", name, seq, s.ToString());
      saved_all = false;
      continue;
    }
    // Its undo history, for a restart from this file (Open checks the seq matches).
    std::string bytes(reinterpret_cast<const char*>(&seq), sizeof seq);
    bytes += entry.history.Serialize([](const State& st) { return hetero::ModelToJson(st.model); },
                                     IntentBytes);
    if (const Status s = store::WriteFileDurably(ModelHistoryPath(dir, name), bytes); !s.ok()) {
      spdlog::error("undo history of model {} at seq {} not saved: {}", name, seq, s.ToString());
      saved_all = false;
    }
  }
  return saved_all;
}

Status ModelBook::PrepareIntent(const codec::ModelEdit& edit, IntentPlan* plan) const {
  auto it = models_.find(edit.object);
  if (it == models_.end()) {
    return Outside("ModelIntent.object", edit.object, "the scene's model objects",
                   Status::Code::kNotFound);
  }
  const Entry& entry = it->second;
  const hetero::CompositeModel& model = entry.model;
  const hetero::EditIntent& intent = edit.intent;
  if (intent.corner >= model.coefficient_count()) {
    return Outside("ModelIntent.corner", std::to_string(intent.corner),
                   std::string("[0, ") + std::to_string(model.coefficient_count() - 1) + "]");
  }
  if (intent.cell >= static_cast<int64_t>(model.cell_count())) {
    return Outside("ModelIntent.cell", std::to_string(intent.cell),
                   std::string("[-1, ") + std::to_string(model.cell_count() - 1) + "]");
  }
  plan->object = edit.object;
  plan->next = entry.model;
  plan->next_checker = entry.checker;
  auto out = hetero::ApplyIntent(&plan->next, &plan->next_checker, intent);
  if (!out.ok()) return Rename(out.status());
  if (!out->applied) {
    plan->rejection = out->rejection;
    plan->now = {entry.version, ModelHash(entry.model)};
    return Outside("ModelIntent", plan->rejection->ToString(), "intents that keep the model valid",
                   Status::Code::kFailedPrecondition);
  }
  plan->moved = out->moves.size();
  plan->version = entry.version + 1;
  return Status::Ok();
}

ModelBook::Stamp ModelBook::ApplyIntent(IntentPlan plan, uint64_t seq, const std::string& author,
                                        const hetero::EditIntent& intent, uint64_t wall_ms) {
  Entry& entry = models_.at(plan.object);
  if (!author.empty()) {
    entry.history.Commit(seq, author, wall_ms, intent,
                         State{std::move(entry.model), std::move(entry.checker)});
  }
  entry.model = std::move(plan.next);
  entry.checker = std::move(plan.next_checker);
  entry.version = plan.version;
  return {entry.version, ModelHash(entry.model)};
}

StatusOr<uint64_t> ModelBook::UndoTarget(const std::string& object, const std::string& author,
                                         bool redo, uint64_t* undone_at) const {
  auto it = models_.find(object);
  if (it == models_.end()) return NotFound("object " + object + " holds no hyperpatch model");
  const History& h = it->second.history;
  if (undone_at) *undone_at = redo ? h.RedoUndoneAt(author) : 0;
  return redo ? h.RedoTarget(author) : h.UndoTarget(author);
}

StatusOr<UndoOutcome> ModelBook::Undo(const std::string& object, const std::string& author,
                                      bool redo, uint64_t at_seq) {
  auto it = models_.find(object);
  if (it == models_.end()) return NotFound("object " + object + " holds no hyperpatch model");
  Entry& entry = it->second;
  // An intent re-applied by the rebuild: on a copy, kept only when the model stays valid.
  auto reapply = [](State& s, const hetero::EditIntent& intent) {
    State next = s;
    auto out = hetero::ApplyIntent(&next.model, &next.checker, intent);
    if (!out.ok() || !out->applied) return false;
    s = std::move(next);
    return true;
  };
  State state{entry.model, entry.checker};
  auto out = redo ? entry.history.Redo(author, &state, reapply)
                  : entry.history.Undo(author, at_seq, &state, reapply);
  if (!out.ok()) return out;
  entry.model = std::move(state.model);
  entry.checker = std::move(state.checker);
  ++entry.version;
  return out;
}

void ModelBook::ReplayUndo(uint64_t seq, const codec::UndoRecord& r) {
  auto it = models_.find(r.object);
  if (it == models_.end() || seq <= it->second.file_seq) return;
  auto out = Undo(r.object, HistoryAuthor(r.client_id), r.redo, seq);
  if (!out.ok()) {
    spdlog::warn("{} of a model intent at seq {} refused on replay: {}", r.redo ? "redo" : "undo",
                 seq, out.status().ToString());
  }
}

std::pair<size_t, size_t> ModelBook::UndoDepth(const std::string& object,
                                               const std::string& author) const {
  auto it = models_.find(object);
  if (it == models_.end()) return {0, 0};
  return {it->second.history.undo_depth(author), it->second.history.redo_depth(author)};
}

std::vector<HistoryEntry> ModelBook::Entries(const std::string& object,
                                             const std::string& author) const {
  auto it = models_.find(object);
  if (it == models_.end()) return {};
  return it->second.history.Entries(author);
}

std::optional<ModelBook::Stamp> ModelBook::StampOf(const std::string& object) const {
  auto it = models_.find(object);
  if (it == models_.end()) return std::nullopt;
  return Stamp{it->second.version, ModelHash(it->second.model)};
}

StatusOr<ModelSummary> ModelBook::Info(const std::string& object) const {
  auto it = models_.find(object);
  if (it == models_.end()) return NotFound("object " + object + " holds no hyperpatch model");
  const Entry& entry = it->second;
  ModelSummary s;
  s.version = entry.version;
  s.hash = ModelHash(entry.model);
  s.cells = entry.model.cell_count();
  s.coefficients = entry.model.coefficient_count();
  s.json = hetero::ModelToJson(entry.model);
  return s;
}

// ---------------------------------------------------------------------------------------------
// The scene's model edit kind

StatusOr<ModelSummary> Scene::ModelInfo(const std::string& object) {
  std::promise<StatusOr<ModelSummary>> p;
  auto fail = [&p](const Status& st) { p.set_value(st); };
  Post("model info", fail, [&] { p.set_value(models_.Info(object)); });
  return p.get_future().get();
}

// A model intent: corner and cell checked against the model, then expanded by the library and
// checked for validity on a copy of the model (a rejection is answered with its reason, nothing
// logged); Apply puts the copy in place (ModelBook). The voxelised sculpture is not
// re-voxelised.
struct Scene::ModelOp final : EditOp {
  ModelOp(uint64_t client, codec::ModelEdit m, std::function<void(ModelOutcome)> d)
      : client(client), edit(std::move(m)), done(std::move(d)) {}
  const char* operation() const override { return "model intent"; }
  ResendStream stream() const override { return ResendStream::kModels; }
  uint64_t client_id() const override { return client; }
  uint64_t client_seq() const override { return edit.client_seq; }

  Status Prepare(Scene& scene, uint64_t first_seq, std::vector<std::string>* records) override {
    plan.emplace();
    if (Status s = scene.models_.PrepareIntent(edit, &*plan); !s.ok()) {
      if (plan->rejection) {
        rejection = plan->rejection;
        stamp = plan->now;
      }
      plan.reset();
      return s;
    }
    codec::ModelRecord rec;
    rec.global_seq = first_seq;
    rec.client_id = client;
    rec.edit = edit;
    rec.model_version = plan->version;
    records->push_back(codec::EncodeLogRecord(rec));
    seq = first_seq;
    return Status::Ok();
  }

  Applied Apply(Scene& scene) override {
    moved = plan->moved;
    stamp = scene.models_.ApplyIntent(std::move(*plan), seq, HistoryAuthor(client), edit.intent,
                                      WallClockMs());
    plan.reset();
    return Applied{};  // the voxels are not re-voxelised
  }

  void Duplicate(Scene& scene) override {
    if (auto s = scene.models_.StampOf(edit.object)) stamp = *s;
  }

  void Answer(const CommitOutcome& o) override {
    ModelOutcome a;
    a.status = o.status;
    a.client_seq = o.client_seq;
    if (rejection) {
      const hetero::Rejection& r = *rejection;
      a.rejection = ModelRejection{hetero::ReasonName(r.reason), r.cell, r.direction, r.span,
                                   r.ToString()};
    } else if (o.status.ok()) {
      a.duplicate = o.duplicate;
      if (!o.duplicate) {
        a.global_seq = o.global_seq_first;
        a.moved_coefficients = static_cast<uint32_t>(moved);
      }
    }
    a.model_version = stamp.version;
    a.model_hash = stamp.hash;
    done(std::move(a));
  }

  uint64_t client;
  codec::ModelEdit edit;
  std::function<void(ModelOutcome)> done;
  std::optional<ModelBook::IntentPlan> plan;
  std::optional<hetero::Rejection> rejection;
  uint64_t seq = 0;
  size_t moved = 0;
  ModelBook::Stamp stamp;
};

void Scene::EditModel(uint64_t client_id, codec::ModelEdit m,
                      std::function<void(ModelOutcome)> done) {
  Commit(std::make_shared<ModelOp>(client_id, std::move(m), AnswerOnce(std::move(done))));
}

}  // namespace sculpt::server
