#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <random>
#include <sstream>

#include "lgp/config/json_reader.hpp"
#include "lgp/core/program.hpp"
#include "lgp/core/table.hpp"
#include "lgp/datasets/generate.hpp"

namespace lgp::datasets {

namespace {
namespace fs = std::filesystem;

uint64_t fnv1a(const std::string& s) {
  uint64_t h = 0xcbf29ce484222325ull;
  for (unsigned char c : s) {
    h ^= c;
    h *= 0x100000001b3ull;
  }
  return h;
}

std::string hex(uint64_t v) {
  char b[17];
  std::snprintf(b, sizeof b, "%016llx", static_cast<unsigned long long>(v));
  return b;
}

// Returns the payload if header, length and checksum all match; else an error saying why.
Expected<std::string> readVerified(const fs::path& file) {
  auto text = readInputFile(file);  // a regular file only, never a FIFO or a directory
  if (!text) return text.status();
  const size_t eol = text->find('\n');
  if (text->empty()) return Status::error("empty file");
  if (eol == std::string::npos) return Status::error("bad header");
  std::istringstream hs(text->substr(0, eol));
  std::string magic, sum;
  size_t len = 0;
  if (!(hs >> magic >> sum >> len) || magic != "lgp-cache/1") return Status::error("bad header");
  std::string payload = text->substr(eol + 1);
  if (payload.size() != len)
    return Status::error("truncated (" + std::to_string(payload.size()) + " of " +
                         std::to_string(len) + " bytes)");
  if (hex(fnv1a(payload)) != sum) return Status::error("checksum mismatch");
  return payload;
}
}  // namespace

std::string cacheKey(const Scene& scene) {
  return hex(fnv1a(toJson(scene).dump() + "\n" + kGeneratorVersion));
}

fs::path defaultCacheDir() {
  if (const char* d = std::getenv("LGP_CACHE_DIR"); d && *d) return d;
  if (const char* x = std::getenv("XDG_CACHE_HOME"); x && *x) return fs::path(x) / "lgp";
  if (const char* h = std::getenv("HOME"); h && *h) return fs::path(h) / ".cache" / "lgp";
  return ".lgp-cache";
}

namespace {
// Why the cache directory, or the entry in it, may hold what another user wrote ("" when it
// cannot): a directory others may write (unless sticky, as /tmp, where they cannot replace our
// files) or that another user owns, and an entry that is a link, not ours, or writable by
// others. Such a cache is neither read nor written.
std::string untrustedReason(const fs::path& dir, const fs::path& file) {
  struct stat st {};
  const uid_t me = ::geteuid();
  if (::stat(dir.c_str(), &st) == 0) {
    if (st.st_uid != me && st.st_uid != 0) return "the cache directory belongs to another user";
    if ((st.st_mode & (S_IWGRP | S_IWOTH)) && !(st.st_mode & S_ISVTX))
      return "the cache directory is writable by other users";
  }
  if (::lstat(file.c_str(), &st) == 0) {
    if (S_ISLNK(st.st_mode)) return "the cache entry is a symbolic link";
    if (st.st_uid != me) return "the cache entry belongs to another user";
    if (st.st_mode & (S_IWGRP | S_IWOTH)) return "the cache entry is writable by other users";
  }
  return "";
}

// Is `g` the table of `scene`, as this generator makes it? Its recorded scene and generator
// version, its columns and grid, and (a checksum is no signature: anyone who can write the
// file can recompute it) kSpotRows rows recomputed at random and compared within their error
// estimates.
constexpr size_t kSpotRows = 8;
Status checkEntry(const Scene& scene, const GeneratedTable& g, const GenerateOptions& opt) {
  const Table& t = g.table;
  if (t.meta.value("generator_version", std::string()) != kGeneratorVersion)
    return Status::error("made by another generator version");
  if (!t.meta.contains("scene") || t.meta["scene"] != toJson(scene))
    return Status::error("made for another scene");
  if (t.input_names != scene.inputNames() || t.output_names != scene.outputs ||
      t.rows() != scene.rows() || g.errors.size() != t.outputs.size())
    return Status::error("its columns are not the scene's");
  size_t stride = 1;
  for (size_t a = 0; a < scene.grid.size(); ++a) {
    const auto& values = scene.grid[a].values;
    for (size_t row = 0; row < t.rows(); ++row)
      if (t.inputs[a][row] != values[(row / stride) % values.size()])
        return Status::error("its " + scene.grid[a].name + " column is not the scene's grid");
    stride *= values.size();
  }
  for (const auto& e : g.errors)
    for (double v : e)
      if (!(v >= 0.0) || !std::isfinite(v)) return Status::error("an error estimate is not valid");
  std::vector<size_t> rows;
  std::mt19937_64 rng(std::random_device{}());
  std::uniform_int_distribution<size_t> pick(0, t.rows() - 1);
  while (rows.size() < std::min(kSpotRows, t.rows())) {
    const size_t r = pick(rng);
    if (std::find(rows.begin(), rows.end(), r) == rows.end()) rows.push_back(r);
  }
  auto fresh = generateRows(scene, rows, opt);
  if (!fresh) return fresh.status();
  for (size_t k = 0; k < t.outputs.size(); ++k)
    for (size_t i = 0; i < rows.size(); ++i) {
      const double want = fresh->value[k][i], got = t.outputs[k][rows[i]];
      const double tol = 2.0 * std::max(fresh->error[k][i], scene.accuracy.abs_error) +
                         1e-12 * std::abs(want);
      if (!(std::abs(got - want) <= tol))
        return Status::error("its " + t.output_names[k] + " at row " +
                             std::to_string(rows[i] + 1) + " is " + formatDouble(got) +
                             ", recomputed " + formatDouble(want));
    }
  return Status::ok();
}

// The entry at `file`, if it holds the scene's table; else why not.
Expected<GeneratedTable> readEntry(const Scene& scene, const fs::path& file,
                                   const GenerateOptions& opt) {
  auto payload = readVerified(file);
  if (!payload) return Status::error("corrupt (" + payload.error() + ")");
  JsonLimits limits;
  limits.max_bytes = payload->size();  // checked by readVerified
  auto j = parseJson(*payload, limits);
  if (!j) return Status::error("unusable (" + j.error() + ")");
  Expected<GeneratedTable> g = Status::error("unusable");
  try {
    g = fromTableJson(*j, file.string());
  } catch (const nlohmann::json::exception& e) {
    return Status::error(std::string("unusable (") + e.what() + ")");
  }
  if (!g) return Status::error("unusable (" + g.error() + ")");
  if (auto st = checkEntry(scene, *g, opt); !st) {
    if (st.message() == kGenerationStopped) return st;
    return Status::error("not this scene's table (" + st.message() + ")");
  }
  return g;
}

void addNote(CachedTable& out, const std::string& note) {
  out.note += (out.note.empty() ? "" : "; ") + note;
}

// Writes the entry atomically: a reader never sees a half-written file under the final name.
void writeEntry(CachedTable& out, const fs::path& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return addNote(out, "cache not written: " + ec.message());
  const std::string payload = toTableJson(out.table).dump();
  std::mt19937_64 rng(std::random_device{}());
  const fs::path tmp = dir / (out.file.filename().string() + ".tmp" + hex(rng()));
  {
    std::ofstream o(tmp, std::ios::binary);
    o << "lgp-cache/1 " << hex(fnv1a(payload)) << " " << payload.size() << "\n" << payload;
    if (!o) {
      fs::remove(tmp, ec);
      return addNote(out, "cache not written");
    }
  }
  fs::rename(tmp, out.file, ec);
  if (ec) {
    fs::remove(tmp, ec);
    addNote(out, "cache not written");
  }
}
}  // namespace

Expected<CachedTable> generateCached(const Scene& scene, const fs::path& dir,
                                     const GenerateOptions& opt, bool refresh) {
  CachedTable out;
  out.file = dir / (cacheKey(scene) + ".lgpt");
  const std::string distrust = untrustedReason(dir, out.file);
  std::error_code ec;
  if (!distrust.empty()) {
    addNote(out, "cache at " + dir.string() + " not used: " + distrust);
  } else if (!refresh && fs::exists(out.file, ec)) {
    auto g = readEntry(scene, out.file, opt);
    if (g) {
      out.table = std::move(*g);
      out.hit = true;
      return out;
    }
    if (g.error() == kGenerationStopped) return g.status();
    addNote(out, "cache file " + out.file.string() + " " + g.error() + "; regenerated");
  }
  auto g = generate(scene, opt);
  if (!g) return g.status();
  out.table = std::move(*g);
  if (distrust.empty()) writeEntry(out, dir);
  return out;
}

}  // namespace lgp::datasets
