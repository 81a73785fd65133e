/// @brief The contour codec: polylines as predicted, quantised, entropy-coded residuals, for thin
/// clients that follow skins (and slice contours of the sculpture) without meshes. A plain
/// library API: bytes in, bytes out, no networking.
///
/// Bound: every decoded point is within step/sqrt(2) (Euclidean) of the encoded one. SKC3 keeps
/// it as the covering radius of a hexagonal lattice in the curve's frame, SKC2 as step/2 along
/// and step/2 across the curve, SKC1 as step/2 in x and in y; the distance bound is the same
/// (0.707 of the tolerance at step = chord tolerance).
///
/// Four formats (all integers little-endian; "varint" = unsigned LEB128, "zz" = zigzag):
///
/// SKC4 (what EncodeSkinSnapshot and EncodeSkinUpdate write for a skin built with
///   SkinOptions::sample_for_codec, the default; SKC3 otherwise): SKC3 below with magic "SKC4" and
///   coding byte 4, bit for bit, but for the predicted chord: after each point, with h = 2 len +
///   (e & 1) and omega the turtle's new turn, lp = floor(h / 2) for h <= 0; else with lo = h -
///   floor(h / 4), hi = h + floor(h / 4) + 2, g = hi if omega = 0, else c = sqrt(20000 min(h,
///   2^20) / |omega|) (doubles, in that order) and g = lo if c < lo, hi if c > hi, floor(c)
///   otherwise; lp = floor(g / 2). That is the chord rule: the chord whose sagitta is 0.59 of the
///   step on the curvature the last chord and turn show. The skin's sampler (SkinOptions::
///   sample_for_codec) places each side's samples at that predicted chord, found on the true
///   curve, from the decoder state the previous section's side ends with, shortening only where
///   the chord would leave the tolerance; so most along integers of a snapshot are 0 (the others
///   are those escapes, each side's last point and a restart's first chord). A codec restart
///   section (Skin::CodecRestart, about one in four) is sampled from a state of its own, and its
///   sides are coded anew: join flag 0 although they start where the previous section's end, so
///   the first point on the absolute grid and the first direction sent (no format change: any
///   SKC3 line may be coded so). Polyline sets stay SKC3; a message under 4096 points also tries
///   SKC3 and SKC2 and keeps the smallest.
///
/// SKC3 (what EncodeContours writes, and the skin encoders without sample_for_codec): the header of SKC2 below with magic "SKC3" and coding byte 3,
///   then the body: varint length and bytes of the side information, varint length and bytes of
///   the symbol stream, then the raw bits to the end of the message.
///   - Side information: one range-coded stream (SKC2's coder and integer binarisation, each kind
///     of value with its own models) holding the section entries and point counts exactly as SKC2
///     codes them; then 13 frequency tables (per table its symbol count n <= 92, then n
///     frequencies summing to 1024, or n = 0 for an unused table); then per non-empty line as in
///     SKC2 the join flag, the first point (when not joined) and the closed flag, and, when the
///     line codes two points or more and carries no turtle (below), its first direction as 14 raw
///     bits (angle units of 2 pi / 2^14).
///   - Symbol stream: rANS with 10-bit frequencies, two 32-bit states (initial and final value
///     2^16), 16-bit little-endian words, the states first (state 0 then state 1, high word
///     first); a state below 2^16 after a symbol reads one word. Along integers use state 0 and
///     tables 0-3, across integers state 1 and tables 4-12.
///   - Tokens: an integer v becomes z = zz(v); z < 16 is symbol z; otherwise with b = bit length
///     of z, symbol 16 + 2 (b - 5) + (bit b-2 of z) and the b - 2 bits under it go to the raw bits
///     (least significant first, packed from each byte's low end).
///   - Per later point of a line, an along integer a then an across integer e place the point by
///     the line's turtle: direction theta, turn omega, predicted chord lp and last chord l1 (all
///     integers), and the last magnitude classes (0, 1, 2+) of a and e, which pick the tables
///     (along: that of the previous a, or 3 for a line's first point after a sent direction;
///     across: 4 + 3 class(previous e) + class(a)). With th = (theta + omega) mod 2^14, u =
///     (C[th], C[th - 2^12]) (C the cosine table built as contour_codec_skc3.cc builds it) and v
///     = u turned left, the chord len = lp + a, and the point is p + ((2 len + (e & 1)) hs) u +
///     (e vs) v with hs = step 0.6123718516919304 and vs = step 1.060659160255457. Then, with
///     lc = clamp(len, 1, 4096) and d = (clamp(e, -lc, lc) floor(147996223 / lc)) >> 16:
///     theta = (th + d) mod 2^14, omega = clamp(omega + d, -2^11, 2^11), and with h = 2 len +
///     (e & 1) (the chord in half spacings), lp = floor((h + clamp(h - l1, -m, m)) / 2) with
///     m = floor(13 h / 256) (0 for h <= 0), l1 = h. A line
///     that joins its context line carries that line's final turtle, if it has one; else its
///     turtle starts at 0 with the sent direction. Double arithmetic in the order of
///     contour_codec_skc3.cc, so the web client's decoder computes the same doubles.
///   The encoder writes SKC2 instead where that is smaller (messages under 4096 points, where
///   SKC3's tables do not pay), and where SKC3 cannot place a point (chords beyond 2^40 steps).
///
/// SKC2 (still decoded; written where smaller than SKC3 or where SKC3 cannot place a point):
///   magic "SKC2", kind byte (0 polyline set, 1 skin snapshot,
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
///   is 2^53 or more, the encoder writes SKC1 instead (of SKC3 or SKC2).
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
/// byte in SKC1, + 512 per byte in SKC2 and SKC3).
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
