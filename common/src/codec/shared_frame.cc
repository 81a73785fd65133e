/// @brief A server message framed once for every session.
#include "sculpt/codec/shared_frame.h"

#include "sculpt/codec/frame.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::codec {

SharedFrame EncodeSharedFrame(const v1::ServerMessage& message) {
  auto f = std::make_shared<std::string>();
  AppendMessage(message, f.get());
  return f;
}

}  // namespace sculpt::codec
