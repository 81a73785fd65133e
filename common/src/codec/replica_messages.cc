/// @brief Decoding of Subscribe, SetInterest, ViewerSubscribe and DivergenceReport off the wire.
#include "sculpt/codec/replica_messages.h"

#include <cmath>
#include <string>

#include "sculpt/core/check.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::codec {
namespace {

Vec3 V(const v1::Vec3f& v) { return {v.x(), v.y(), v.z()}; }

StatusOr<std::optional<InterestBox>> DecodeInterest(bool has, const v1::Box3& box,
                                                    const std::string& field) {
  if (!has) return std::optional<InterestBox>();
  InterestBox out{V(box.min()), V(box.max())};
  SCULPT_RETURN_IF_ERROR(CheckFinitePoint(field + ".min", out.min));
  SCULPT_RETURN_IF_ERROR(CheckFinitePoint(field + ".max", out.max));
  return std::optional<InterestBox>(out);
}

}  // namespace

StatusOr<ReplicaSubscription> DecodeSubscribe(const v1::Subscribe& r) {
  if (r.mode() != v1::REPLICA_MODE_REPLAY && r.mode() != v1::REPLICA_MODE_LEAF_DELTA) {
    return Outside("Subscribe.mode", std::to_string(r.mode()), "{1 (REPLAY), 2 (LEAF_DELTA)}");
  }
  ReplicaSubscription out;
  out.object = r.object();
  out.mode = static_cast<ReplicaMode>(r.mode());
  out.have_seq = r.have_seq();
  SCULPT_ASSIGN_OR_RETURN(out.interest,
                          DecodeInterest(r.has_interest(), r.interest(), "Subscribe.interest"));
  return out;
}

StatusOr<InterestChange> DecodeSetInterest(const v1::SetInterest& r) {
  InterestChange out;
  out.object = r.object();
  SCULPT_ASSIGN_OR_RETURN(out.interest,
                          DecodeInterest(r.has_interest(), r.interest(), "SetInterest.interest"));
  return out;
}

StatusOr<ViewerSubscription> DecodeViewerSubscribe(const v1::ViewerSubscribe& r) {
  ViewerSubscription out;
  out.object = r.object();
  const double rate = r.max_rate_hz();
  if (rate != 0 && (!std::isfinite(rate) || rate < 0.1 || rate > 120)) {
    return Outside("ViewerSubscribe.max_rate_hz", FormatNumber(rate),
                   "[0.1, 120] (0: the server's default)");
  }
  out.max_rate_hz = rate;
  return out;
}

Divergence DecodeDivergenceReport(const v1::DivergenceReport& r) {
  return {r.object(), r.global_seq(), r.expected_hash(), r.actual_hash()};
}

StatusOr<ReplicaProgress> DecodeReplicaProgress(const v1::ReplicaProgress& p) {
  if (p.object().empty() || p.object().size() > 256) {
    return Outside("ReplicaProgress.object", std::to_string(p.object().size()) + " bytes",
                   "1 to 256 bytes");
  }
  if (p.durable_seq() == 0) {
    return Outside("ReplicaProgress.durable_seq", "0", "[1, 2^64 - 1]");
  }
  return ReplicaProgress{p.object(), p.durable_seq()};
}

}  // namespace sculpt::codec
