/// @brief JSON codecs of the cluster's etcd values (nlohmann::json).
#include "cluster/records.h"

#include <nlohmann/json.hpp>

namespace sculpt::server::cluster {
namespace {

using Json = nlohmann::json;

constexpr size_t kMaxText = 256;
constexpr size_t kMaxList = 1024;

StatusOr<Json> ParseObject(const char* what, const std::string& text) {
  Json j = Json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded() || !j.is_object()) {
    return Outside(what, text.substr(0, 64), "a JSON object");
  }
  return j;
}

Status Text(const Json& j, const std::string& field, bool required, std::string* out) {
  const auto it = j.find(field);
  if (it == j.end()) {
    return required ? Outside(field, "missing", "a string") : Status::Ok();
  }
  if (!it->is_string() || it->get_ref<const std::string&>().size() > kMaxText) {
    return Outside(field, it->dump().substr(0, 64),
                   "a string of at most " + std::to_string(kMaxText) + " bytes");
  }
  *out = it->get<std::string>();
  if (required && out->empty()) return Outside(field, "\"\"", "a non-empty string");
  return Status::Ok();
}

Status Count(const Json& j, const std::string& field, uint64_t* out) {
  const auto it = j.find(field);
  if (it == j.end() || !it->is_number_unsigned()) {
    return Outside(field, it == j.end() ? "missing" : it->dump().substr(0, 64),
                   "an unsigned integer");
  }
  *out = it->get<uint64_t>();
  return Status::Ok();
}

Status List(const Json& j, const std::string& field, std::vector<std::string>* out) {
  const auto it = j.find(field);
  if (it == j.end()) return Status::Ok();
  if (!it->is_array() || it->size() > kMaxList) {
    return Outside(field, it->dump().substr(0, 64),
                   "an array of at most " + std::to_string(kMaxList) + " strings");
  }
  for (const Json& x : *it) {
    if (!x.is_string() || x.get_ref<const std::string&>().size() > kMaxText) {
      return Outside(field, x.dump().substr(0, 64), "strings");
    }
    out->push_back(x.get<std::string>());
  }
  return Status::Ok();
}

// `following` / `owning`: an array of {"scene", "seq"[, "acks_async" (owning),
// "divergences" (following)]}.
Status ProgressList(const Json& j, const std::string& field, bool owner,
                    std::vector<SceneProgress>* out) {
  const auto it = j.find(field);
  if (it == j.end()) return Status::Ok();
  if (!it->is_array() || it->size() > kMaxList) {
    return Outside(field, it->dump().substr(0, 64),
                   "an array of at most " + std::to_string(kMaxList) + " objects");
  }
  for (const Json& x : *it) {
    if (!x.is_object()) return Outside(field, x.dump().substr(0, 64), "objects");
    SceneProgress p;
    SCULPT_RETURN_IF_ERROR(Text(x, "scene", true, &p.scene));
    SCULPT_RETURN_IF_ERROR(Count(x, "seq", &p.seq));
    if (const auto a = x.find("acks_async"); owner && a != x.end()) {
      if (!a->is_boolean()) return Outside("acks_async", a->dump().substr(0, 64), "true or false");
      p.acks_async = a->get<bool>();
    }
    if (!owner && x.contains("divergences")) {
      SCULPT_RETURN_IF_ERROR(Count(x, "divergences", &p.divergences));
    }
    out->push_back(std::move(p));
  }
  return Status::Ok();
}

const SceneProgress* Find(const std::vector<SceneProgress>& list, const std::string& scene) {
  for (const SceneProgress& p : list) {
    if (p.scene == scene) return &p;
  }
  return nullptr;
}

}  // namespace

const SceneProgress* MemberRecord::Following(const std::string& scene) const {
  return Find(following, scene);
}

const SceneProgress* MemberRecord::Owning(const std::string& scene) const {
  return Find(owning, scene);
}

std::string EncodeMember(const MemberRecord& m) {
  Json following = Json::array();
  for (const SceneProgress& p : m.following) {
    Json f = {{"scene", p.scene}, {"seq", p.seq}};
    if (p.divergences > 0) f["divergences"] = p.divergences;
    following.push_back(std::move(f));
  }
  Json owning = Json::array();
  for (const SceneProgress& p : m.owning) {
    owning.push_back({{"scene", p.scene}, {"seq", p.seq}, {"acks_async", p.acks_async}});
  }
  return Json{{"name", m.name},     {"tcp", m.tcp},   {"http", m.http},
              {"offers", m.offers}, {"owns", m.owns}, {"sessions", m.sessions},
              {"standby", m.standby}, {"follows", m.follows}, {"follow_seq", m.follow_seq},
              {"scene_seq", m.scene_seq}, {"acks_async", m.acks_async},
              {"following", following}, {"owning", owning}}
      .dump();
}

std::string EncodeStandby(const StandbyRecord& s) {
  return Json{{"member", s.member}, {"epoch", s.epoch}}.dump();
}

StatusOr<StandbyRecord> DecodeStandby(const std::string& text) {
  SCULPT_ASSIGN_OR_RETURN(Json j, ParseObject("standby record", text));
  StandbyRecord s;
  SCULPT_RETURN_IF_ERROR(Text(j, "member", true, &s.member));
  SCULPT_RETURN_IF_ERROR(Count(j, "epoch", &s.epoch));
  return s;
}

std::string EncodeMove(const MoveRecord& m) {
  return Json{{"member", m.member}, {"epoch", m.epoch}, {"released", m.released}}.dump();
}

StatusOr<MoveRecord> DecodeMove(const std::string& text) {
  SCULPT_ASSIGN_OR_RETURN(Json j, ParseObject("move record", text));
  MoveRecord m;
  SCULPT_RETURN_IF_ERROR(Text(j, "member", true, &m.member));
  SCULPT_RETURN_IF_ERROR(Count(j, "epoch", &m.epoch));
  if (const auto it = j.find("released"); it != j.end()) {
    if (!it->is_boolean()) return Outside("released", it->dump().substr(0, 64), "true or false");
    m.released = it->get<bool>();
  }
  return m;
}

std::string EncodeOwner(const OwnerRecord& o) {
  return Json{{"member", o.member}, {"tcp", o.tcp}, {"http", o.http}, {"epoch", o.epoch}}.dump();
}

std::string EncodeEpoch(const EpochRecord& e) {
  return Json{{"epoch", e.epoch}, {"member", e.member}}.dump();
}

StatusOr<MemberRecord> DecodeMember(const std::string& text) {
  SCULPT_ASSIGN_OR_RETURN(Json j, ParseObject("member record", text));
  MemberRecord m;
  SCULPT_RETURN_IF_ERROR(Text(j, "name", true, &m.name));
  SCULPT_RETURN_IF_ERROR(Text(j, "tcp", true, &m.tcp));
  SCULPT_RETURN_IF_ERROR(Text(j, "http", false, &m.http));
  SCULPT_RETURN_IF_ERROR(List(j, "offers", &m.offers));
  SCULPT_RETURN_IF_ERROR(List(j, "owns", &m.owns));
  uint64_t sessions = 0;
  SCULPT_RETURN_IF_ERROR(Count(j, "sessions", &sessions));
  m.sessions = static_cast<uint32_t>(std::min<uint64_t>(sessions, UINT32_MAX));
  // Written by members that know standbys (absent: an older member, which may not follow).
  if (const auto it = j.find("standby"); it != j.end()) {
    if (!it->is_boolean()) return Outside("standby", it->dump().substr(0, 64), "true or false");
    m.standby = it->get<bool>();
  } else {
    m.standby = false;
  }
  SCULPT_RETURN_IF_ERROR(Text(j, "follows", false, &m.follows));
  if (j.contains("follow_seq")) SCULPT_RETURN_IF_ERROR(Count(j, "follow_seq", &m.follow_seq));
  // Written by members since the eleventh session (absent: 0 and false).
  if (j.contains("scene_seq")) SCULPT_RETURN_IF_ERROR(Count(j, "scene_seq", &m.scene_seq));
  if (const auto it = j.find("acks_async"); it != j.end()) {
    if (!it->is_boolean()) return Outside("acks_async", it->dump().substr(0, 64), "true or false");
    m.acks_async = it->get<bool>();
  }
  // Written by members hosting several scenes (absent: one scene at most, from the fields above).
  SCULPT_RETURN_IF_ERROR(ProgressList(j, "following", false, &m.following));
  SCULPT_RETURN_IF_ERROR(ProgressList(j, "owning", true, &m.owning));
  if (!j.contains("following") && !m.follows.empty()) {
    m.following.push_back({m.follows, m.follow_seq, false});
  }
  if (!j.contains("owning") && !m.owns.empty()) {
    m.owning.push_back({m.owns.front(), m.scene_seq, m.acks_async});
  }
  return m;
}

StatusOr<OwnerRecord> DecodeOwner(const std::string& text) {
  SCULPT_ASSIGN_OR_RETURN(Json j, ParseObject("owner record", text));
  OwnerRecord o;
  SCULPT_RETURN_IF_ERROR(Text(j, "member", true, &o.member));
  SCULPT_RETURN_IF_ERROR(Text(j, "tcp", true, &o.tcp));
  SCULPT_RETURN_IF_ERROR(Text(j, "http", false, &o.http));
  SCULPT_RETURN_IF_ERROR(Count(j, "epoch", &o.epoch));
  if (o.epoch == 0) return Outside("epoch", "0", "[1, 2^64)");
  return o;
}

StatusOr<EpochRecord> DecodeEpoch(const std::string& text) {
  SCULPT_ASSIGN_OR_RETURN(Json j, ParseObject("epoch record", text));
  EpochRecord e;
  SCULPT_RETURN_IF_ERROR(Count(j, "epoch", &e.epoch));
  SCULPT_RETURN_IF_ERROR(Text(j, "member", true, &e.member));
  return e;
}

bool Keys::ParseSceneKey(const std::string& key, std::string* scene, std::string* kind) const {
  const std::string scenes = Scenes();
  if (key.compare(0, scenes.size(), scenes) != 0) return false;
  for (const char* k : {"/owner", "/epoch", "/standby", "/move"}) {
    const std::string suffix = k;
    if (key.size() > scenes.size() + suffix.size() &&
        key.compare(key.size() - suffix.size(), suffix.size(), suffix) == 0) {
      *scene = key.substr(scenes.size(), key.size() - scenes.size() - suffix.size());
      *kind = suffix.substr(1);
      return true;
    }
  }
  return false;
}

}  // namespace sculpt::server::cluster
