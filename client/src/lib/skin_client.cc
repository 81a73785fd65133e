/// @brief SkinClient: ball edits, sweeps, and the contour views of followed skins and slices.
#include "sculpt/client/skin_client.h"

#include <spdlog/spdlog.h>

namespace sculpt::client {

SkinClient::SkinClient(Client& client) : client_(client) {
  client_.SetReplicationHandler([this](v1::ServerMessage&& m) { OnMessage(std::move(m)); });
}

SkinClient::~SkinClient() { client_.SetReplicationHandler(nullptr); }

// Runs on the client's I/O thread under its lock: decoding a contour message is a bounded,
// local step and never calls back into the Client.
void SkinClient::OnMessage(v1::ServerMessage&& m) {
  std::lock_guard<std::mutex> lock(mu_);
  if (m.has_skin_ack()) {
    acks_[m.skin_ack().client_seq()] = m.skin_ack();
  } else if (m.has_contour()) {
    const v1::ContourUpdate& u = m.contour();
    bytes_ += u.data().size();
    if (!u.skin().empty()) {
      Followed& f = skins_[u.skin()];
      if (const Status st = f.view.Apply(u.data()); !st.ok()) {
        ++decode_errors_;
        spdlog::warn("skin {}: contour update not applied: {}", u.skin(), st.ToString());
      } else {
        f.version = u.skin_version();
        f.sections.push_back(u.sections());
        f.balls.clear();
        for (const v1::SkinBall& b : u.balls()) f.balls.push_back({{b.x(), b.y()}, b.r(), b.theta()});
      }
    } else {
      auto lines = skin::DecodeContours(u.data());
      if (!lines.ok()) {
        ++decode_errors_;
      } else {
        SliceView& s = slices_[u.object()];
        s.lines = std::move(lines).value();
        s.seq = u.global_seq();
        s.any = true;
      }
    }
  } else {
    return;
  }
  cv_.notify_all();
}

StatusOr<uint64_t> SkinClient::Send(v1::ClientMessage m, uint64_t seq) {
  SCULPT_RETURN_IF_ERROR(client_.SendMessage(m));
  return seq;
}

StatusOr<uint64_t> SkinClient::SendEdit(v1::SkinBallEdit edit) {
  uint64_t seq;
  {
    std::lock_guard<std::mutex> lock(mu_);
    seq = next_seq_++;
  }
  edit.set_client_seq(seq);
  v1::ClientMessage m;
  *m.mutable_skin_ball_edit() = std::move(edit);
  return Send(std::move(m), seq);
}

StatusOr<uint64_t> SkinClient::AddBall(const std::string& skin, uint32_t index,
                                       const skin::OrientedBall& b) {
  v1::SkinBallEdit e;
  e.set_skin(skin);
  e.set_op(v1::SKIN_BALL_OP_ADD);
  e.set_index(index);
  e.mutable_ball()->set_x(b.c.x);
  e.mutable_ball()->set_y(b.c.y);
  e.mutable_ball()->set_r(b.r);
  e.mutable_ball()->set_theta(b.theta);
  return SendEdit(std::move(e));
}

StatusOr<uint64_t> SkinClient::MoveBall(const std::string& skin, uint32_t index, skin::Vec2 c,
                                        double r) {
  v1::SkinBallEdit e;
  e.set_skin(skin);
  e.set_op(v1::SKIN_BALL_OP_MOVE);
  e.set_index(index);
  e.mutable_ball()->set_x(c.x);
  e.mutable_ball()->set_y(c.y);
  e.mutable_ball()->set_r(r);
  return SendEdit(std::move(e));
}

StatusOr<uint64_t> SkinClient::OrientBall(const std::string& skin, uint32_t index, double theta) {
  v1::SkinBallEdit e;
  e.set_skin(skin);
  e.set_op(v1::SKIN_BALL_OP_ORIENT);
  e.set_index(index);
  e.mutable_ball()->set_theta(theta);
  return SendEdit(std::move(e));
}

StatusOr<uint64_t> SkinClient::RemoveBall(const std::string& skin, uint32_t index) {
  v1::SkinBallEdit e;
  e.set_skin(skin);
  e.set_op(v1::SKIN_BALL_OP_REMOVE);
  e.set_index(index);
  return SendEdit(std::move(e));
}

StatusOr<uint64_t> SkinClient::Sweep(v1::SkinSweep sweep) {
  uint64_t seq;
  {
    std::lock_guard<std::mutex> lock(mu_);
    seq = next_seq_++;
  }
  sweep.set_client_seq(seq);
  v1::ClientMessage m;
  *m.mutable_skin_sweep() = std::move(sweep);
  return Send(std::move(m), seq);
}

Status SkinClient::FollowSkin(const std::string& skin) {
  v1::ClientMessage m;
  m.mutable_contour_subscribe()->set_skin(skin);
  return client_.SendMessage(m);
}

Status SkinClient::FollowSlice(const v1::ContourSlice& slice) {
  v1::ClientMessage m;
  *m.mutable_contour_subscribe()->mutable_slice() = slice;
  return client_.SendMessage(m);
}

StatusOr<v1::SkinAck> SkinClient::WaitAck(uint64_t seq, std::chrono::milliseconds timeout) {
  std::unique_lock<std::mutex> lock(mu_);
  if (!cv_.wait_for(lock, timeout, [&] { return acks_.count(seq) > 0; })) {
    return Status(Status::Code::kUnavailable,
                  "no SkinAck for client_seq " + std::to_string(seq));
  }
  return acks_.at(seq);
}

bool SkinClient::WaitSkinVersion(const std::string& skin, uint64_t version,
                                 std::chrono::milliseconds timeout) {
  std::unique_lock<std::mutex> lock(mu_);
  return cv_.wait_for(lock, timeout, [&] {
    auto it = skins_.find(skin);
    return it != skins_.end() && !it->second.sections.empty() && it->second.version >= version;
  });
}

bool SkinClient::WaitSlice(const std::string& object, uint64_t seq,
                           std::chrono::milliseconds timeout) {
  std::unique_lock<std::mutex> lock(mu_);
  return cv_.wait_for(lock, timeout, [&] {
    auto it = slices_.find(object);
    return it != slices_.end() && it->second.any && it->second.seq >= seq;
  });
}

skin::ContourView SkinClient::View(const std::string& skin) const {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = skins_.find(skin);
  return it == skins_.end() ? skin::ContourView{} : it->second.view;
}

std::vector<uint32_t> SkinClient::UpdateSections(const std::string& skin) const {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = skins_.find(skin);
  return it == skins_.end() ? std::vector<uint32_t>{} : it->second.sections;
}

std::vector<skin::OrientedBall> SkinClient::Balls(const std::string& skin) const {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = skins_.find(skin);
  return it == skins_.end() ? std::vector<skin::OrientedBall>{} : it->second.balls;
}

std::vector<skin::Polyline2> SkinClient::Slice(const std::string& object) const {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = slices_.find(object);
  return it == slices_.end() ? std::vector<skin::Polyline2>{} : it->second.lines;
}

uint64_t SkinClient::contour_bytes() const {
  std::lock_guard<std::mutex> lock(mu_);
  return bytes_;
}

uint64_t SkinClient::decode_errors() const {
  std::lock_guard<std::mutex> lock(mu_);
  return decode_errors_;
}

}  // namespace sculpt::client
