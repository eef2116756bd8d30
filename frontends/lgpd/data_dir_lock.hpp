// One daemon per data dir: lgpd holds an exclusive flock on DIR/lgpd.lock for as long as it
// runs, taken before it opens the database or resumes a run. Two daemons on one dir would
// both "resume" the same running run and overwrite each other's front. The file holds the
// holder's PID so that the second daemon's message can name it. The lock goes with the
// process (flock is released when its last descriptor closes, also after kill -9), so a
// stale file never blocks a restart.
#pragma once

#include <filesystem>
#include <memory>

#include "lgp/core/status.hpp"

namespace lgpd {

class DataDirLock {
 public:
  // Creates DIR (and the lock file) if missing. Error when another process holds the lock:
  // "the data dir DIR is in use by another lgpd (pid N, see DIR/lgpd.lock); ...".
  static lgp::Expected<std::unique_ptr<DataDirLock>> acquire(const std::filesystem::path& dir);
  ~DataDirLock();
  DataDirLock(const DataDirLock&) = delete;
  DataDirLock& operator=(const DataDirLock&) = delete;

 private:
  explicit DataDirLock(int fd) : fd_(fd) {}
  int fd_ = -1;
};

}  // namespace lgpd
