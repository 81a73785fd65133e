/// @brief Validity of composite hyperpatches (seed 001 §7.3): the thesis's single-cell condition
/// (48 ordered spans, disjoint parallel slice skins) evaluated in a canonical object frame, a
/// Jacobian sign check over a subdivision as a second opinion, and the cell-overlap test
/// (control-point boxes, alternating de Casteljau subdivision) cached by cell version.
#ifndef SCULPT_HETERO_VALIDITY_H_
#define SCULPT_HETERO_VALIDITY_H_

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <unordered_map>
#include <vector>

#include "sculpt/core/status.h"
#include "sculpt/core/vec3.h"
#include "sculpt/hetero/composite_model.h"
#include "sculpt/hetero/hyperpatch.h"

namespace sculpt::hetero {

/// Why a cell, a pair of cells or an edit was refused (seed 001 §10.2 reason codes).
enum class Reason {
  kOk = 0,
  kNotFinite,             // a coordinate is NaN or infinite
  kMaterialNotInSimplex,  // a distribution outside V (4.2)
  kDegenerateCell,        // mean parametric directions (near) coplanar: no object frame, zero volume
  kSpanNotOrdered,        // requirement 1 fails in every candidate frame (cell, direction, span, coord)
  kSkinIntersect,         // requirement 2: two parallel slice skins touch (cell, direction, skins)
  kJacobianSign,          // second opinion: det J <= 0 (or changes sign) at a subdivision node
  kCellOverlap,           // Case 2: two cells overlap beyond legitimately shared boundary
  kIrregularCorner,       // automatic C1 asked for at a corner that is not a regular block
  kNotContinuous,         // construction: asked continuity does not hold
  kBadIntent,             // an edit intent that names nothing that exists
};

/// "SPAN_NOT_ORDERED" etc.
const char* ReasonName(Reason r);

/// A rejection with where it happened; fields that do not apply are -1.
struct Rejection {
  Reason reason = Reason::kOk;
  int cell = -1;
  int other_cell = -1;  // kCellOverlap
  int direction = -1;   // 0=u (I), 1=v (J), 2=w (K)
  int span = -1;        // kSpanNotOrdered: 4*a+b for the two fixed indices (a, b)
  int coord = -1;       // kSpanNotOrdered: axis of the canonical frame
  int skin_a = -1;      // kSkinIntersect: the two slice indices
  int skin_b = -1;
  Vec3 uvw{-1, -1, -1};  // kJacobianSign: where
  std::string detail;

  bool ok() const { return reason == Reason::kOk; }
  std::string ToString() const;
  /// FailedPrecondition carrying ToString(), or Ok.
  Status ToStatus() const;
};

struct CellCheckOptions {
  /// Tolerances relative to the cell's box diagonal.
  double relative_tolerance = 1e-9;  // a coordinate difference this small counts as 0
  double contact_tolerance = 1e-7;   // skins closer than this touch (touching = intersecting)
  /// Search rotations of the canonical frame (15° steps, Euler angles in [0°, 90°)) when the
  /// canonical frame itself fails requirement 1; off = the canonical frame alone.
  bool frame_search = true;
  /// Second opinion: det J sampled at the (n+1)^3 nodes of an n×n×n subdivision; 0 = off.
  int jacobian_subdivisions = 4;
};

/// The verdict of the single-cell test.
struct CellVerdict {
  bool valid = false;
  Rejection rejection;
  int frame_index = -1;  // which candidate frame passed requirement 1 (0 = canonical)
  double min_det_j = 0;  // over the subdivision nodes (normalised by scale^3)
  double max_det_j = 0;
};

/// The canonical object frame of a net: rows are orthonormal axes built from the mean u, v
/// chords (Gram–Schmidt) and their cross product. Rotating the net rotates the frame, so
/// coordinates in it do not depend on the world orientation (the digest's claim 32). Returns
/// false when the mean directions are degenerate.
bool CanonicalFrame(const std::array<Vec3, 64>& net, std::array<Vec3, 3>* frame);

/// Requirement 1 alone (§7.3.1, the intended reading of (7.1)): every span monotone in every
/// coordinate of some candidate frame. kOk or kSpanNotOrdered / kDegenerateCell.
Rejection CheckSpansOrdered(const std::array<Vec3, 64>& net, const CellCheckOptions& opt = {},
                            int* frame_index = nullptr);
/// Requirement 2 alone: no two parallel slice skins (9 bilinear patches each) touch.
Rejection CheckSkinsDisjoint(const std::array<Vec3, 64>& net, const CellCheckOptions& opt = {});
/// det J at the nodes of an n×n×n subdivision: kOk when all share one strict sign.
Rejection CheckJacobianSign(const Hyperpatch& patch, int subdivisions, double relative_tolerance,
                            double* min_det = nullptr, double* max_det = nullptr);

/// The full single-cell test: finite positions, fractions in V, requirement 1, requirement 2,
/// then the Jacobian second opinion. The first failure is reported.
CellVerdict CheckCell(const Hyperpatch& patch, const CellCheckOptions& opt = {});

struct OverlapOptions {
  int max_depth = 6;     // levels of alternating subdivision (both cells split per level)
  int excuse_depth = 2;  // from this level, sub-cells meeting at a shared curve or corner pass
  double relative_tolerance = 1e-9;
};

/// Case 2 (§7.3.2) for two nets assumed valid: true when they overlap beyond the boundary
/// elements (corners, curves, faces) whose coefficients coincide. Boxes disjoint at level 0
/// return without subdivision. `boxes_tested` counts box tests when non-null.
bool NetsOverlap(const std::array<Vec3, 64>& a, const std::array<Vec3, 64>& b,
                 const OverlapOptions& opt = {}, int* boxes_tested = nullptr);

/// Checks the cells of a model and keeps verdicts keyed by cell version, so a re-check after an
/// edit costs only the touched cells and their neighbours (§7.3.2-3, §7.3.3-3).
/// Use one checker per model (versions are per model). Not thread-safe (it owns caches).
class ValidityChecker {
 public:
  ValidityChecker() = default;
  ValidityChecker(CellCheckOptions cell, OverlapOptions overlap) : cell_(cell), overlap_(overlap) {}

  struct Report {
    bool valid = true;
    std::vector<Rejection> rejections;
    int cells_checked = 0;   // single-cell tests run (cache misses)
    int pairs_tested = 0;    // pair tests run (cache misses)
    int cache_hits = 0;
  };

  /// Every cell, then every pair with overlapping boxes (Case 1 before Case 2, §7.3.2 note).
  Report CheckModel(const CompositeModel& model, bool stop_at_first = false);
  /// Only `cells` and their pairs with any other cell.
  Report CheckCells(const CompositeModel& model, std::span<const int> cells,
                    bool stop_at_first = true);
  CellVerdict CheckOneCell(const CompositeModel& model, int cell);
  Rejection CheckPair(const CompositeModel& model, int a, int b);

  void Clear();
  const CellCheckOptions& cell_options() const { return cell_; }

 private:
  struct CellEntry {
    uint64_t version;
    CellVerdict verdict;
  };
  struct PairEntry {
    uint64_t version_a, version_b;
    bool overlap;
  };
  CellCheckOptions cell_;
  OverlapOptions overlap_;
  std::unordered_map<int, CellEntry> cell_cache_;
  std::unordered_map<uint64_t, PairEntry> pair_cache_;
  std::vector<std::pair<uint64_t, Aabb>> box_cache_;  // per cell: version, control-point box
  const Aabb& CellBox(const CompositeModel& model, int cell);
  int hits_ = 0;
};

}  // namespace sculpt::hetero

#endif  // SCULPT_HETERO_VALIDITY_H_
