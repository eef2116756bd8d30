// The table and scene readers check the file they have opened against the data roots (lgpd's
// allowed_data_dirs), by its descriptor: a link inside a root that leads outside is refused
// (as is a file swapped for such a link after a check by path), a file inside is read, and
// without roots every file is read.
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "lgp/core/data_roots.hpp"
#include "lgp/core/table.hpp"

namespace lgp {
namespace {

namespace fs = std::filesystem;

struct LiftRoots {
  ~LiftRoots() { setDataRoots({}); }
};

TEST(DataRoots, ATableOpenedThroughALinkToOutsideIsRefused) {
  const fs::path base = fs::temp_directory_path() / ("lgp_roots_" + std::to_string(getpid()));
  const fs::path allowed = base / "allowed", outside = base / "outside";
  fs::create_directories(allowed);
  fs::create_directories(outside);
  for (const fs::path& d : {allowed, outside}) std::ofstream(d / "t.csv") << "x,f\n1,2\n3,4\n";
  fs::create_symlink(outside / "t.csv", allowed / "link.csv");
  fs::create_symlink(allowed, base / "via-link");  // a root named through a link
  {
    LiftRoots lift;
    setDataRoots({base / "via-link"});
    auto in = readTableFile(allowed / "t.csv");
    EXPECT_TRUE(in) << in.error();
    for (const fs::path& p : {allowed / "link.csv", outside / "t.csv"}) {
      auto out = readTableFile(p);
      ASSERT_FALSE(out) << p;
      EXPECT_EQ(out.error(), p.string() + ": is outside the allowed data directories");
    }
    auto json = readTableFile(outside / "t.json");  // a missing file: the open fails first
    EXPECT_FALSE(json);
  }
  EXPECT_TRUE(readTableFile(allowed / "link.csv"));  // no roots: read from anywhere
  fs::remove_all(base);
}

}  // namespace
}  // namespace lgp
