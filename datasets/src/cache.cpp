#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <random>
#include <sstream>

#include "lgp/config/json_reader.hpp"
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

Expected<CachedTable> generateCached(const Scene& scene, const fs::path& dir,
                                     const GenerateOptions& opt) {
  CachedTable out;
  out.file = dir / (cacheKey(scene) + ".lgpt");
  std::error_code ec;
  if (fs::exists(out.file, ec)) {
    auto payload = readVerified(out.file);
    if (payload) {
      JsonLimits limits;
      limits.max_bytes = payload->size();  // checked by readVerified
      auto j = parseJson(*payload, limits);
      try {
        auto g = j ? fromTableJson(*j, out.file.string()) : Expected<GeneratedTable>(j.status());
        if (g) {
          out.table = std::move(*g);
          out.hit = true;
          return out;
        }
        out.note = "cache file " + out.file.string() + " unusable (" + g.error() + "); regenerated";
      } catch (const nlohmann::json::exception& e) {
        out.note = "cache file " + out.file.string() + " unusable (" + e.what() + "); regenerated";
      }
    } else {
      out.note =
          "cache file " + out.file.string() + " corrupt (" + payload.error() + "); regenerated";
    }
  }
  auto g = generate(scene, opt);
  if (!g) return g.status();
  out.table = std::move(*g);
  // Write atomically: a reader never sees a half-written file under the final name.
  fs::create_directories(dir, ec);
  if (ec) {
    out.note += (out.note.empty() ? "" : "; ") + std::string("cache not written: ") + ec.message();
    return out;
  }
  const std::string payload = toTableJson(out.table).dump();
  std::mt19937_64 rng(std::random_device{}());
  const fs::path tmp = dir / (out.file.filename().string() + ".tmp" + hex(rng()));
  {
    std::ofstream o(tmp, std::ios::binary);
    o << "lgp-cache/1 " << hex(fnv1a(payload)) << " " << payload.size() << "\n" << payload;
    if (!o) {
      out.note += (out.note.empty() ? "" : "; ") + std::string("cache not written");
      fs::remove(tmp, ec);
      return out;
    }
  }
  fs::rename(tmp, out.file, ec);
  if (ec) {
    fs::remove(tmp, ec);
    out.note += (out.note.empty() ? "" : "; ") + std::string("cache not written");
  }
  return out;
}

}  // namespace lgp::datasets
