/// @brief The skin messages off the wire (issue 6) decoded into domain types: a ball edit, a
/// sweep of a skin into an object, and a contour subscription (a skin or a slice of an object).
/// Each Decode* checks every field the message's kind uses and names field, value and range.
#ifndef SCULPT_CODEC_SKIN_MESSAGES_H_
#define SCULPT_CODEC_SKIN_MESSAGES_H_

#include <cstddef>
#include <cstdint>
#include <string>

#include "sculpt/core/status.h"
#include "sculpt/levelset/sweep.h"

namespace sculpt::v1 {
class SkinBallEdit;
class SkinSweep;
class ContourSubscribe;
}  // namespace sculpt::v1

namespace sculpt::codec {

/// Limits of a skin's balls (scene configuration and wire alike), world units and radians.
inline constexpr size_t kMaxSkinBalls = 4096;
inline constexpr double kMaxSkinCoordinate = 1e6;
inline constexpr double kMinSkinRadius = 1e-3;
inline constexpr double kMaxSkinTheta = 64;
/// Longest skin or object name a skin message may carry, in bytes.
inline constexpr size_t kMaxSkinNameBytes = 64;

/// What a ball edit does to the ball at `index` (values as on the wire).
enum class BallOp : uint8_t { kAdd = 1, kMove = 2, kRemove = 3, kOrient = 4 };

/// A validated ball edit. The ball fields the op does not use are 0 (move: theta; orient: x, y,
/// r; remove: all), so no unchecked number reaches the scene or its edit log.
struct BallEdit {
  uint64_t client_seq = 0;
  std::string skin;
  BallOp op = BallOp::kAdd;
  /// Below kMaxSkinBalls; checked against the skin's ball count by the scene.
  uint32_t index = 0;
  double x = 0, y = 0, r = 0, theta = 0;
};

/// A ball of a skin as skin files and contour updates carry it (world units, radians).
struct SkinBall {
  double x = 0, y = 0, r = 0, theta = 0;
};

/// Checks a SkinBallEdit: skin name 1..64 bytes, op in {ADD, MOVE, REMOVE, ORIENT}, index below
/// kMaxSkinBalls, the ball fields the op uses finite with |x|, |y| <= kMaxSkinCoordinate,
/// r in [kMinSkinRadius, kMaxSkinCoordinate], |theta| <= kMaxSkinTheta. InvalidArgument
/// "SkinBallEdit.<field>=<value> outside <range>" (or "... is not finite").
StatusOr<BallEdit> DecodeSkinBallEdit(const v1::SkinBallEdit& edit);
/// The wire form of a decoded ball edit, which the edit log's SkinEditRecord embeds; decoding it
/// gives `edit` back.
v1::SkinBallEdit EncodeSkinBallEdit(const BallEdit& edit);

/// A validated sweep request: the scene adds the skin's outline and plane.
struct SkinSweepRequest {
  uint64_t client_seq = 0;
  std::string skin;
  std::string object;
  levelset::SweepRequest::Mode mode = levelset::SweepRequest::Mode::kExtrude;
  bool add = true;  // EDIT_KIND_ADD; false: EDIT_KIND_SUBTRACT
  /// Extrude: in (0, kMaxSkinCoordinate]; 0 for a revolution.
  double depth = 0;
  /// Revolve: the axis through (axis_x, axis_y) at axis_angle radians; 0 for an extrusion.
  double axis_x = 0, axis_y = 0, axis_angle = 0;
};

/// Checks a SkinSweep: skin and object names 1..64 bytes, mode EXTRUDE or REVOLVE, kind ADD or
/// SUBTRACT, an extrusion's depth in (0, kMaxSkinCoordinate], a revolution's axis point within
/// ±kMaxSkinCoordinate and angle within ±kMaxSkinTheta. InvalidArgument naming the field.
StatusOr<SkinSweepRequest> DecodeSkinSweep(const v1::SkinSweep& sweep);

/// A validated contour subscription: a skin's contours (`skin` set) or a slice of `object`.
struct ContourRequest {
  std::string skin;
  std::string object;  // a slice's object (empty for a skin)
  bool unsubscribe = false;
  /// A slice's plane, half extent and sample step (unset when unsubscribing).
  levelset::SweepPlane plane;
  double half_extent = 0;
  double step = 0;
};

/// Checks a ContourSubscribe: a skin name 1..64 bytes, or a slice whose object name is 1..64
/// bytes and, unless unsubscribing, whose plane is finite with unit orthogonal axes, step in
/// [1e-3, 1e3] and half extent in [step, (levelset::kMaxSliceSamples - 1) / 2 steps].
/// InvalidArgument naming the field.
StatusOr<ContourRequest> DecodeContourSubscribe(const v1::ContourSubscribe& request);

}  // namespace sculpt::codec

#endif  // SCULPT_CODEC_SKIN_MESSAGES_H_
