/// @brief Slice contours: a plane cut of a sculpture's level set, found by marching squares on a
/// 2D sample of phi, as polylines in plane coordinates (for thin clients that follow the shape
/// without meshes; encoded with the contour codec).
#ifndef SCULPT_LEVELSET_SLICE_H_
#define SCULPT_LEVELSET_SLICE_H_

#include <vector>

#include "sculpt/core/status.h"
#include "sculpt/levelset/sculpture.h"
#include "sculpt/levelset/sweep.h"

namespace sculpt::levelset {

/// Largest sample grid edge of a slice.
inline constexpr int kMaxSliceSamples = 1024;

/// One slice request: the square [-half_extent, half_extent]^2 of `plane`, sampled every `step`.
struct SliceRequest {
  SweepPlane plane;
  double half_extent = 32;
  double step = 0.5;
};

/// The zero crossings of phi in the slice, linked into polylines (plane coordinates). A closed
/// loop repeats its first point at its end; a curve leaving the square stays open. Saddle cells
/// are split by the cell-centre average. InvalidArgument for a bad plane, a non-finite or
/// non-positive step or half extent, or more than kMaxSliceSamples samples per edge.
StatusOr<std::vector<std::vector<PlanePoint>>> SliceContours(const Sculpture& sculpture,
                                                             const SliceRequest& request);

/// Marching squares on a row-major nx x ny grid of samples `phi` (spacing `step`, sample (0, 0)
/// at `origin`): the same linking as SliceContours.
std::vector<std::vector<PlanePoint>> MarchingSquares(const std::vector<float>& phi, int nx, int ny,
                                                     PlanePoint origin, double step);

}  // namespace sculpt::levelset

#endif  // SCULPT_LEVELSET_SLICE_H_
