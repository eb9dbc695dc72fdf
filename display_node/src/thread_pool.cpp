#include "thread_pool.h"

#include <afr/common/check.h>

namespace afr {

ThreadPool::ThreadPool(int threads) {
  AFR_CHECK(threads >= 1);
  workers_.reserve(size_t(threads - 1));
  for (int i = 1; i < threads; ++i) workers_.emplace_back([this] { worker_loop(); });
}

ThreadPool::~ThreadPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  for (std::thread& t : workers_) t.join();
}

void ThreadPool::work(Erased call, void* fn, int tasks) {
  for (int task = next_.fetch_add(1); task < tasks; task = next_.fetch_add(1)) call(fn, task);
}

void ThreadPool::run_erased(int tasks, Erased call, void* fn) {
  if (tasks <= 0) return;
  if (workers_.empty() || tasks == 1) {
    for (int task = 0; task < tasks; ++task) call(fn, task);
    return;
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    call_ = call;
    fn_ = fn;
    tasks_ = tasks;
    next_.store(0);
    busy_ = int(workers_.size());
    ++generation_;
  }
  wake_.notify_all();
  work(call, fn, tasks);
  // Every worker reports back before the phase ends, so none still touches fn afterwards.
  std::unique_lock<std::mutex> lock(mutex_);
  done_.wait(lock, [this] { return busy_ == 0; });
}

void ThreadPool::worker_loop() {
  uint64_t seen = 0;
  for (;;) {
    Erased call;
    void* fn;
    int tasks;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [&] { return stop_ || generation_ != seen; });
      if (stop_) return;
      seen = generation_;
      call = call_;
      fn = fn_;
      tasks = tasks_;
    }
    work(call, fn, tasks);
    std::lock_guard<std::mutex> lock(mutex_);
    if (--busy_ == 0) done_.notify_one();
  }
}

}  // namespace afr
