#include "pumeta/core/threads.h"

#include <ATen/Parallel.h>
#include <c10/core/GradMode.h>

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

void for_each_concurrently(int64_t count, const std::function<void(int64_t)>& body) {
    if (count <= 0) return;
    if (count == 1 || at::get_num_threads() <= 1 || at::in_parallel_region()) {
        ThreadCountGuard one_thread(1);
        for (int64_t i = 0; i < count; ++i) body(i);
        return;
    }
    const bool grad = c10::GradMode::is_enabled();
    // Grain 1: each thread takes a contiguous run of calls; inside the parallel region
    // LibTorch's operations and OpenBLAS run on the calling thread.
    at::parallel_for(0, count, 1, [&](int64_t begin, int64_t end) {
        c10::AutoGradMode mode(grad);
        for (int64_t i = begin; i < end; ++i) body(i);
    });
}

}  // namespace pumeta
