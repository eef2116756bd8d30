// The README's settings table states the code's defaults: its search.refine and search.archive
// rows are read from README.md and compared with a default RunConfig.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>

#include "lgp/config/config.hpp"

namespace lgp {
namespace {

// The table row whose first cell is `key` (e.g. "`search.refine`").
std::string readmeRow(const std::string& key) {
  std::ifstream in(std::string(LGP_SOURCE_DIR) + "/README.md");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("| " + key + " |", 0) == 0) return line;
  return "";
}

TEST(ReadmeDefaults, RefineRowStatesTheOffspringShare) {
  const std::string row = readmeRow("`search.refine`");
  ASSERT_FALSE(row.empty()) << "no `search.refine` row in README.md";
  const RunConfig c;
  char want[64];
  std::snprintf(want, sizeof want, "`offspring_share` %.1f", c.search.refine.offspring_share);
  EXPECT_NE(row.find(want), std::string::npos) << row << "\nwants: " << want;
  EXPECT_NE(row.find("LM " + std::to_string(c.search.refine.lm_iterations) + " iterations"),
            std::string::npos)
      << row;
  EXPECT_NE(row.find("every " + std::to_string(c.search.refine.archive_period) + " gens"),
            std::string::npos)
      << row;
}

TEST(ReadmeDefaults, ArchiveRowStatesTheBoxWidth) {
  const std::string row = readmeRow("`search.archive`");
  ASSERT_FALSE(row.empty()) << "no `search.archive` row in README.md";
  const RunConfig c;
  // A box of eps decades spans a factor 10^eps in error: 0.01 decades is 2.3 %.
  const double eps = c.search.archive.eps_log10_error;
  char decades[32], percent[32];
  std::snprintf(decades, sizeof decades, "%g decades", eps);
  std::snprintf(percent, sizeof percent, "(%.1f %%)", 100 * (std::pow(10.0, eps) - 1));
  EXPECT_NE(row.find(std::to_string(c.search.archive.max_size) + " members"), std::string::npos)
      << row;
  EXPECT_NE(row.find(decades), std::string::npos) << row << "\nwants: " << decades;
  EXPECT_NE(row.find(percent), std::string::npos) << row << "\nwants: " << percent;
}

}  // namespace
}  // namespace lgp
