// Skips that `scripts/lgp.sh test` does not allow. That command installs every package the
// GPU, MPI, Python and daemon tests need and builds every part, then runs CTest with
// LGP_TEST_NO_SKIP=1: a test of those areas that would skip there (no Vulkan driver, no
// mpirun, no chromium, a part left out of the build) points at a broken build, so it fails
// instead, with the reason. Elsewhere (a developer's partial build) it skips as before.
//   if (!found) LGP_SKIP_UNLESS_REQUIRED() << "mpirun not found";
#pragma once

#include <cstdlib>
#include <cstring>

#include <gtest/gtest.h>

namespace lgp_test {

inline bool skipsAreFailures() {
  const char* v = std::getenv("LGP_TEST_NO_SKIP");
  return v && *v && std::strcmp(v, "0") != 0;
}

}  // namespace lgp_test

// GTEST_SKIP(), or under LGP_TEST_NO_SKIP a fatal failure; the streamed reason goes with either.
#define LGP_SKIP_UNLESS_REQUIRED()                                                                \
  return GTEST_MESSAGE_(::lgp_test::skipsAreFailures()                                            \
                            ? "LGP_TEST_NO_SKIP is set (scripts/lgp.sh test): this test "         \
                              "may not skip, and would have: "                                    \
                            : "",                                                                 \
                        ::lgp_test::skipsAreFailures() ? ::testing::TestPartResult::kFatalFailure \
                                                       : ::testing::TestPartResult::kSkip)
