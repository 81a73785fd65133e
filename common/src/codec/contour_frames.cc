/// @brief Contour frames: domain values to one shared, length-prefixed ServerMessage.
#include "sculpt/codec/contour_frames.h"

#include <utility>

#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::codec {

SharedFrame EncodeContourUpdate(ContourUpdateFrame update) {
  v1::ServerMessage m;
  v1::ContourUpdate* u = m.mutable_contour();
  u->set_skin(std::move(update.skin));
  u->set_object(std::move(update.object));
  u->set_data(std::move(update.data));
  u->set_sections(update.sections);
  u->set_global_seq(update.global_seq);
  u->set_skin_version(update.skin_version);
  for (const SkinBall& b : update.balls) {
    v1::SkinBall* w = u->add_balls();
    w->set_x(b.x);
    w->set_y(b.y);
    w->set_r(b.r);
    w->set_theta(b.theta);
  }
  return EncodeSharedFrame(m);
}

}  // namespace sculpt::codec
