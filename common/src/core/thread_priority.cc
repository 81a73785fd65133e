#include "sculpt/core/thread_priority.h"

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <string>

namespace sculpt {
namespace {

id_t ThisThread() { return static_cast<id_t>(syscall(SYS_gettid)); }

}  // namespace

int ThreadNice() {
  errno = 0;
  const int nice = getpriority(PRIO_PROCESS, ThisThread());
  return errno == 0 ? nice : 0;
}

Status LowerThreadPriority(int nice) {
  const id_t tid = ThisThread();
  errno = 0;
  const int now = getpriority(PRIO_PROCESS, tid);
  if (errno != 0) {
    return Status(Status::Code::kInternal, std::string("getpriority: ") + std::strerror(errno));
  }
  if (now >= nice) return Status::Ok();
  if (setpriority(PRIO_PROCESS, tid, nice) != 0) {
    return Status(Status::Code::kInternal,
                  "setpriority(" + std::to_string(nice) + "): " + std::strerror(errno));
  }
  return Status::Ok();
}

}  // namespace sculpt
