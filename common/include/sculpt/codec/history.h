/// @brief The history view's request (issue 15) decoded at the edge: an untrusted
/// sculpt.v1.HistoryRequest becomes a HistoryQuery, or an error naming field, value and range.
#ifndef SCULPT_CODEC_HISTORY_H_
#define SCULPT_CODEC_HISTORY_H_

#include <cstdint>
#include <string>

#include "sculpt/core/status.h"

namespace sculpt::v1 {
class HistoryRequest;
}  // namespace sculpt::v1

namespace sculpt::codec {

/// Entries returned when HistoryRequest.limit is 0, and the largest limit accepted.
inline constexpr uint32_t kDefaultHistoryLimit = 50;
inline constexpr uint32_t kMaxHistoryLimit = 1000;
/// Longest object and author name accepted, in bytes.
inline constexpr size_t kMaxHistoryNameBytes = 64;

/// What a history view asks for, checked.
struct HistoryQuery {
  uint64_t request_id = 0;
  std::string object;                     // 1..64 bytes (the scene says whether it exists)
  std::string author;                     // empty: every author
  uint32_t limit = kDefaultHistoryLimit;  // [1, kMaxHistoryLimit]
};

/// InvalidArgument naming the field, value and allowed range: object empty or over 64 bytes,
/// author over 64 bytes or holding control characters, limit above 1000 (0 takes the default).
StatusOr<HistoryQuery> DecodeHistoryRequest(const v1::HistoryRequest& request);

}  // namespace sculpt::codec

#endif  // SCULPT_CODEC_HISTORY_H_
