/// @brief Distances rebuilt on a DenseField: fast marching from known voxels, and the distance of
/// an interface voxel to the surface placed as volumeToMesh places it. No OpenVDB here.
#ifndef SCULPT_LEVELSET_FAST_MARCH_H_
#define SCULPT_LEVELSET_FAST_MARCH_H_

#include <cstddef>
#include <cstdint>
#include <vector>

#include "sculpt/levelset/dense_field.h"

namespace sculpt::levelset {

/// Role of a voxel in MarchDistance.
enum class MarchState : uint8_t {
  kFree = 0,     // |phi| is computed; the sign of its current value is kept
  kKnown = 1,    // |phi| is read as it is and never written
  kIgnored = 2,  // neither read nor written
};

/// Fast marching (Sethian; first-order Godunov update, the discrete |grad phi| = 1 that
/// OpenVDB's checkLevelSet measures) of the distance |phi| from the kKnown voxels into the kFree
/// ones, in world units. A free voxel keeps the sign of its value; one that the front does not
/// reach within `limit` gets +-limit. Free voxels must not have a 6-neighbour of the other sign
/// (put the interface in kKnown), or the distance would cross the interface. Ties break by the
/// linear index, so the result is deterministic. `state` has phi's layout; on return every
/// free voxel is kKnown. Returns the number of free voxels (every one of them is set). Bad
/// arguments (a state of another size, dx or limit not positive) change nothing and return 0.
size_t MarchDistance(DenseField& phi, std::vector<MarchState>& state, double dx, double limit);

/// MarchDistance for a field whose free voxels all lie in the index box [lo, hi): the seeding
/// scan visits that box alone, so a rebuild of a small part of a large field costs what the
/// part does. The result is the whole-field march's.
size_t MarchDistance(DenseField& phi, std::vector<MarchState>& state, double dx, double limit,
                     Int3 lo, Int3 hi);

/// The distance to the surface of an interface voxel (one with a 6-neighbour of the other sign),
/// signed as phi: along each axis with a sign change the crossing is placed by linear
/// interpolation on the edge to the nearer such neighbour (as volumeToMesh places its vertices),
/// and the distance is that to the plane through those intercepts. A crossing along one axis
/// stays exactly where it was; the pair of voxels across it then differs by one voxel (a unit
/// gradient). Returns phi itself for a voxel without a sign change.
double InterfaceDistance(const DenseField& phi, int i, int j, int k, double dx);

}  // namespace sculpt::levelset

#endif  // SCULPT_LEVELSET_FAST_MARCH_H_
