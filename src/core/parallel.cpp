#include "aosr/core/parallel.hpp"

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

#include "aosr/core/error.hpp"

namespace aosr {
namespace {

std::atomic<int> g_default_threads{1};

// One job at a time: a caller that finds the pool busy (or is itself a pool worker) runs its loop inline.
class Pool {
 public:
  static Pool& Get() {
    static Pool* pool = new Pool;  // never destroyed: workers may outlive static destruction order
    return *pool;
  }

  // Returns false (doing nothing) if the pool is busy; the caller then runs the loop itself.
  bool TryRun(Index count, int threads, const std::function<void(Index)>& fn) {
    std::unique_lock<std::mutex> job_lock(job_mutex_, std::try_to_lock);
    if (!job_lock.owns_lock() || t_in_pool) return false;
    const int helpers = threads - 1;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      // A new worker's rank and the generation it has "seen" are fixed here, under the lock, so it takes
      // part in this job even if it starts running after the bump below.
      while (int(workers_.size()) < helpers) {
        const int rank = int(workers_.size());
        workers_.emplace_back([this, rank, seen = generation_] { WorkerLoop(rank, seen); });
      }
      fn_ = &fn;
      count_ = count;
      next_.store(0);
      error_ = nullptr;
      active_helpers_ = helpers;
      pending_ = helpers;
      ++generation_;
    }
    wake_.notify_all();
    t_in_pool = true;
    Work();
    t_in_pool = false;
    std::unique_lock<std::mutex> lock(mutex_);
    done_.wait(lock, [this] { return pending_ == 0; });
    fn_ = nullptr;
    if (error_) std::rethrow_exception(error_);
    return true;
  }

 private:
  void WorkerLoop(int index, std::uint64_t seen) {
    t_in_pool = true;
    for (;;) {
      {
        std::unique_lock<std::mutex> lock(mutex_);
        wake_.wait(lock, [&] { return generation_ != seen; });
        seen = generation_;
        if (index >= active_helpers_) continue;  // not needed for this job
      }
      Work();
      std::lock_guard<std::mutex> lock(mutex_);
      if (--pending_ == 0) done_.notify_one();
    }
  }

  // Dynamic scheduling: tasks are taken from a shared counter (which thread runs k does not matter).
  void Work() {
    for (;;) {
      const Index k = next_.fetch_add(1);
      if (k >= count_) return;
      try {
        (*fn_)(k);
      } catch (...) {
        std::lock_guard<std::mutex> lock(mutex_);
        if (!error_) error_ = std::current_exception();
        next_.store(count_);  // stop handing out work
      }
    }
  }

  static thread_local bool t_in_pool;
  std::mutex job_mutex_;  // held by the thread whose job the pool runs
  std::mutex mutex_;
  std::condition_variable wake_, done_;
  std::vector<std::thread> workers_;
  const std::function<void(Index)>* fn_ = nullptr;
  Index count_ = 0;
  std::atomic<Index> next_{0};
  std::exception_ptr error_;
  int active_helpers_ = 0, pending_ = 0;
  std::uint64_t generation_ = 0;
};

thread_local bool Pool::t_in_pool = false;

}  // namespace

void ParallelFor(Index count, int threads, const std::function<void(Index)>& fn) {
  CheckArgument(threads >= 1, "ParallelFor", "threads", threads, ">= 1");
  CheckArgument(count >= 0, "ParallelFor", "count", count, ">= 0");
  threads = int(std::min<Index>(threads, count));
  if (threads > 1 && Pool::Get().TryRun(count, threads, fn)) return;
  for (Index k = 0; k < count; ++k) fn(k);
}

void ParallelFor(Index count, const std::function<void(Index)>& fn) { ParallelFor(count, DefaultThreads(), fn); }

void SetDefaultThreads(int threads) {
  CheckArgument(threads >= 1 && threads <= 256, "SetDefaultThreads", "threads", threads, "1 .. 256");
  g_default_threads.store(threads);
}

int DefaultThreads() { return g_default_threads.load(); }

}  // namespace aosr
