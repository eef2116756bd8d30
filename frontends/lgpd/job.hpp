// What the three parts of the job queue share (jobs.cpp: the queue and a job's start,
// local_job.cpp: a search in process, mpi_job.cpp: a search over MPI in a child process).
#pragma once

#include <atomic>
#include <chrono>
#include <mutex>
#include <string>
#include <thread>

#include "jobs.hpp"
#include "lgp/search/search.hpp"

namespace lgpd {

struct JobManager::Job {
  std::string id;
  std::thread thread;
  std::atomic<bool> cancel{false};
  std::atomic<bool> deleted{false};
  std::atomic<bool> shutdown{false};
  std::atomic<bool> finished{false};
  std::mutex search_mutex;
  lgp::Search* search = nullptr;  // valid while the job thread runs its search

  void requestStop() {
    std::lock_guard lock(search_mutex);
    if (search) search->requestStop();
  }
  // The search a cancel reaches (nullptr: none, before the job's search goes away).
  void attach(lgp::Search* s) {
    std::lock_guard lock(search_mutex);
    search = s;
  }
  // Whether the run is to stop: cancelled, deleted or the daemon stopping.
  bool stopRequested() const { return cancel.load() || deleted.load() || shutdown.load(); }
};

inline double seconds(std::chrono::steady_clock::duration d) {
  return std::chrono::duration<double>(d).count();
}

}  // namespace lgpd
