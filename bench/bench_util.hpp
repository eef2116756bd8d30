// Small pieces shared by the benchmark programs.
#pragma once

#include <time.h>

#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <string>

#include <nlohmann/json.hpp>

namespace lgp::bench {

// CPU time of the calling thread: on a shared machine it leaves out time spent descheduled.
inline double threadCpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// The value following option argv[i] (i advances past it); exits with a message if missing.
inline const char* optionValue(int argc, char** argv, int& i) {
  if (i + 1 >= argc) {
    std::fprintf(stderr, "%s needs a value\n", argv[i]);
    std::exit(2);
  }
  return argv[++i];
}

// The CPU model from /proc/cpuinfo (benchmarks print it: machines differ between runs).
inline std::string cpuModel() {
  std::ifstream f("/proc/cpuinfo");
  for (std::string line; std::getline(f, line);)
    if (line.rfind("model name", 0) == 0) {
      const auto c = line.find(':');
      if (c != std::string::npos) return line.substr(line.find_first_not_of(" \t", c + 1));
    }
  return "unknown";
}

// A markdown table cell: '|' escaped, line breaks joined with spaces (a reference's name or a
// compiler's multi-line message stays one cell).
inline std::string mdEscape(const std::string& s) {
  std::string o;
  for (char c : s)
    o += c == '|'                   ? std::string("\\|")
         : (c == '\n' || c == '\r') ? std::string(" ")
                                    : std::string(1, c);
  return o;
}

inline std::string utcNow() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char b[32];
  std::strftime(b, sizeof(b), "%Y-%m-%d %H:%M UTC", &tm);
  return b;
}

// A run config's JSON read from `config` for a benchmark on the table file `table`: the data
// section points at the table (no scene), references and outputs are dropped, and the search
// runs on `threads` threads without a wall-time budget. Exits with a message if `config` is
// not JSON.
inline nlohmann::json benchConfigJson(const char* config, const char* table, int threads) {
  std::ifstream in(config);
  nlohmann::json j = nlohmann::json::parse(in, nullptr, false);
  if (j.is_discarded()) {
    std::fprintf(stderr, "%s: not JSON\n", config);
    std::exit(1);
  }
  j["data"].erase("scene");
  j["data"]["path"] = std::filesystem::absolute(table).string();
  j.erase("references");
  j.erase("output");
  j["search"]["seed_references"] = false;
  j["search"]["threads"] = threads;
  j["search"].erase("wall_time_s");
  return j;
}

}  // namespace lgp::bench
