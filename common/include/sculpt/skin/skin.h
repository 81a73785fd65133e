/// @brief Skin: the G1 skin of an ordered chain of oriented balls (seed 004), built section by
/// section with the naive, offset or hybrid construction, validated per section, sampled to
/// polylines with a chord tolerance, and edited incrementally (one ball rebuilds its two
/// sections, and with the codec's sampler those up to the next codec restart).
#ifndef SCULPT_SKIN_SKIN_H_
#define SCULPT_SKIN_SKIN_H_

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "sculpt/core/status.h"
#include "sculpt/skin/curves.h"
#include "sculpt/skin/oriented_ball.h"
#include "sculpt/skin/vec2.h"

namespace sculpt::skin {

/// The three constructions of the thesis (digest §3.2, §3.4, §3.5).
enum class Method { kNaive, kOffset, kHybrid };

/// "naive", "offset", "hybrid".
const char* MethodName(Method m);
/// Parses a method name; InvalidArgument naming the value and the allowed set otherwise.
StatusOr<Method> ParseMethod(const std::string& name);

/// Build parameters. Value type.
struct SkinOptions {
  Method method = Method::kHybrid;
  /// Maximum distance between the polylines and the exact curves. <= 0: 1e-3 of the smallest
  /// radius at Build time (digest §8.6), kept fixed through later edits so that an edit
  /// never touches unrelated sections.
  double chord_tolerance = 0;
  /// A-spline shape parameter; <= 0 picks the circle-reproducing default per section.
  double delta = 0;
  /// Sample each side where the contour codec's SKC4 decoder will predict its points (each chord
  /// still within the chord tolerance), from the previous section's decoder state, so that a
  /// snapshot at step = chord tolerance codes almost no along offsets (docs/benchmarks.md,
  /// "Contour bytes"). Restart sections (Skin::CodecRestart: the first, and those whose first
  /// ball hashes to 0 modulo kCodecRestartPeriod) start from a state of their own instead, so
  /// the points stay a function of the balls: an edit also rebuilds the sections after the ones
  /// it touches, up to the next restart (about kCodecRestartPeriod of them), and a skin rebuilt
  /// from its balls equals the edited one point for point. Off: chords from the true curve's
  /// curvature alone, each section on its own.
  bool sample_for_codec = true;
};

/// One piece of one side of a section: an offset of the mother on [tau_a, tau_b] or an A-spline.
/// The end tangents are analytic unit tangents (not from the polyline).
struct SkinPiece {
  enum class Kind { kOffset, kASpline };
  Kind kind = Kind::kOffset;
  double tau_a = 0, tau_b = 1;  // mother parameters the piece spans
  ASpline spline;               // kASpline only
  Vec2 start, end;              // exact end points
  Vec2 start_tangent, end_tangent;
};

/// Diagnostics of one side (+ = right of the travel direction, - = left).
struct SideReport {
  /// min over the section of 1 + side kappa d for this side's offset of the mother (digest
  /// Thm 2.3): the offset construction would loop where it is negative; reported whatever pieces
  /// the side actually uses.
  double min_one_plus_kd = 1;
  int offset_pieces = 0;
  int aspline_pieces = 0;
  /// Pairs of non-adjacent crossing segments in this side's polyline.
  int self_intersections = 0;
  /// min over the side's polyline points of |p - C_j| - r_j over the section's two balls.
  double clearance = 0;
};

/// The validation report of one section (digest §8.7): a section is total only when every check
/// passed on its sampled closed contour (Def 2.3-2.5).
struct SectionReport {
  bool mother_regular = true;  // min |p'| > 1e-6 L
  bool end_reversed = false;   // an offset piece runs against t_i at a ball (not G1 there)
  bool simple = false;         // the closed contour (both sides and the caps) does not cross
  bool total = false;          // simple, and both balls inside within the chord tolerance
  double clearance = 0;        // min of the two sides' clearances
  std::array<SideReport, 2> side;  // [0] = +, [1] = -
  std::vector<OrientedBall> hidden;  // hybrid: the hidden balls at the mother's inflections
  std::vector<std::string> notes;    // why the section is not total, fallbacks taken
};

/// Where the contour codec's SKC4 decoder stands at the end of a side's polyline in a snapshot
/// (its turtle and last decoded point, contour_codec.h). The sampler places the next section's
/// side where that decoder predicts its points, so that they cost no along offset. Opaque.
struct CodecCursor {
  int32_t theta = 0, omega = 0;
  int64_t lp = 0, l1 = 0;
  int actx = 0, mag_e = 0;
  bool valid = false;      // the decoder carries a turtle
  bool has_point = false;  // p is the decoded last point
  Vec2 p;
};

/// One section (balls k and k+1): its pieces, polylines and report. `id` is stable across edits
/// of other sections; `version` increases each time the section is rebuilt.
struct Section {
  uint64_t id = 0;
  uint64_t version = 0;
  std::array<std::vector<SkinPiece>, 2> pieces;  // [0] = +, [1] = -
  Polyline2 plus, minus;  // from P_k^± to P_{k+1}^±, both ends included
  SectionReport report;
  std::array<CodecCursor, 2> codec_end;  // [0] = +, [1] = -: SKC4's decoder after this section
  /// Sampled for the codec from a state of its own (Skin::CodecRestart): the encoder codes its
  /// sides anew, not joined to the previous section's.
  bool codec_restart = false;
};

/// About one section in this many is a codec restart (SkinOptions::sample_for_codec): the
/// sections an edit rebuilds and sends past its own two, on average, against the bytes a restart
/// costs (its sides' first point, direction and chord sent in full). Measured on the benchmark's
/// 1,000-ball skin (docs/benchmarks.md, "Contour bytes"): 4 gives a snapshot 5 % larger than
/// no restarts and updates of 4.7 sections; 8, 3 % and 8.2; 16, 1.6 % and 14.3.
inline constexpr uint64_t kCodecRestartPeriod = 4;

/// Totals over the sections.
struct SkinSummary {
  size_t sections = 0, total = 0, simple = 0, points = 0;
  double min_clearance = 0;
  bool all_total() const { return sections > 0 && total == sections; }
};

/// What an edit changed: the indices (after the edit) of the sections rebuilt or created, and the
/// splice it made in the section list (at `splice_at`, `removed` old sections replaced by
/// `inserted` new ones; both 0 for SetBall). The contour codec sends exactly this.
struct SkinChange {
  std::vector<size_t> changed;
  size_t splice_at = 0, removed = 0, inserted = 0;
};

/// The skin of a chain of at least two oriented balls. Not thread-safe; a value type (copyable).
class Skin {
 public:
  /// Validates the balls (ValidateChain) and the options, then builds every section (O(n)).
  /// InvalidArgument naming the field, value and range for bad input; the skin is not built.
  static StatusOr<Skin> Build(std::vector<OrientedBall> balls, const SkinOptions& options = {});

  /// Replaces ball i and rebuilds sections i-1 and i (those that exist): at most two, whatever
  /// the chain length (digest Conclusions); with sample_for_codec also the sections after them
  /// up to the next codec restart. On error (bad index, bad ball, a pair made inadmissible) the
  /// skin is unchanged.
  StatusOr<SkinChange> SetBall(size_t i, const OrientedBall& ball);
  /// Inserts a ball before index i (i == ball count appends): the section it splits is replaced
  /// by two new ones (one at either end of the chain).
  StatusOr<SkinChange> InsertBall(size_t i, const OrientedBall& ball);
  /// Removes ball i (at least two must remain): its two sections become one (none at an end).
  StatusOr<SkinChange> RemoveBall(size_t i);

  const std::vector<OrientedBall>& balls() const { return balls_; }
  const SkinOptions& options() const { return options_; }
  double chord_tolerance() const { return options_.chord_tolerance; }
  const std::vector<Section>& sections() const { return sections_; }
  /// Whether section k (from ball k) is sampled for the codec from a state of its own: k = 0,
  /// or ball k's bits hash to 0 modulo kCodecRestartPeriod. A function of ball k alone, so an
  /// edit moves restarts only at the balls it changes.
  bool CodecRestart(size_t k) const;
  const Section& section(size_t k) const { return sections_[k]; }

  /// The closed contour of section k (digest Def 2.3): + side, the front cap on ball k+1 from
  /// P+ to P-, the - side reversed, the rear cap on ball k from P- to P+; counter-clockwise, the
  /// first point not repeated at the end.
  Polyline2 SectionOutline(size_t k) const;
  /// The whole partial contour (digest Def 2.7, §4): the + chain, the front cap on the last ball,
  /// the - chain reversed, the rear cap on the first ball; closed, first point not repeated.
  Polyline2 Outline() const;
  /// The + chain (or - chain) as one list, consecutive sections sharing their end point once
  /// (digest §4 final format).
  Polyline2 Chain(int side) const;
  SkinSummary Summary() const;

 private:
  Skin() = default;
  Section MakeSection(size_t k);
  /// Rebuilds section k in place (same id, next version) and lists it in `change`.
  void Rebuild(size_t k, SkinChange& change);
  /// With sample_for_codec: rebuilds the sections after `change`'s last one up to the next
  /// codec restart (each is sampled from its predecessor's decoder state) and lists them.
  void FollowToRestart(SkinChange& change);

  std::vector<OrientedBall> balls_;
  SkinOptions options_;
  std::vector<Section> sections_;
  uint64_t next_id_ = 1;
};

/// The cap on `ball` from its contact point `from_side` counter-clockwise to the other one,
/// sampled with the chord tolerance; both ends included.
Polyline2 SampleCap(const OrientedBall& ball, int from_side, double chord_tolerance);

/// Builds and samples one section on its own (what Skin does per section): exposed for tests
/// and benchmarks. Balls must be an admissible pair; options as in Skin.
Section BuildSection(const OrientedBall& b0, const OrientedBall& b1, const SkinOptions& options);

}  // namespace sculpt::skin

#endif  // SCULPT_SKIN_SKIN_H_
