/// @brief DecodeHistoryRequest: the history view's request checked at the edge.
#include "sculpt/codec/history.h"

#include <algorithm>

#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::codec {

StatusOr<HistoryQuery> DecodeHistoryRequest(const v1::HistoryRequest& r) {
  const std::string bounds = std::to_string(kMaxHistoryNameBytes);
  // Names are echoed by size only: the text is the client's and may hold anything.
  if (r.object().empty() || r.object().size() > kMaxHistoryNameBytes) {
    return Outside("HistoryRequest.object",
                   std::string("(") + std::to_string(r.object().size()) + " bytes)",
                   std::string("names of 1..") + bounds + " bytes");
  }
  if (r.author().size() > kMaxHistoryNameBytes) {
    return Outside("HistoryRequest.author",
                   std::string("(") + std::to_string(r.author().size()) + " bytes)",
                   std::string("names of 0..") + bounds + " bytes (empty: every author)");
  }
  const auto control = [](char c) {
    const auto u = static_cast<unsigned char>(c);
    return u < 0x20 || u == 0x7f;
  };
  if (std::any_of(r.author().begin(), r.author().end(), control)) {
    return Outside(
        "HistoryRequest.author",
        std::string("(") + std::to_string(r.author().size()) + " bytes with control characters)",
        "names without control characters");
  }
  if (r.limit() > kMaxHistoryLimit) {
    return Outside("HistoryRequest.limit", std::to_string(r.limit()),
                   std::string("[0, ") + std::to_string(kMaxHistoryLimit) + std::string("] (0: ") +
                       std::to_string(kDefaultHistoryLimit) + ")");
  }
  HistoryQuery q;
  q.request_id = r.request_id();
  q.object = r.object();
  q.author = r.author();
  q.limit = r.limit() == 0 ? kDefaultHistoryLimit : r.limit();
  return q;
}

}  // namespace sculpt::codec
