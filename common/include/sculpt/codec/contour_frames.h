/// @brief The contour frames the server fans out (issue 6): a skin's contours (a snapshot or the
/// sections a ball edit changed, with the whole chain of balls) and an object's slice, each built
/// from domain values into one length-prefixed ServerMessage frame, serialized once and shared by
/// every session that sends it.
#ifndef SCULPT_CODEC_CONTOUR_FRAMES_H_
#define SCULPT_CODEC_CONTOUR_FRAMES_H_

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "sculpt/codec/shared_frame.h"
#include "sculpt/codec/skin_messages.h"

namespace sculpt::codec {

/// A ContourUpdate: a skin's (`skin` set) or an object's slice (`object` set).
struct ContourUpdateFrame {
  std::string skin;
  std::string object;
  /// skin::EncodeSkinSnapshot / EncodeSkinUpdate bytes, or skin::EncodeContours for a slice.
  std::string data;
  uint32_t sections = 0;        // sections the bytes carry (an update: the changed ones only)
  uint64_t global_seq = 0;      // slice: the edit sequence the cut shows
  uint64_t skin_version = 0;    // skin: edits applied to it since start
  std::vector<SkinBall> balls;  // skin: the whole chain at skin_version
};

/// The frame (4-byte little-endian length, then the serialized ServerMessage). Every value is
/// representable on the wire, so it does not fail.
SharedFrame EncodeContourUpdate(ContourUpdateFrame update);

}  // namespace sculpt::codec

#endif  // SCULPT_CODEC_CONTOUR_FRAMES_H_
