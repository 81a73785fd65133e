/// @brief The two example models of issue 7 (seed 001 chapter 10), built with the construction
/// operations: the thesis's mechanical part (§10.1, after the 8-step recipe of §9.3) and a
/// motorcycle tyre whose tread blends three materials (§10.2, §4.3).
#ifndef SCULPT_HETERO_EXAMPLES_H_
#define SCULPT_HETERO_EXAMPLES_H_

#include <string>

#include "sculpt/core/status.h"
#include "sculpt/hetero/composite_model.h"

namespace sculpt::hetero {

/// A racing motorcycle tyre about the z axis (units: cm): `sectors` sectors (8 of 45° by
/// default, at least 4, at most 1000; 100 give the 1,000-cell benchmark model); per sector a tread of
/// 3 cells (library ring sectors) whose three compounds blend continuously from carbon-black rich
/// on the left to silica rich on the right (§4.3: Estoril has 4 left and 9 right turns), a body
/// ply extruded inwards from the tread, side walls and beads extruded from the body ply's edges.
/// Materials: carbon_black_compound, silica_compound, natural_rubber, body_ply, bead_steel.
StatusOr<CompositeModel> BuildMotorcycleTyre(int sectors = 8);

/// A mechanical part in the manner of §9.3 (units: cm): two rings of 8 sectors from the library, a hub
/// extruded from one, a non-continuous blend joining them, the blend subdivided, a geometry edit
/// through an intent and material edits (a cylindrical steel-to-bronze transition in the hub, an
/// aluminium-rich arm). Materials: steel, bronze, aluminium.
StatusOr<CompositeModel> BuildMechanicalPart();

/// The file names under scenes/ the examples ship as.
inline constexpr const char* kTyreSceneFile = "hetero_motorcycle_tyre.json";
inline constexpr const char* kMechanicalPartSceneFile = "hetero_mechanical_part.json";

}  // namespace sculpt::hetero

#endif  // SCULPT_HETERO_EXAMPLES_H_
