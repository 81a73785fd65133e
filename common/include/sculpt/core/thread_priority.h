/// @brief Background threads: lowering one thread's share of a contended core (Linux nice per
/// thread), for work that must not slow the edits (meshing for viewers, late-join serialisation,
/// snapshot writing).
#ifndef SCULPT_CORE_THREAD_PRIORITY_H_
#define SCULPT_CORE_THREAD_PRIORITY_H_

#include "sculpt/core/status.h"

namespace sculpt {

/// The calling thread's nice value (Linux applies nice per thread).
int ThreadNice();

/// Moves the calling thread back to nice value `nice`, never forward: a thread already further
/// back (the process run under `nice`) stays where it is. Raising one's own nice value needs no
/// privilege. Returns the reason when the kernel refused; a caller carries on at its priority.
Status LowerThreadPriority(int nice);

}  // namespace sculpt

#endif  // SCULPT_CORE_THREAD_PRIORITY_H_
