/// @brief A server message framed once and shared by every session that sends it.
#ifndef SCULPT_CODEC_SHARED_FRAME_H_
#define SCULPT_CODEC_SHARED_FRAME_H_

#include <memory>
#include <string>

namespace sculpt::v1 {
class ServerMessage;
}  // namespace sculpt::v1

namespace sculpt::codec {

/// A frame as every session queues it: immutable, shared.
using SharedFrame = std::shared_ptr<const std::string>;

/// `message` serialized into one length-prefixed frame (frame.h).
SharedFrame EncodeSharedFrame(const v1::ServerMessage& message);

}  // namespace sculpt::codec

#endif  // SCULPT_CODEC_SHARED_FRAME_H_
