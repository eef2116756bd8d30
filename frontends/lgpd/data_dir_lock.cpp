#include "data_dir_lock.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <string>

namespace lgpd {

namespace fs = std::filesystem;
using lgp::Expected;
using lgp::Status;

namespace {

// The PID the holder wrote, or "" when the file holds none (yet).
std::string readPid(int fd) {
  char buf[32] = {0};
  ssize_t n = ::pread(fd, buf, sizeof buf - 1, 0);
  if (n <= 0) return "";
  std::string s(buf, static_cast<size_t>(n));
  while (!s.empty() && (s.back() == '\n' || s.back() == ' ')) s.pop_back();
  for (char c : s)
    if (c < '0' || c > '9') return "";
  return s;
}

}  // namespace

Expected<std::unique_ptr<DataDirLock>> DataDirLock::acquire(const fs::path& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return Status::error("cannot create data dir " + dir.string() + ": " + ec.message());
  const fs::path path = dir / "lgpd.lock";
  // O_CLOEXEC: a launched MPI run must not inherit (and so keep) the lock after lgpd ends.
  int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644);
  if (fd < 0)
    return Status::error("cannot open the lock file " + path.string() + ": " +
                         std::strerror(errno));
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const int err = errno;
    std::string pid = err == EWOULDBLOCK ? readPid(fd) : "";
    ::close(fd);
    if (err != EWOULDBLOCK)
      return Status::error("cannot lock " + path.string() + ": " + std::strerror(err));
    return Status::error("the data dir " + dir.string() + " is in use by another lgpd (" +
                         (pid.empty() ? std::string("pid not yet written") : "pid " + pid) +
                         ", see " + path.string() +
                         "); one lgpd per data dir: stop that one or give this one another "
                         "--data-dir");
  }
  const std::string pid = std::to_string(::getpid()) + "\n";
  if (::ftruncate(fd, 0) != 0 ||
      ::pwrite(fd, pid.data(), pid.size(), 0) != static_cast<ssize_t>(pid.size())) {
    const int err = errno;
    ::close(fd);
    return Status::error("cannot write the lock file " + path.string() + ": " + std::strerror(err));
  }
  return std::unique_ptr<DataDirLock>(new DataDirLock(fd));
}

DataDirLock::~DataDirLock() {
  if (fd_ >= 0) ::close(fd_);
}

}  // namespace lgpd
