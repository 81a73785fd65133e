/// @brief Deformation edits on a Sculpture: press (seed 000 ch. 5), CSG add/subtract, smooth,
/// inflate/deflate, with volume compensation, local reinitialisation and an islands policy.
#ifndef SCULPT_LEVELSET_EDIT_H_
#define SCULPT_LEVELSET_EDIT_H_

#include <cstdint>
#include <string>
#include <vector>

#include "sculpt/core/status.h"
#include "sculpt/levelset/dense_field.h"
#include "sculpt/levelset/kernels.h"
#include "sculpt/levelset/sculpture.h"
#include "sculpt/levelset/tool.h"

namespace sculpt::levelset {

enum class EditKind : uint8_t {
  kPress = 0,     // move the surface inward inside the tool until the tool holds no material
  kAdd = 1,       // CSG union with the tool
  kSubtract = 2,  // CSG difference with the tool
  kSmooth = 3,    // mean-curvature flow inside the tool
  kInflate = 4,   // normal offset outward inside the tool by `amount`
  kDeflate = 5,   // normal offset inward inside the tool by `amount`
};
const char* EditKindName(EditKind kind);

/// Where lost or added volume is restored (seed 000 ch. 5, Algorithm 2).
enum class CompensationRegion : uint8_t {
  kNone = 0,
  kShell = 1,   // a band around the tool (clay bulging around a finger); cost follows the edit
  kGlobal = 2,  // the whole interface outside the tool, as the thesis; walks the whole grid
};
/// How the compensation step is computed.
enum class CompensationMethod : uint8_t {
  kNewton = 0,               // offset d = (c - Vol) / Area, iterated (digest §3.3, §8)
  kGradientDescentDelta = 1, // phi += dt (Vol - c) delta_eps(phi) chi (seed 000 eq. 5.6, corrected)
  kGradientDescentGrad = 2,  // phi += dt (Vol - c) |grad phi| chi (seed 000 eq. 5.8, corrected)
};
enum class IslandPolicy : uint8_t {
  kKeep = 0,         // report pieces split off and pockets of air sealed, keep them
  kRemoveSmall = 1,  // remove pieces and fill pockets below min_island_volume, re-baseline the
                     // reference by what that removed and added
};

/// Scene-level choices for edits (the effects the scene calls for).
struct EditSettings {
  /// First-order upwind in space: a press runs a few substeps and stops when the tool is
  /// empty, so WENO5 bought no measured accuracy there (docs/benchmarks.md section 2) and cost
  /// a fifth of an edit.
  MotionSettings motion{SpatialScheme::kUpwind, TemporalScheme::kRk2, Boundary::kClamp};
  /// CFL number for every substep (phi moves at most cfl voxels per substep).
  double cfl = 0.5;
  CompensationRegion compensation = CompensationRegion::kShell;
  CompensationMethod compensation_method = CompensationMethod::kNewton;
  /// Shell outer distance from the tool surface, in tool radii (at least 3 voxels).
  double shell_radii = 1.0;
  /// Stop compensating when |c - Vol| is at most this many voxel volumes. Absolute, not
  /// relative: a relative tolerance let presses on large objects skip compensation and return
  /// the deficit later as one larger bulge (docs/benchmarks.md, section 1).
  double compensation_tolerance_voxels = 0.25;
  int max_compensation_iterations = 6;
  /// Pseudo time step of the gradient-descent forms (in voxels per unit of volume error,
  /// scaled by 1/Area internally so it is dimensionless; 1 = one Newton step).
  double gradient_descent_dt = 0.5;
  /// Reinitialise the edited region when the mean Eikonal error there exceeds this. 0.05 cut
  /// the shape error near strokes by a fifth and halved its worst case against 0.15, for
  /// about 15% more time per edit (docs/benchmarks.md, section 2).
  double reinit_eikonal_threshold = 0.05;
  /// Also reinitialise every k edits (0 = only by the threshold).
  int reinit_every_k = 0;
  int reinit_iterations = 4;
  /// Scheme of the reinitialisation. First-order upwind by default: with the Russo-Smereka
  /// subcell fix it keeps the interface in place, costs a tenth of WENO5, and does not
  /// overshoot at the kinks a press leaves (WENO5 there made sub-voxel specks of material).
  SpatialScheme reinit_spatial = SpatialScheme::kUpwind;
  /// Scan every edit's block for a torn band (the zero crossing near the band's edge, |grad phi|
  /// outside [0.6, 1.4]) and sub-voxel slivers, and rebuild the band there, as inflate, deflate
  /// and box edits always do. Off by default: it makes a press 5.4x and a 4-pose stroke 4.3x the
  /// instructions (the scan runs over the whole dense block), and the random-edit property test
  /// (tests/stability/edit_property_test.cc; docs/benchmarks.md, "Invariants under random
  /// edits") measures what it buys: with it no sliver, band edge, speck or small pocket is left
  /// in 600 random edits, without it about one edit in five leaves a |grad phi| or sliver
  /// violation. A scene sets it with `[scene.effects] band_repair = "every_edit"`; the settings
  /// codec carries it to replicas (EditSettingsMsg.repair_band_every_edit).
  bool repair_band_every_edit = false;
  IslandPolicy islands = IslandPolicy::kKeep;
  /// Pieces of material below this volume (world units^3) are removed under kRemoveSmall, and
  /// pockets of air sealed inside the material below it are filled.
  double min_island_volume = 0;
  /// Accepted tool sizes, in voxels.
  double min_tool_voxels = 0.5;
  double max_tool_voxels = 64;
  /// Largest press speed, in voxels per unit time.
  double max_speed_voxels = 1e4;
  /// Largest inflate/deflate amount, in voxels.
  double max_amount_voxels = 32;
};

/// Returns InvalidArgument naming the field, the value and the range.
Status ValidateEditSettings(const EditSettings& settings);

/// EditSettings that ValidateEditSettings accepted. Made once where settings enter (the scene's
/// configuration, the settings codec) and passed inward, so the kernel's entry points taking one
/// do not check the settings again per edit. Only Validate makes one from arbitrary settings; a
/// default-constructed one holds EditSettings{}, which is valid. Reads as a const EditSettings&.
/// Immutable: safe to share between threads.
class ValidEditSettings {
 public:
  ValidEditSettings() = default;
  /// InvalidArgument naming the field, the value and the range (ValidateEditSettings).
  static StatusOr<ValidEditSettings> Validate(const EditSettings& settings);

  const EditSettings& get() const { return settings_; }
  const EditSettings* operator->() const { return &settings_; }
  operator const EditSettings&() const { return settings_; }  // NOLINT: implicit by design

 private:
  explicit ValidEditSettings(const EditSettings& settings) : settings_(settings) {}
  EditSettings settings_;
};

/// One edit request (what a stroke sample asks for).
struct EditRequest {
  EditKind kind = EditKind::kPress;
  ToolShape tool;
  /// Press: tool speed in world units per unit time (>= 0; 0 moves nothing).
  double speed = 1.0;
  /// Press: time per step (the stroke sample interval). The press runs whole steps until the
  /// tool holds no material.
  double dt = 1.0;
  /// Inflate/deflate: offset distance in world units. Smooth: flow time in voxel^2 units.
  double amount = 1.0;
};

/// Wall time (ms) of each stage of one edit, for profiling (sculpt-bench edit reports them). The
/// stages run in this order (the islands and voids search last, before the write-back) and
/// together make up about `EditResult::elapsed_ms`.
struct EditStageTimes {
  double block = 0;         // copy-in of the block and the tools' distance field
  double operators = 0;     // the kind's operator (a press's motion substeps)
  double islands = 0;       // sliver scan, islands and voids search and their repair
  double compensation = 0;  // every shell compensation pass
  double reinit = 0;        // Eikonal measure and reinitialisation
  double resolve = 0;       // sliver and band-repair rounds (inflate, deflate, box tools)
  double write_back = 0;    // material fractions, write-back and volume tracking
};

/// What an edit did.
struct EditResult {
  bool changed = false;
  std::vector<Int3> dirty_leaves;
  uint64_t changed_voxels = 0;
  double volume_before = 0;
  double volume_after = 0;
  /// Exactly what the edit added to the tracked volume (volume_after == volume_before +
  /// volume_change, bit for bit, except under global compensation, which recomputes the volume):
  /// undo carries the bookkeeping past an edit it does not need to replay (edit_history.h).
  double volume_change = 0;
  double reference_volume = 0;
  int steps = 0;
  int substeps = 0;
  int compensation_iterations = 0;
  /// (volume_after - reference) / reference, after compensation.
  double compensation_residual = 0;
  bool compensation_failed = false;  // no interface in the compensation region
  int reinit_passes = 0;
  double eikonal_error_before_reinit = 0;
  int islands_found = 0;
  int islands_removed = 0;
  double island_volume_removed = 0;
  /// Pockets of air the edit sealed inside the material (at least one voxel of air; a smaller
  /// pocket is below the grid's resolution and filled under kRemoveSmall without being counted),
  /// and how many it filled under kRemoveSmall (pockets below min_island_volume).
  int voids_found = 0;
  int voids_filled = 0;
  /// Material added by filling them (world units^3; the reference volume grows by it).
  double void_volume_filled = 0;
  bool press_fallback_csg = false;  // the flow stalled (no interface reached) and CSG finished it
  double elapsed_ms = 0;
  EditStageTimes stage_ms;
};

/// Applies one edit. Validates the request first (tool fields, speed, dt, amount): on a bad
/// field returns InvalidArgument naming field, value and range and leaves the sculpture
/// unchanged. Reads and writes only the leaves of the tool's influence box, the compensation
/// shell and a stencil halo (except CompensationRegion::kGlobal). Deterministic.
StatusOr<EditResult> ApplyEdit(Sculpture& sculpture, const EditRequest& request,
                               const ValidEditSettings& settings);
/// The same for settings not validated yet: ValidEditSettings::Validate's error first.
StatusOr<EditResult> ApplyEdit(Sculpture& sculpture, const EditRequest& request,
                               const EditSettings& settings);

/// Largest batch ApplyEdits takes.
inline constexpr size_t kMaxEditsPerBatch = 256;

/// Applies the requests of one stroke (all of one kind) as one edit: each request's operator
/// runs in turn in one shared block, then the islands check, volume compensation and
/// reinitialisation run once for the batch and the block is written back once. Cheaper than
/// ApplyEdit per request when the tools overlap, as the poses of one stroke do; the result
/// differs from per-request application only in when compensation and reinit run.
/// InvalidArgument for an empty or oversized batch, mixed kinds, or any bad request (the
/// sculpture is then unchanged).
StatusOr<EditResult> ApplyEdits(Sculpture& sculpture, const std::vector<EditRequest>& requests,
                                const ValidEditSettings& settings);
/// The same for settings not validated yet: ValidEditSettings::Validate's error first.
StatusOr<EditResult> ApplyEdits(Sculpture& sculpture, const std::vector<EditRequest>& requests,
                                const EditSettings& settings);

/// The server's scalars an edit starts from, beyond the voxels it reads: a replica replaying the
/// edit sets them first, so its compensation aims at the same volumes as the server's did.
struct ReplayState {
  double volume = 0;
  double reference_volume = 0;
  uint64_t edits_since_reinit = 0;
};
ReplayState CaptureReplayState(const Sculpture& sculpture);
/// Sets the tracked scalars (a replica after loading leaf records).
void RestoreReplayState(Sculpture& sculpture, const ReplayState& state);

/// Replays a batch the server applied (ApplyEdits with the same requests and settings), on a
/// replica holding at least the batch's footprint: sets `state`, skips the check against the
/// object's extent (the replica may hold part of it), then runs the same kernel. On equal input
/// voxels the result is bit-identical to the server's.
StatusOr<EditResult> ReplayEdits(Sculpture& sculpture, const std::vector<EditRequest>& requests,
                                 const ValidEditSettings& settings, const ReplayState& state);
/// The same for settings not validated yet: ValidEditSettings::Validate's error first.
StatusOr<EditResult> ReplayEdits(Sculpture& sculpture, const std::vector<EditRequest>& requests,
                                 const EditSettings& settings, const ReplayState& state);

/// The index box a batch reads (its block: tools, reach, compensation shell, stencil halo), so
/// a replica holding it can replay the batch. `whole_object` when global compensation reads
/// the whole grid.
struct EditFootprint {
  Int3 min{0, 0, 0};
  Int3 max{-1, -1, -1};
  bool whole_object = false;
};
EditFootprint FootprintOf(const Sculpture& sculpture, const std::vector<EditRequest>& requests,
                          const EditSettings& settings);

/// Validates a request against settings and the sculpture (tool inside the object's bounds plus
/// a margin of the tool size, sizes in range) without applying it.
Status ValidateEditRequest(const Sculpture& sculpture, const EditRequest& request,
                           const EditSettings& settings);

/// Reinitialises the band inside a world box (seed 000 eq. 4.9 with the subcell fix), `iterations`
/// pseudo-time steps; keeps the tracked volume exact. InvalidArgument for a non-finite or empty
/// box or iterations outside [1, 100]. Returns the edit summary (dirty leaves, volumes).
StatusOr<EditResult> ReinitializeRegion(Sculpture& sculpture, const Aabb& region, int iterations,
                                        const MotionSettings& motion);

}  // namespace sculpt::levelset

#endif  // SCULPT_LEVELSET_EDIT_H_
