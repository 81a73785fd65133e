/// @file edit_passes.h
/// @brief The passes of an edit on its block (internal to the levelset library), in the order
/// ApplyEdits runs them: the operators (one per kind), the sliver and band repair, the volume
/// compensation, and the islands and voids policy.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "edit_block.h"
#include "sculpt/levelset/edit.h"

namespace sculpt::levelset::internal {

// ---- Operators (edit_operators.cc) ----

/// Scratch the operators of one batch share.
struct OperatorScratch {
  std::vector<float> speed;  // a press's speed field
};

/// Runs one request's operator on the block (seed 000 ch. 5 for press and smooth, CSG for add
/// and subtract, a weighted normal offset for inflate and deflate). `batch`: the request is one
/// of several, so its own tool field is loaded first (the block holds the union's otherwise).
/// Adds its steps and substeps to `res`. Returns whether it changed the block.
bool ApplyOperator(Block& b, const EditRequest& req, bool batch, const EditSettings& s,
                   double scale, OperatorScratch& scratch, EditResult& res);

// ---- Slivers and the band (edit_resolve.cc) ----

/// Material one sample thick along some direction (both neighbours outside, along an axis, a
/// face diagonal or a body diagonal): a sheet or fibre the grid cannot resolve, which the next
/// edit or the mesher turns into holes, tunnels and open edges, and around which no band has a
/// unit gradient. Such voxels are emptied (repeatedly: emptying one can thin its neighbour) on
/// the block's written interior, looked for where the edit changed a voxel or its neighbour (the
/// rest of the block is as the previous edit left it). Returns the voxels emptied; `touched`
/// marks them for the band repair.
size_t RemoveThinMaterial(Block& b, std::vector<uint8_t>& touched);

/// Empties material thinner than a voxel and repairs the band where it is broken, so that
/// nothing the edit leaves behind is a sliver or a torn band. The band repair changes distances,
/// by which thinness is judged, so the two alternate until neither has anything left to do (a
/// rebuilt interface voxel takes its distance from its neighbours' old values: next to a
/// voxel-scale corner a second round settles the pair across the surface). Where they keep
/// trading (a groove whose corners sit between samples) the rounds are bounded and a last pass
/// empties what the last repair thinned, so no sliver survives either way. Unless
/// `always_repair` (inflate and deflate, which rewrite the band wholesale), the band is repaired
/// only where something was emptied or marked in `repair`: after a press, a smooth or a CSG
/// edit the reinitialisation has already straightened it, and looking for a torn band and
/// rebuilding it would cost more than the edit. Both passes look only at the voxels the edit
/// changed and their neighbours. Returns whether anything changed.
bool Resolve(Block& b, std::vector<uint8_t>& repair, bool always_repair);

// ---- Volume compensation (edit_compensation.cc) ----

struct CompensationOutcome {
  int iterations = 0;
  int substeps = 0;
  bool failed = false;
};

// Shell compensation inside the block. `base_volume` is the tracked volume before the edit, so
// Vol = base_volume + (change of the block's inside count) dx^3, exactly as the tracked volume.
// The shell and its weights depend on the tools' field alone, which the passes of one edit share.
struct ShellCache {
  bool ready = false;
  VoxelList shell;
  std::vector<float> w;
};

CompensationOutcome CompensateShell(Block& b, double target, double base_volume, double shell_outer,
                                    const EditSettings& s, ShellCache& cache);

/// The thesis's region (seed 000 §6.3): a uniform normal offset of every interface voxel of the
/// grid outside the tools (chi of Gamma's complement), towards `reference`, after the block was
/// written back. Walks the whole grid by design; it exists to reproduce the thesis.
void CompensateGlobal(Sculpture& sculpture, const std::vector<EditRequest>& reqs, double reference,
                      const EditSettings& s, EditResult& res);

// ---- Islands and voids (edit_islands.cc) ----

struct IslandReport {
  int found = 0;    // pieces of at least one voxel (smaller ones are below the grid's resolution)
  int removed = 0;  // pieces removed (material) or pockets filled (air)
  double inside_change = 0;  // change of the block's inside-voxel sum by the removals
  VoxelList zone;            // voxels reset by a removal or a fill (to be reinitialised)
  VoxelList flipped;         // voxels of the pieces removed (now of the other phase)
};

/// The voxels of the block's interior whose phase (material, phi < 0, or air) differs from the
/// extracted field's, in index order.
VoxelList PhaseChanges(const Block& b);

/// Pieces of material the edit cut off inside the block, seeded from `flipped` (the voxels
/// whose phase changed), removed under IslandPolicy::kRemoveSmall when below
/// min_island_volume. A piece reaching the block's stencil margin counts as connected.
IslandReport FindIslands(Block& b, const EditSettings& s, const VoxelList& flipped);

/// Pockets of air the edit sealed inside the material, filled under kRemoveSmall when below
/// min_island_volume; as FindIslands for the other phase.
IslandReport FindVoids(Block& b, const EditSettings& s, const VoxelList& flipped);

}  // namespace sculpt::levelset::internal
