/// @brief ResendAllowance: the declared and committed resends a connection passes without tokens.
#include "net/resend_allowance.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace sculpt::server {
namespace {

// EditStream values 1..kResendStreams are the ResendStream values 0..kResendStreams-1.
static_assert(v1::EDIT_STREAM_STROKES == static_cast<int>(ResendStream::kStrokes) + 1);
static_assert(v1::EDIT_STREAM_PAINTS == static_cast<int>(ResendStream::kPaints) + 1);
static_assert(v1::EDIT_STREAM_MODELS == static_cast<int>(ResendStream::kModels) + 1);
static_assert(v1::EDIT_STREAM_BALL_EDITS == static_cast<int>(ResendStream::kBallEdits) + 1);
static_assert(v1::EDIT_STREAM_SWEEPS == static_cast<int>(ResendStream::kSweeps) + 1);
static_assert(v1::EDIT_STREAM_UNDOS == static_cast<int>(ResendStream::kUndos) + 1);
static_assert(v1::EditStream_MAX == static_cast<int>(kResendStreams));

std::string Field(int k, const char* name) {
  return "JoinScene.resends[" + std::to_string(k) + "]." + name;
}

}  // namespace

uint64_t ResendAllowance::AllowanceFor(const LimitsConfig& limits) {
  const double n = limits.stroke_burst + kSeconds * limits.strokes_per_second;
  if (!std::isfinite(n) || n <= 0) return 0;
  // Far above any configured rate; keeps the conversion defined.
  return static_cast<uint64_t>(std::min(n, 1e15));
}

StatusOr<ResendAllowance::Ranges> ResendAllowance::Decode(const v1::JoinScene& join,
                                                          uint64_t allowance) {
  Ranges out{};
  // Sequences declared so far; saturates rather than wraps (each range is checked first).
  uint64_t total = 0;
  const int n = join.resends_size();
  if (n > static_cast<int>(kResendStreams)) {
    return Outside("JoinScene.resends", std::to_string(n) + " ranges",
                   "[0, " + std::to_string(kResendStreams) + "] ranges, one per EditStream");
  }
  for (int k = 0; k < n; ++k) {
    const v1::ResendRange& r = join.resends(k);
    const int stream = static_cast<int>(r.stream());
    if (stream < v1::EDIT_STREAM_STROKES || stream > v1::EditStream_MAX) {
      return Outside(Field(k, "stream"), std::to_string(stream),
                     "[1, " + std::to_string(v1::EditStream_MAX) +
                         "] (EDIT_STREAM_STROKES..EDIT_STREAM_UNDOS)");
    }
    Range& slot = out[static_cast<size_t>(stream - 1)];
    if (slot.last != 0) {
      return FieldViolation(
          Status::Code::kInvalidArgument, Field(k, "stream"), v1::EditStream_Name(r.stream()),
          "one range per stream",
          Field(k, "stream") + "=" + v1::EditStream_Name(r.stream()) + " declared twice");
    }
    if (r.first_seq() == 0) {
      return Outside(Field(k, "first_seq"), "0", "[1, 2^64-1]");
    }
    if (r.last_seq() < r.first_seq()) {
      return Outside(Field(k, "last_seq"), std::to_string(r.last_seq()),
                     "[first_seq=" + std::to_string(r.first_seq()) + ", 2^64-1]");
    }
    const uint64_t size_minus_one = r.last_seq() - r.first_seq();
    total = (size_minus_one >= std::numeric_limits<uint64_t>::max() - total)
                ? std::numeric_limits<uint64_t>::max()
                : total + size_minus_one + 1;
    if (total > allowance) {
      const std::string value = total == std::numeric_limits<uint64_t>::max()
                                    ? "more than 2^64-2 client_seqs"
                                    : std::to_string(total) + " client_seqs";
      return Outside("JoinScene.resends", value,
                     "[0, " + std::to_string(allowance) +
                         "] client_seqs (limits.stroke_burst + 5 s of limits.strokes_per_second)",
                     Status::Code::kResourceExhausted);
    }
    slot = Range{r.first_seq(), r.last_seq()};
  }
  return out;
}

void ResendAllowance::Declare(const Ranges& declared, uint64_t allowance) {
  declared_ = declared;
  left_ = allowance;
}

bool ResendAllowance::Take(ResendStream stream, uint64_t seq) {
  const size_t i = static_cast<size_t>(stream);
  if (i >= kResendStreams || left_ == 0 || seq == 0 || seq <= last_free_[i]) return false;
  const Range& d = declared_[i];
  const bool declared = d.last != 0 && seq >= d.first && seq <= d.last;
  if (!declared && seq > committed_[i]) return false;
  last_free_[i] = seq;
  --left_;
  return true;
}

}  // namespace sculpt::server
