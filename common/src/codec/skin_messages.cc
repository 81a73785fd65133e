/// @brief Decoding of the skin messages off the wire: ball edits, sweeps, contour subscriptions.
#include "sculpt/codec/skin_messages.h"

#include <string>

#include "sculpt/core/check.h"
#include "sculpt/levelset/slice.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::codec {
namespace {

Status CheckName(const std::string& field, const std::string& name) {
  if (name.empty() || name.size() > kMaxSkinNameBytes) {
    return Outside(field, name,
                   std::string("names of 1..") + std::to_string(kMaxSkinNameBytes) + " bytes");
  }
  return Status::Ok();
}

Vec3 V(const v1::Vec3f& v) { return {v.x(), v.y(), v.z()}; }

}  // namespace

StatusOr<BallEdit> DecodeSkinBallEdit(const v1::SkinBallEdit& e) {
  SCULPT_RETURN_IF_ERROR(CheckName("SkinBallEdit.skin", e.skin()));
  if (e.op() < v1::SKIN_BALL_OP_ADD || e.op() > v1::SKIN_BALL_OP_ORIENT) {
    return Outside("SkinBallEdit.op", std::to_string(e.op()),
                   "{1 (ADD), 2 (MOVE), 3 (REMOVE), 4 (ORIENT)}");
  }
  if (e.index() >= kMaxSkinBalls) {
    return Outside("SkinBallEdit.index", std::to_string(e.index()),
                   std::string("[0, ") + std::to_string(kMaxSkinBalls - 1) + "]");
  }
  BallEdit out;
  out.client_seq = e.client_seq();
  out.skin = e.skin();
  out.op = static_cast<BallOp>(e.op());
  out.index = e.index();
  const v1::SkinBall& b = e.ball();
  const bool position = out.op == BallOp::kAdd || out.op == BallOp::kMove;
  const bool theta = out.op == BallOp::kAdd || out.op == BallOp::kOrient;
  if (position) {
    SCULPT_RETURN_IF_ERROR(
        CheckRange("SkinBallEdit.ball.x", b.x(), -kMaxSkinCoordinate, kMaxSkinCoordinate));
    SCULPT_RETURN_IF_ERROR(
        CheckRange("SkinBallEdit.ball.y", b.y(), -kMaxSkinCoordinate, kMaxSkinCoordinate));
    SCULPT_RETURN_IF_ERROR(
        CheckRange("SkinBallEdit.ball.r", b.r(), kMinSkinRadius, kMaxSkinCoordinate));
    out.x = b.x();
    out.y = b.y();
    out.r = b.r();
  }
  if (theta) {
    SCULPT_RETURN_IF_ERROR(
        CheckRange("SkinBallEdit.ball.theta", b.theta(), -kMaxSkinTheta, kMaxSkinTheta));
    out.theta = b.theta();
  }
  return out;
}

v1::SkinBallEdit EncodeSkinBallEdit(const BallEdit& e) {
  v1::SkinBallEdit out;
  out.set_client_seq(e.client_seq);
  out.set_skin(e.skin);
  out.set_op(static_cast<v1::SkinBallOp>(e.op));
  out.set_index(e.index);
  v1::SkinBall* b = out.mutable_ball();
  b->set_x(e.x);
  b->set_y(e.y);
  b->set_r(e.r);
  b->set_theta(e.theta);
  return out;
}

StatusOr<SkinSweepRequest> DecodeSkinSweep(const v1::SkinSweep& s) {
  SCULPT_RETURN_IF_ERROR(CheckName("SkinSweep.skin", s.skin()));
  SCULPT_RETURN_IF_ERROR(CheckName("SkinSweep.object", s.object()));
  if (s.mode() != v1::SKIN_SWEEP_MODE_EXTRUDE && s.mode() != v1::SKIN_SWEEP_MODE_REVOLVE) {
    return Outside("SkinSweep.mode", std::to_string(s.mode()), "{1 (EXTRUDE), 2 (REVOLVE)}");
  }
  if (s.kind() != v1::EDIT_KIND_ADD && s.kind() != v1::EDIT_KIND_SUBTRACT) {
    return Outside("SkinSweep.kind", std::to_string(s.kind()), "{2 (ADD), 3 (SUBTRACT)}");
  }
  SkinSweepRequest out;
  out.client_seq = s.client_seq();
  out.skin = s.skin();
  out.object = s.object();
  out.add = s.kind() == v1::EDIT_KIND_ADD;
  if (s.mode() == v1::SKIN_SWEEP_MODE_EXTRUDE) {
    out.mode = levelset::SweepRequest::Mode::kExtrude;
    SCULPT_RETURN_IF_ERROR(CheckRange("SkinSweep.depth", s.depth(), 0, kMaxSkinCoordinate));
    if (!(s.depth() > 0)) {
      return Outside("SkinSweep.depth", FormatNumber(s.depth()),
                     std::string("(0, ") + FormatNumber(kMaxSkinCoordinate) + "]");
    }
    out.depth = s.depth();
  } else {
    out.mode = levelset::SweepRequest::Mode::kRevolve;
    SCULPT_RETURN_IF_ERROR(
        CheckRange("SkinSweep.axis_x", s.axis_x(), -kMaxSkinCoordinate, kMaxSkinCoordinate));
    SCULPT_RETURN_IF_ERROR(
        CheckRange("SkinSweep.axis_y", s.axis_y(), -kMaxSkinCoordinate, kMaxSkinCoordinate));
    SCULPT_RETURN_IF_ERROR(
        CheckRange("SkinSweep.axis_angle", s.axis_angle(), -kMaxSkinTheta, kMaxSkinTheta));
    out.axis_x = s.axis_x();
    out.axis_y = s.axis_y();
    out.axis_angle = s.axis_angle();
  }
  return out;
}

StatusOr<ContourRequest> DecodeContourSubscribe(const v1::ContourSubscribe& c) {
  ContourRequest out;
  out.unsubscribe = c.unsubscribe();
  if (!c.skin().empty()) {
    SCULPT_RETURN_IF_ERROR(CheckName("ContourSubscribe.skin", c.skin()));
    out.skin = c.skin();
    return out;
  }
  if (!c.has_slice()) {
    return Outside("ContourSubscribe.skin", "", "names of 1..64 bytes (or set slice)");
  }
  const v1::ContourSlice& s = c.slice();
  SCULPT_RETURN_IF_ERROR(CheckName("ContourSubscribe.slice.object", s.object()));
  out.object = s.object();
  if (out.unsubscribe) return out;
  const levelset::SweepPlane plane{V(s.origin()), V(s.u()), V(s.v())};
  SCULPT_RETURN_IF_ERROR(levelset::ValidatePlane("ContourSubscribe.slice", plane));
  SCULPT_RETURN_IF_ERROR(CheckRange("ContourSubscribe.slice.step", s.step(), 1e-3, 1e3));
  SCULPT_RETURN_IF_ERROR(CheckRange("ContourSubscribe.slice.half_extent", s.half_extent(),
                                    s.step(), 0.5 * (levelset::kMaxSliceSamples - 1) * s.step()));
  out.plane = plane;
  out.half_extent = s.half_extent();
  out.step = s.step();
  return out;
}

}  // namespace sculpt::codec
