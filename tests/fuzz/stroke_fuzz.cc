/// @brief libFuzzer target for stroke unpacking: UnpackPoses on raw bytes and DecodeStroke on an
/// arbitrary serialized sculpt.v1.Stroke.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include <google/protobuf/stubs/logging.h>

#include "sculpt/codec/stroke.h"
#include "sculpt/v1/sculpt.pb.h"

namespace {
// Invalid UTF-8 in Stroke.object is an expected rejection; protobuf's log line for each one
// would drown the fuzzer's output.
const bool kQuietProtobuf = (google::protobuf::SetLogHandler(nullptr), true);
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const std::string_view bytes(reinterpret_cast<const char*>(data) + 1, size - 1);
  if (data[0] & 1) {
    // Packed poses: the declared count is the first byte; the rest is the packed buffer.
    const uint32_t count = data[0] >> 1;
    auto poses = sculpt::codec::UnpackPoses(bytes, count, sculpt::Vec3{0, 0, 0}, 0.05, 64);
    if (poses.ok() && poses->size() != count) std::abort();
    return 0;
  }
  sculpt::v1::Stroke stroke;
  if (!stroke.ParseFromArray(bytes.data(), static_cast<int>(bytes.size()))) return 0;
  sculpt::codec::StrokeLimits limits;
  limits.voxel_size = 0.05;
  limits.bounds = sculpt::levelset::Aabb{{-4, -4, -4}, {4, 4, 4}};
  auto decoded = sculpt::codec::DecodeStroke(stroke, limits);
  if (decoded.ok()) {
    // A replica decodes what the server accepted into the same edits.
    sculpt::v1::Stroke again;
    if (!again.ParseFromString(decoded->source)) std::abort();
    auto replica = sculpt::codec::DecodeStroke(again, sculpt::codec::ReplicaLimits(0.05));
    if (!replica.ok() || replica->edits.size() != decoded->edits.size()) std::abort();
  } else {
    // Every refusal names its field.
    const sculpt::Status::Violation* v = decoded.status().violation();
    if (v == nullptr || v->field.empty()) std::abort();
  }
  return 0;
}
