// Results that do not depend on the thread count. OpenBLAS's multi-threaded kernels round
// differently with the number of threads on some CPUs (with its Haswell kernel on this
// machine a 2,048-point upsampling moved by up to 0.02 between --threads 1 and 2), and
// concurrent calls from a parallel region change its results too, so code whose output must be
// the same on any machine runs its matrix products on one thread.
#pragma once

#include <cstdint>
#include <functional>

namespace pumeta {

/// Sets LibTorch's intra-op thread count (and so OpenBLAS's) for its lifetime, then restores
/// the previous count. A no-op inside a parallel region, where operations run on one thread.
class ThreadCountGuard {
  public:
    explicit ThreadCountGuard(int threads);
    ~ThreadCountGuard();
    ThreadCountGuard(const ThreadCountGuard&) = delete;
    ThreadCountGuard& operator=(const ThreadCountGuard&) = delete;

  private:
    int previous_ = 0;  // 0: nothing to restore
};

/// Runs body(0), ..., body(count - 1) concurrently on up to LibTorch's intra-op thread count,
/// every operation inside each call on one thread (the calls share no thread pool, so each
/// computes as on one thread): when body(i) depends on i alone, the results are the same bits
/// whatever the thread count. Calls run in the caller's autograd mode (worker threads do not
/// inherit it otherwise). The first exception thrown by a call is rethrown.
void for_each_concurrently(int64_t count, const std::function<void(int64_t)>& body);

}  // namespace pumeta
