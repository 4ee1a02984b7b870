#include "pumeta/core/threads.h"

#include <ATen/Parallel.h>

namespace pumeta {

ThreadCountGuard::ThreadCountGuard(int threads) {
    // Inside a parallel region operations already run on one thread, and the count is shared
    // by every thread: leave it alone.
    if (at::in_parallel_region()) return;
    previous_ = at::get_num_threads();
    if (threads != previous_) at::set_num_threads(threads);
}

ThreadCountGuard::~ThreadCountGuard() {
    if (previous_ > 0 && at::get_num_threads() != previous_) at::set_num_threads(previous_);
}

}  // namespace pumeta
