/// @brief The session fuzz target's input format (session_fuzz.cc), shared with the seed writer
/// (session_seeds.cc) so that the committed seeds and the harness agree.
///
/// Byte 0: bit 0 set: two sessions (A and B) take part, else only A; bit 1 set: the scene with
/// materials (paint), else the one without (undo). Then records until the
/// input ends, each an op byte and, for messages, a payload:
///   op & 7          kind (below; kinds 5..7 are messages too, so random bytes mostly send)
///   (op >> 3) & 1   the session: B when set and there are two, else A
///   op >> 4         the kind's argument
/// kMessage: a 2-byte little-endian length L, then L bytes (fewer if the input ends first): one
///   serialized sculpt.v1.ClientMessage as a transport would hand it over. Argument bit 0: more
///   messages follow in the same read (delivered together, as one ReadResult).
/// kPump: runs the server until idle (io_context, scene compute thread, durable acks).
/// kStall: argument bit 0 set: the session's writes stop completing; clear: they complete again
///   (the held ones first).
/// kEnd: the session's stream ends: argument & 3: 0 the peer closed, 1 a frame above the maximum,
///   2 malformed framing; 3: not an end but a partial frame buffered (arms the frame timer).
/// kPresence: the server broadcasts presence to the joined sessions.
#ifndef SCULPT_TESTS_FUZZ_SESSION_INPUT_H_
#define SCULPT_TESTS_FUZZ_SESSION_INPUT_H_

#include <cstdint>
#include <string>

namespace sculpt::fuzz {

enum SessionOp : uint8_t {
  kMessage = 0,
  kPump = 1,
  kStall = 2,
  kEnd = 3,
  kPresence = 4,
};

inline constexpr uint8_t kTwoSessions = 1;
inline constexpr uint8_t kMaterials = 2;
inline constexpr uint8_t kSessionB = 1 << 3;
inline constexpr uint8_t kMoreInRead = 1 << 4;  // kMessage's argument bit 0

/// Appends one op record (and a message's length-prefixed payload) to `input`.
inline void AppendOp(std::string* input, uint8_t op, const std::string& payload = {}) {
  input->push_back(static_cast<char>(op));
  if ((op & 7) == kMessage || (op & 7) > kPresence) {
    const size_t n = payload.size() > 0xffff ? 0xffff : payload.size();
    input->push_back(static_cast<char>(n & 0xff));
    input->push_back(static_cast<char>(n >> 8));
    input->append(payload, 0, n);
  }
}

}  // namespace sculpt::fuzz

#endif  // SCULPT_TESTS_FUZZ_SESSION_INPUT_H_
