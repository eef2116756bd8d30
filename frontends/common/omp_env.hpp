// Process start-up for the executables that run searches (lgp, lgpd).
#pragma once

#include <unistd.h>

#include <cstdlib>

namespace lgp::cli {

// Each generation runs a few short parallel regions; libgomp's default spin-waiting makes
// threads burn their partners' time slices on a shared machine (measured 4.8x slower with 2
// threads under load). libgomp reads the policy when it loads, before main, so this sets it
// and re-executes the program once. An explicit OMP_WAIT_POLICY from the user is respected;
// if the exec fails the program simply continues with the default policy.
inline void ensurePassiveOpenMpWaits(char** argv) {
  if (std::getenv("OMP_WAIT_POLICY")) return;
  setenv("OMP_WAIT_POLICY", "passive", 1);
  execv("/proc/self/exe", argv);
}

}  // namespace lgp::cli
