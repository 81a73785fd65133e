/// @brief The coalescing key of a shared frame: frames with the same key supersede each other in
/// a session's send queue (one "latest version" slot per viewer and mesh chunk).
#ifndef SCULPT_SERVER_NET_FRAME_KEY_H_
#define SCULPT_SERVER_NET_FRAME_KEY_H_

#include <string>

namespace sculpt::server {

/// For a length-prefixed ServerMessage frame holding a MeshChunk: a key naming the object and
/// chunk coordinates (a newer frame of the same chunk makes an unsent older one useless). Empty
/// for every other frame and for bytes that do not parse as far as the key. Reads only the
/// message's leading fields; the Draco bytes are skipped, not copied.
std::string CoalescingKey(const std::string& frame);

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_NET_FRAME_KEY_H_
