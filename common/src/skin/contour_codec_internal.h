/// @brief What the contour codec exposes to its tests only: the SKC1 encoder, so that the web
/// client's decoder keeps being checked against messages in the older format, and the benchmark
/// can set both formats side by side.
#ifndef SCULPT_SKIN_CONTOUR_CODEC_INTERNAL_H_
#define SCULPT_SKIN_CONTOUR_CODEC_INTERNAL_H_

#include <string>
#include <vector>

#include "sculpt/core/status.h"
#include "sculpt/skin/skin.h"
#include "sculpt/skin/vec2.h"

namespace sculpt::skin::internal {

/// EncodeContours as SKC1 writes it (integers, varints or Draco rANS), errors as EncodeContours.
StatusOr<std::string> EncodeContoursSkc1(const std::vector<Polyline2>& polylines, double step);
/// EncodeSkinSnapshot as SKC1 writes it (for the benchmark's before / after in one run).
StatusOr<std::string> EncodeSkinSnapshotSkc1(const Skin& skin, double step = 0);

}  // namespace sculpt::skin::internal

#endif  // SCULPT_SKIN_CONTOUR_CODEC_INTERNAL_H_
