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
/// SKC4 whatever the message (EncodeSkinSnapshot writes it for skins; SKC2 where smaller under
/// 4096 points); polyline sets stay SKC3 by default.
StatusOr<std::string> EncodeSkinSnapshotSkc4(const Skin& skin, double step = 0);
StatusOr<std::string> EncodeContoursSkc4(const std::vector<Polyline2>& polylines, double step);

/// A section entry of a skin message: its index (updates only), id and version.
struct SectionEntry {
  uint64_t index = 0, id = 0, version = 0;
};

/// SKC3's body for `kind` (0 polyline set, 1 snapshot, 2 update; contour_codec.h describes it),
/// or nullopt where it cannot place every point within step/sqrt(2) (the caller falls back).
/// `skc4`: SKC4's body (the same but for the chord predictor: the chord rule, contour_codec.h).
/// `fresh` (may be null; else one flag per line): lines coded anew, never joined to their
/// context line (a restart section's sides, sampled from Skc4Restart).
std::optional<std::string> Skc3Body(int kind, double step, const std::vector<SectionEntry>& entries,
                                    const std::vector<const Polyline2*>& lines, bool skc4 = false,
                                    const std::vector<bool>* fresh = nullptr);
/// Decodes Skc3Body's output (untrusted) into `entries` (sized by the caller) and `lines`.
Status DecodeSkc3Body(std::string_view body, size_t message_size, int kind, double step,
                      uint64_t nlines, uint64_t section_count, std::vector<SectionEntry>* entries,
                      std::vector<Polyline2>* lines, bool skc4 = false);

/// SKC4 as the skin's sampler follows it (sampling.cc): the direction of the decoder's next chord
/// from `c` and the distances along it of the two points it predicts (2 lp and 2 lp + 1 half
/// spacings; the row's parity decides which).
void Skc4Predict(const CodecCursor& c, double step, Vec2* u, double* along_even, double* along_odd);
/// Codes `target` as SKC4's encoder does from `c` and advances `c` to the decoded point and the
/// turtle after it; `along` (may be null) = the along integer, 0 where the point is where
/// predicted. False where no lattice point is within the bound (c unchanged).
bool Skc4Advance(CodecCursor& c, Vec2 target, double step, int64_t* along);
/// The cursor after SKC4's encoder codes `line` as the next line of the side whose last line
/// ended at `start` (joined when its first point is within the bound of start.p, as the encoder
/// decides). An invalid cursor where the line cannot be coded.
CodecCursor Skc4Trace(const CodecCursor& start, const Polyline2& line, double step);

/// Where SKC4's decoder stands at the start of a line coded anew (not joined to its context
/// line, contour_codec.h): at `first` on the absolute grid of `step`, with no turtle (the line
/// sends its first direction). The skin's sampler starts a restart section's sides from it, so
/// that they are a function of the section's own balls. has_point is false where `first` is
/// beyond the codec's range.
CodecCursor Skc4Restart(Vec2 first, double step);

/// SKC4's chord rule (contour_codec.h): the next chord in lattice spacings after a chord of `h`
/// half spacings that turned by `omega` angle units (|omega| <= 2^11), as the coder computes it,
/// and as the format defines it in doubles (which the JS decoder repeats). Equal for every
/// argument (the tests sweep them); the first is the one on the decoder's critical path.
int64_t Skc4ChordRule(int64_t h, int32_t omega);
int64_t Skc4ChordRuleDefinition(int64_t h, int32_t omega);

}  // namespace sculpt::skin::internal

#endif  // SCULPT_SKIN_CONTOUR_CODEC_INTERNAL_H_
