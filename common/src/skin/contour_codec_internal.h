/// @brief What the contour codec exposes to its tests only: the SKC1 and SKC2 encoders, so that
/// the web client's decoder keeps being checked against messages in the older formats, and the
/// benchmark can set the formats side by side; and SKC3's body coder, which contour_codec.cc
/// frames.
#ifndef SCULPT_SKIN_CONTOUR_CODEC_INTERNAL_H_
#define SCULPT_SKIN_CONTOUR_CODEC_INTERNAL_H_

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "sculpt/core/status.h"
#include "sculpt/skin/skin.h"
#include "sculpt/skin/vec2.h"

namespace sculpt::skin::internal {

/// EncodeContours as SKC1 writes it (integers, varints or Draco rANS), errors as EncodeContours.
StatusOr<std::string> EncodeContoursSkc1(const std::vector<Polyline2>& polylines, double step);
/// EncodeSkinSnapshot as SKC1 writes it (for the benchmark's before / after in one run).
StatusOr<std::string> EncodeSkinSnapshotSkc1(const Skin& skin, double step = 0);
/// EncodeSkinSnapshot as SKC2 writes it (the benchmark's before / after in one run).
StatusOr<std::string> EncodeSkinSnapshotSkc2(const Skin& skin, double step = 0);
/// EncodeContours as SKC2 writes it (the web fixtures keep checking the JS SKC2 decoder).
StatusOr<std::string> EncodeContoursSkc2(const std::vector<Polyline2>& polylines, double step);

/// SKC3 whatever the message's size (EncodeSkinSnapshot and EncodeContours keep SKC2 for a small
/// message where it is smaller); the usual fallback where SKC3 cannot place every point.
StatusOr<std::string> EncodeSkinSnapshotSkc3(const Skin& skin, double step = 0);
StatusOr<std::string> EncodeContoursSkc3(const std::vector<Polyline2>& polylines, double step);

/// A section entry of a skin message: its index (updates only), id and version.
struct SectionEntry {
  uint64_t index = 0, id = 0, version = 0;
};

/// SKC3's body for `kind` (0 polyline set, 1 snapshot, 2 update; contour_codec.h describes it),
/// or nullopt where it cannot place every point within step/sqrt(2) (the caller falls back).
std::optional<std::string> Skc3Body(int kind, double step, const std::vector<SectionEntry>& entries,
                                    const std::vector<const Polyline2*>& lines);
/// Decodes Skc3Body's output (untrusted) into `entries` (sized by the caller) and `lines`.
Status DecodeSkc3Body(std::string_view body, size_t message_size, int kind, double step,
                      uint64_t nlines, uint64_t section_count, std::vector<SectionEntry>* entries,
                      std::vector<Polyline2>* lines);

}  // namespace sculpt::skin::internal

#endif  // SCULPT_SKIN_CONTOUR_CODEC_INTERNAL_H_
