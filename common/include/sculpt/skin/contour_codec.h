/// @brief The contour codec: polylines as predicted, quantised, entropy-coded residuals, for thin
/// clients that follow skins (and slice contours of the sculpture) without meshes. A plain
/// library API: bytes in, bytes out, no networking.
///
/// Bound: every decoded point is within step/sqrt(2) (Euclidean) of the encoded one. SKC2 keeps
/// it as step/2 along and step/2 across the curve, SKC1 as step/2 in x and in y; the distance
/// bound is the same (0.707 of the tolerance at step = chord tolerance).
///
/// Two formats (all integers little-endian; "varint" = unsigned LEB128, "zz" = zigzag):
///
/// SKC2 (what the encoders write): magic "SKC2", kind byte (0 polyline set, 1 skin snapshot,
///   2 skin update), step as float64, coding byte 2, then the kind's counts as varints (polyline
///   set: polyline count; snapshot: section count; update: section count after the update,
///   splice_at, removed, inserted, changed count), then one adaptive binary range-coded body
///   (LZMA's scheme, 12-bit probabilities; signed integers as a zero flag, a sign, the bit length
///   in unary and the bit under the leading one, each with its own adaptive model, the lower bits
///   raw) to the end of the message holding, in order:
///   - skin messages: per section entry, the index (updates only) minus the previous index + 1,
///     the id minus the previous id + 1, the version minus the previous version;
///   - per polyline, its point count minus that of its context line (the previous line of the
///     same side in a skin message, the previous polyline in a set; 0 without one);
///   - per non-empty polyline: if its context line has points, a flag "starts where the context
///     line ends" (then the first point is that decoded point, and the context's last three points
///     start the prediction); else the first point as integers x/step, y/step minus the context's
///     last point rounded likewise (or the origin); then, for two points or more, a flag
///     "closed" (the last point equals the first: it is not coded, the decoder repeats the first);
///   - per later point: two integers a (along) and e (across). From the previous decoded points
///     p3, p2, p1 the decoder forms u = unit(p1 - p2), v = u turned left, the step length l1 =
///     |p1 - p2| scaled by the previous ratio l1/|p2 - p3| clamped to [0.95, 1/0.95] (lp), and the
///     parabola n(s) = c s (s + l1) through p3, p2, p1 in that frame (c = 0 for a turn over 45
///     degrees); the point is p1 + s u + (n(s) + e step) v with s = lp + a step. Double
///     arithmetic (+ - * / and sqrt only, in the order of contour_codec.cc), so the web client's
///     decoder (client/web/src/contour_codec.js) computes the same doubles.
///   Where doubles cannot place a point within the bound (coordinates near 2^52 steps), or an id
///   is 2^53 or more, the encoder writes SKC1 instead.
///
/// SKC1 (still decoded; written only as that fallback): magic "SKC1", kind byte, step as float64,
///   coding byte (0 varint residuals, 1 Draco rANS symbols), then the kind's header (below), then
///   per polyline: varint point count, zz varint x/step and y/step of its first point; then the
///   residual stream of every later point of every polyline, in order: 2 values per point.
///   A point's residual is its quantised position minus a prediction from the already decoded
///   points of the same polyline: the previous point for the 2nd, a constant step for the 3rd,
///   then the previous step turned and scaled like the one before it (constant curvature),
///   in integer plane coordinates. Coding 0 writes the zz residuals as varints; coding 1 hands
///   them to Draco's entropy coder (draco::EncodeSymbols), whichever is smaller is kept.
///   Skin snapshot header: varint section count; per section varint id, varint version; the
///   polylines are each section's + then - list.
///   Skin update header: varint section count after the update, varint splice_at, removed,
///   inserted, changed count; per changed section varint index, id, version; polylines as above
///   for the changed sections only.
#ifndef SCULPT_SKIN_CONTOUR_CODEC_H_
#define SCULPT_SKIN_CONTOUR_CODEC_H_

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "sculpt/core/status.h"
#include "sculpt/skin/skin.h"
#include "sculpt/skin/vec2.h"

namespace sculpt::skin {

/// Upper bounds a decoder enforces on untrusted input (points also to 65536 + 256 per message
/// byte in SKC1, + 512 per byte in SKC2).
inline constexpr uint64_t kMaxContourPoints = 1ull << 26;
inline constexpr uint64_t kMaxContourPolylines = 1ull << 24;

/// Encodes any set of polylines (e.g. slice contours of the sculpture), every decoded point
/// within step/sqrt(2) of its input. Lines that continue one another (each starting where the
/// previous ends) cost least. InvalidArgument for a step that is not finite and > 0, a
/// non-finite point, or a point whose |coordinate| / step exceeds 2^52.
StatusOr<std::string> EncodeContours(const std::vector<Polyline2>& polylines, double step);
/// Decodes EncodeContours' output. DataLoss / InvalidArgument naming what is wrong for
/// truncated, oversized or malformed input; never reads past `bytes`.
StatusOr<std::vector<Polyline2>> DecodeContours(std::string_view bytes);

/// One section as a thin client holds it.
struct SectionContour {
  uint64_t id = 0, version = 0;
  Polyline2 plus, minus;
};

/// Every section of the skin. `step` <= 0 uses the skin's chord tolerance; a step larger than
/// the chord tolerance is refused (InvalidArgument).
StatusOr<std::string> EncodeSkinSnapshot(const Skin& skin, double step = 0);
/// Only the sections an edit changed (section id + version), and the splice it made.
StatusOr<std::string> EncodeSkinUpdate(const Skin& skin, const SkinChange& change,
                                       double step = 0);

/// A thin client's copy of a skin's contours: applies snapshots and updates in order. Not
/// thread-safe; a value type.
class ContourView {
 public:
  /// Applies a snapshot (replaces everything) or an update (splice, then changed sections).
  /// On error the view is unchanged.
  Status Apply(std::string_view bytes);
  const std::vector<SectionContour>& sections() const { return sections_; }
  double step() const { return step_; }
  /// The + or - list of the whole chain, joints once (as Skin::Chain).
  Polyline2 Chain(int side) const;

 private:
  std::vector<SectionContour> sections_;
  double step_ = 0;
};

}  // namespace sculpt::skin

#endif  // SCULPT_SKIN_CONTOUR_CODEC_H_
