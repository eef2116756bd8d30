// Small pieces shared by the benchmark programs.
#pragma once

#include <time.h>

#include <cstdio>
#include <cstdlib>

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

}  // namespace lgp::bench
