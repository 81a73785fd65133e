/// @brief AcceptPause: a growing pause and a rate-limited log line after failed accepts.
#include "net/accept_pause.h"

#include <spdlog/spdlog.h>

#include <algorithm>

namespace sculpt::server {

AcceptPause::AcceptPause(asio::io_context& io, std::string what)
    : timer_(io), what_(std::move(what)) {}

void AcceptPause::OnError(const boost::system::error_code& ec, std::function<void()> resume) {
  pause_ = std::clamp(pause_ * 2, std::chrono::milliseconds(10), std::chrono::milliseconds(1000));
  if (const uint64_t n = log_.Tick()) {
    spdlog::warn("{}: {} ({} failed accepts since the last report); the acceptor pauses {} ms",
                 what_, ec.message(), n, pause_.count());
  }
  timer_.expires_after(pause_);
  timer_.async_wait([resume = std::move(resume)](boost::system::error_code wec) {
    if (!wec) resume();
  });
}

}  // namespace sculpt::server
