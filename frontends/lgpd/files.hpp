// Reading files that a request or the operator names, without ever blocking: a FIFO, a
// device or a directory where a table or a config should be is refused before anything is
// read from it (a FIFO opened for reading would otherwise wait for a writer forever).
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "lgp/core/status.hpp"

namespace lgpd {

// An open regular file (closed on destruction).
class RegularFile {
 public:
  RegularFile() = default;
  RegularFile(RegularFile&& o) noexcept : fd_(o.fd_), size_(o.size_) { o.fd_ = -1; }
  RegularFile& operator=(RegularFile&& o) noexcept;
  RegularFile(const RegularFile&) = delete;
  RegularFile& operator=(const RegularFile&) = delete;
  ~RegularFile();

  // Opens `p` for reading with O_NONBLOCK, then checks with fstat that it is a regular file.
  // Errors: "is a directory", "is not a regular file (a FIFO)", "does not exist",
  // "cannot be read: Permission denied", each after the path.
  static lgp::Expected<RegularFile> open(const std::filesystem::path& p);

  int fd() const { return fd_; }
  size_t size() const { return size_; }
  // Up to `max_bytes` from the current position.
  lgp::Expected<std::string> read(size_t max_bytes);

 private:
  int fd_ = -1;
  size_t size_ = 0;
};

// lgp::readInputFile (a regular file of at most `max_bytes`, opened without blocking), then
// lgp::parseJson (depth, size, number range, duplicate keys). The
// error starts with the path.
lgp::Expected<nlohmann::json> readJsonDocument(const std::filesystem::path& p, size_t max_bytes);

}  // namespace lgpd
