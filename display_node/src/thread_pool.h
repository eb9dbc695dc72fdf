// A fixed set of worker threads that run the CPU backend's parallel phases: run() hands out
// task indices from a shared counter (the caller works too) and returns when all are done.
// Workers sleep on a condition variable between phases.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <thread>
#include <vector>

namespace afr {

class ThreadPool {
 public:
  // threads: the total including the calling thread (>= 1).
  explicit ThreadPool(int threads);
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  int size() const { return int(workers_.size()) + 1; }

  // Calls fn(task) once for every task in [0, tasks), spread over the threads.
  template <typename Fn>
  void run(int tasks, Fn&& fn) {
    run_erased(
        tasks, [](void* f, int task) { (*static_cast<Fn*>(f))(task); }, &fn);
  }

 private:
  using Erased = void (*)(void*, int);
  void run_erased(int tasks, Erased call, void* fn);
  void work(Erased call, void* fn, int tasks);
  void worker_loop();

  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::condition_variable done_;
  // The current phase, guarded by mutex_.
  uint64_t generation_ = 0;
  Erased call_ = nullptr;
  void* fn_ = nullptr;
  int tasks_ = 0;
  int busy_ = 0;
  bool stop_ = false;
  std::atomic<int> next_{0};
};

}  // namespace afr
