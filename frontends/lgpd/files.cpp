#include "files.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "lgp/config/json_reader.hpp"
#include "lgp/core/table.hpp"

namespace lgpd {

using lgp::Expected;
using lgp::Status;

RegularFile& RegularFile::operator=(RegularFile&& o) noexcept {
  if (this != &o) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = o.fd_;
    size_ = o.size_;
    o.fd_ = -1;
  }
  return *this;
}

RegularFile::~RegularFile() {
  if (fd_ >= 0) ::close(fd_);
}

Expected<RegularFile> RegularFile::open(const std::filesystem::path& p) {
  const std::string name = p.string();
  // O_NONBLOCK: opening a FIFO for reading returns at once instead of waiting for a writer;
  // O_NOCTTY: a terminal device never becomes our controlling terminal.
  int fd = ::open(name.c_str(), O_RDONLY | O_NONBLOCK | O_NOCTTY | O_CLOEXEC);
  if (fd < 0) {
    const int e = errno;
    if (e == ENOENT) return Status::error(name + " does not exist");
    if (e == ENOTDIR) return Status::error(name + ": a component of the path is not a directory");
    return Status::error(name + " cannot be read: " + std::strerror(e));
  }
  RegularFile f;
  f.fd_ = fd;
  struct stat st {};
  if (::fstat(fd, &st) != 0) return Status::error(name + ": " + std::strerror(errno));
  if (S_ISDIR(st.st_mode)) return Status::error(name + " is a directory, not a file");
  if (!S_ISREG(st.st_mode)) {
    const char* what = S_ISFIFO(st.st_mode)   ? "a FIFO"
                       : S_ISSOCK(st.st_mode) ? "a socket"
                       : S_ISCHR(st.st_mode)  ? "a character device"
                       : S_ISBLK(st.st_mode)  ? "a block device"
                                              : "not a plain file";
    return Status::error(name + " is not a regular file (" + what + ")");
  }
  // Reads of a regular file never block; clear the flag anyway for whoever reads the fd.
  ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) & ~O_NONBLOCK);
  f.size_ = static_cast<size_t>(st.st_size);
  return f;
}

Expected<std::string> RegularFile::read(size_t max_bytes) {
  std::string out;
  char buf[65536];
  while (out.size() < max_bytes) {
    const size_t want = std::min(sizeof buf, max_bytes - out.size());
    const ssize_t n = ::read(fd_, buf, want);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return Status::error(std::string("read error: ") + std::strerror(errno));
    if (n == 0) break;
    out.append(buf, static_cast<size_t>(n));
  }
  return out;
}

Expected<nlohmann::json> readJsonDocument(const std::filesystem::path& p, size_t max_bytes) {
  auto text = lgp::readInputFile(p, max_bytes);  // regular files only, never blocks
  if (!text) return text.status();
  lgp::JsonLimits limits;
  limits.max_bytes = max_bytes;
  auto j = lgp::parseJson(*text, limits);
  if (!j) return Status::error(p.string() + ": " + j.error());
  return j;
}

}  // namespace lgpd
