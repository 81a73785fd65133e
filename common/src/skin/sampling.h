/// @brief Internal: chord-tolerance sampling of offsets, A-splines and caps, and the polyline
/// predicates the validation uses (crossings, winding, distances).
#ifndef SCULPT_SKIN_INTERNAL_SAMPLING_H_
#define SCULPT_SKIN_INTERNAL_SAMPLING_H_

#include <functional>

#include "sculpt/skin/curves.h"
#include "sculpt/skin/skin.h"
#include "sculpt/skin/vec2.h"

namespace sculpt::skin::internal {

/// Appends samples of the offset on [ta, tb] to `out`, excluding the point at ta when
/// `skip_first`. Adaptive recursive subdivision from 8 uniform intervals until the chord
/// deviation at the mid and quarter points is within `tol` (digest §8.5).
void SampleOffset(const Offset& off, double ta, double tb, double tol, bool skip_first,
                  Polyline2& out);
/// Samples a whole side as one curve f(u), u in [0, pieces] (piece j on [j, j+1]), so the spacing
/// stays smooth across the joints between pieces; the joints themselves need not be samples.
void SampleSide(const std::function<Vec2(double)>& f, int pieces, double tol, Polyline2& out);
/// SampleSide for the contour codec: where `cursor` carries SKC4's decoder state from the side's
/// previous section (the side's first point, f(0), then being that section's last), each next
/// sample is the point of the curve at the chord the decoder predicts (found on the true curve),
/// kept where the chord is within `tol` of the curve, else the longest chord on the codec's
/// lattice that is (an escape). Without a valid cursor, SampleSide. `tol` is also the codec's
/// step. The caller traces the finished polyline (Skc4Trace) for the next section's cursor.
void SampleSideForCodec(const std::function<Vec2(double)>& f, int pieces, double tol,
                        const CodecCursor& cursor, Polyline2& out);
/// Appends samples of the A-spline from P0 to P2, same rule on the pencil angle.
void SampleASpline(const ASpline& s, double tol, bool skip_first, Polyline2& out);

/// Pairs of non-adjacent segments that cross properly. `closed` joins the last point to the
/// first (and treats that segment as adjacent to both ends).
int CountCrossings(const Polyline2& pts, bool closed);
/// Winding number of `p` around the closed polygon `pts`.
int Winding(const Polyline2& pts, Vec2 p);
/// Distance from `p` to the closed polygon `pts`.
double DistanceToClosed(const Polyline2& pts, Vec2 p);

}  // namespace sculpt::skin::internal

#endif  // SCULPT_SKIN_INTERNAL_SAMPLING_H_
