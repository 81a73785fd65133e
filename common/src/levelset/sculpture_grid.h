/// @brief GridOf: read-only access to a Sculpture's SDF grid for the other modules of common/.
/// Internal (it includes OpenVDB): for .cc files of sculpt::haptics, sculpt::mesh and tests that
/// read the grid. What edits the sculpture's state includes sculpture_impl.h instead.
#ifndef SCULPT_LEVELSET_SCULPTURE_GRID_H_
#define SCULPT_LEVELSET_SCULPTURE_GRID_H_

#include <openvdb/openvdb.h>

#include "sculpt/levelset/sculpture.h"

namespace sculpt::levelset::internal {

/// The sculpture's narrow-band SDF. Valid while the sculpture lives and is not moved from; the
/// one-writer rule of Sculpture applies (read it only where no edit runs concurrently).
const openvdb::FloatGrid& GridOf(const Sculpture& sculpture);

}  // namespace sculpt::levelset::internal

#endif  // SCULPT_LEVELSET_SCULPTURE_GRID_H_
