/// @brief AnswerOnce: wraps a requester's callback so that only its first call goes through.
#ifndef SCULPT_SERVER_SCENE_ANSWER_ONCE_H_
#define SCULPT_SERVER_SCENE_ANSWER_ONCE_H_

#include <atomic>
#include <functional>
#include <memory>
#include <utility>

namespace sculpt::server {

/// A copyable callback that forwards its first call to `fn` and drops every later one. The
/// compute thread's exception boundary answers a failed task through a copy of the same wrapper,
/// so a requester hears once even when its task throws after answering. Thread safety: copies
/// may be called from any threads; exactly one call wins.
template <typename... Args>
std::function<void(Args...)> AnswerOnce(std::function<void(Args...)> fn) {
  struct State {
    std::function<void(Args...)> fn;
    std::atomic<bool> answered{false};
  };
  auto state = std::make_shared<State>();
  state->fn = std::move(fn);
  return [state](Args... args) {
    if (state->answered.exchange(true)) return;
    auto fn = std::move(state->fn);  // released after the answer: it may hold a session
    if (fn) fn(std::forward<Args>(args)...);
  };
}

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_SCENE_ANSWER_ONCE_H_
