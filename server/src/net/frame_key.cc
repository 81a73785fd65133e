/// @brief CoalescingKey: a mesh chunk frame's object and coordinates, read without parsing it.
#include "net/frame_key.h"

#include <google/protobuf/io/coded_stream.h>
#include <google/protobuf/wire_format_lite.h>

#include "sculpt/codec/frame.h"

namespace sculpt::server {
namespace {

using google::protobuf::io::CodedInputStream;
using WireFormatLite = google::protobuf::internal::WireFormatLite;

// Field numbers of sculpt.v1 (proto/sculpt/v1/sculpt.proto).
constexpr uint32_t kServerMessageMeshChunk = 10;
constexpr uint32_t kMeshChunkObject = 1;
constexpr uint32_t kMeshChunkKey = 2;

void AppendCoordinate(uint32_t zigzag, std::string* key) {
  *key += std::to_string(WireFormatLite::ZigZagDecode32(zigzag));
  *key += ',';
}

}  // namespace

std::string CoalescingKey(const std::string& frame) {
  if (frame.size() <= codec::kFrameHeaderBytes) return {};
  CodedInputStream in(reinterpret_cast<const uint8_t*>(frame.data()) + codec::kFrameHeaderBytes,
                      static_cast<int>(frame.size() - codec::kFrameHeaderBytes));
  const uint32_t tag = in.ReadTag();
  if (WireFormatLite::GetTagFieldNumber(tag) != kServerMessageMeshChunk ||
      WireFormatLite::GetTagWireType(tag) != WireFormatLite::WIRETYPE_LENGTH_DELIMITED) {
    return {};
  }
  uint32_t length = 0;
  if (!in.ReadVarint32(&length)) return {};
  const auto limit = in.PushLimit(static_cast<int>(length));
  std::string object, coords;
  bool have_object = false;
  for (uint32_t t = in.ReadTag(); t != 0; t = in.ReadTag()) {
    const uint32_t field = WireFormatLite::GetTagFieldNumber(t);
    const auto type = WireFormatLite::GetTagWireType(t);
    if (field == kMeshChunkObject && type == WireFormatLite::WIRETYPE_LENGTH_DELIMITED) {
      uint32_t n = 0;
      if (!in.ReadVarint32(&n) || !in.ReadString(&object, static_cast<int>(n))) return {};
      have_object = true;
    } else if (field == kMeshChunkKey && type == WireFormatLite::WIRETYPE_LENGTH_DELIMITED) {
      uint32_t n = 0;
      if (!in.ReadVarint32(&n)) return {};
      const auto packed = in.PushLimit(static_cast<int>(n));
      uint32_t v = 0;
      while (in.BytesUntilLimit() > 0) {
        if (!in.ReadVarint32(&v)) return {};
        AppendCoordinate(v, &coords);
      }
      in.PopLimit(packed);
    } else if (field == kMeshChunkKey && type == WireFormatLite::WIRETYPE_VARINT) {
      uint32_t v = 0;
      if (!in.ReadVarint32(&v)) return {};
      AppendCoordinate(v, &coords);
    } else if (!WireFormatLite::SkipField(&in, t)) {
      return {};
    }
  }
  in.PopLimit(limit);
  if (!have_object || coords.empty()) return {};
  return "mesh:" + object + '\0' + coords;
}

}  // namespace sculpt::server
