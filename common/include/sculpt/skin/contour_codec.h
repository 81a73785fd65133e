/// @brief The contour codec: polylines as quantised, predicted, zigzag-coded integers, for thin
/// clients that follow skins (and slice contours of the sculpture) without meshes. A plain
/// library API: bytes in, bytes out, no networking.
///
/// Format (all integers little-endian; "varint" = unsigned LEB128, "zz" = zigzag of a signed
/// value):
///   magic "SKC1", kind byte (0 polyline set, 1 skin snapshot, 2 skin update), step as float64,
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
/// Every decoded point is within step/2 of the encoded one in x and in y.
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
/// byte).
inline constexpr uint64_t kMaxContourPoints = 1ull << 26;
inline constexpr uint64_t kMaxContourPolylines = 1ull << 24;

/// Encodes any set of polylines (e.g. slice contours of the sculpture) with positions quantised
/// to `step`. InvalidArgument for a step that is not finite and > 0, a non-finite point, or a
/// point whose |coordinate| / step exceeds 2^52.
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
