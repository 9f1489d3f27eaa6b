// Deterministic data parallelism for aosr's loops (FFT blocks, frames, per-bin solves).
//
// The promise (DESIGN.md §4, "thread count not in the result"): ParallelFor(count, threads, fn) calls
// fn(k) exactly once for every k in [0, count), on up to `threads` threads. Which thread runs k is not
// specified, so a caller keeps its result independent of the thread count by making fn(k) write only what
// task k owns and by reducing partial results afterwards in index order. Every parallel loop in aosr is
// written that way, and tests compare 1-thread and 2-thread outputs bit for bit.
//
// Execution: the threads come from one process-wide pool, started on first use and grown on demand, so a
// parallel loop costs a wake-up (microseconds), not a thread start. The calling thread takes part. A
// ParallelFor issued from inside another (a nested loop, or a loop on a thread of the caller's own) runs
// serially on the calling thread: the outer loop already holds the cores, and the result is the same.
// The first exception thrown by any fn(k) is rethrown in the caller after every started task has finished.
//
// The default thread count is a setting (SetDefaultThreads), read by library code that takes no explicit
// count; the CLI sets it from --threads.
#pragma once

#include <functional>

#include "aosr/core/image.hpp"

namespace aosr {

// Runs fn(0) … fn(count − 1) on up to `threads` threads (>= 1; count >= 0). See the rules above.
void ParallelFor(Index count, int threads, const std::function<void(Index)>& fn);
// The same with the default thread count.
void ParallelFor(Index count, const std::function<void(Index)>& fn);

// The default thread count for library loops (>= 1; InvalidArgument otherwise). Thread-safe. Default 1.
void SetDefaultThreads(int threads);
int DefaultThreads();

}  // namespace aosr
