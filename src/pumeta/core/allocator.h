// Process-wide allocator settings for tensor-heavy work.
#pragma once

namespace pumeta {

/// Keeps freed memory in the process instead of returning it to the OS (glibc: no mmap'd
/// chunks, no trimming of the heap's top). glibc otherwise hands every allocation over its mmap
/// threshold back on free, so each large tensor of a training step is page-faulted and
/// zeroed afresh: PU-GCN steps were 1.8x slower, PU-Dense steps 1.7x (bench/models). Call
/// once at start-up, before the first tensor; a no-op on other C libraries.
void keep_freed_memory();

/// The largest resident set this process has had so far, in MiB (getrusage; what the
/// benchmarks report as peak memory).
double peak_resident_mib();

}  // namespace pumeta
