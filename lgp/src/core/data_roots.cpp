#include "lgp/core/data_roots.hpp"

#include <cstdio>
#include <mutex>

#include "lgp/core/table.hpp"

namespace lgp {

namespace fs = std::filesystem;

namespace {

std::mutex g_mutex;
std::vector<fs::path> g_roots;

bool inside(const fs::path& p, const fs::path& root) {
  const fs::path rel = p.lexically_relative(root);
  return !rel.empty() && *rel.begin() != "..";
}

}  // namespace

void setDataRoots(const std::vector<fs::path>& roots) {
  std::vector<fs::path> resolved;
  for (const auto& r : roots) {
    std::error_code ec;
    fs::path c = fs::weakly_canonical(fs::absolute(r), ec);
    resolved.push_back(ec ? fs::absolute(r).lexically_normal() : c);
  }
  std::lock_guard lock(g_mutex);
  g_roots = std::move(resolved);
}

Status checkDataRoots(int fd, const std::string& shown) {
  std::vector<fs::path> roots;
  {
    std::lock_guard lock(g_mutex);
    roots = g_roots;
  }
  if (roots.empty()) return Status::ok();
  // The kernel's name for the open file: every link resolved, as it was when it was opened.
  char link[64];
  std::snprintf(link, sizeof link, "/proc/self/fd/%d", fd);
  std::error_code ec;
  const fs::path real = fs::read_symlink(link, ec);
  if (ec || !real.is_absolute())
    return Status::error(shown + ": cannot tell where the opened file lies, so it is not read");
  for (const auto& r : roots)
    if (inside(real, r)) return Status::ok();
  return Status::error(shown + ": is outside the allowed data directories");
}

Expected<std::string> readDataFile(const fs::path& path, size_t max_bytes) {
  return readInputFile(path, max_bytes, &checkDataRoots);
}

}  // namespace lgp
