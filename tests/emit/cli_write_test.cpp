// `lgp emit` output: a failed write (a full device, a missing folder, stdout on a full device)
// exits non-zero with a message, and -o writes exactly what stdout gets.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "../shell.hpp"

namespace {

namespace fs = std::filesystem;
using lgp_test::sh;

class EmitWrite : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / ("lgp-emit-write-" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    const auto r = sh(lgp() + " run " + std::string(LGP_SOURCE_DIR) +
                      "/examples/quickstart.json -q --generations 5 --threads 1 -o " +
                      (dir_ / "front.json").string() + " --csv ''");
    ASSERT_EQ(r.code, 0) << r.out;
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }
  static std::string lgp() { return LGP_CLI_PATH; }
  static std::string emit() { return lgp() + " emit " + (dir_ / "front.json").string() + " "; }
  static fs::path dir_;
};
fs::path EmitWrite::dir_;

TEST_F(EmitWrite, FullDeviceFails) {
  const auto r = sh(emit() + "--no-measure -o /dev/full");
  EXPECT_NE(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("/dev/full: write failed"), std::string::npos) << r.out;
  // The device is still a device: -o never replaces what it names with a file.
  EXPECT_TRUE(fs::is_character_file("/dev/full"));
}

TEST_F(EmitWrite, FullStdoutFails) {
  // Only stdout to the full device; the message still reaches the pipe.
  const auto r = sh("(" + emit() + "--no-measure > /dev/full)");
  EXPECT_NE(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("standard output: write failed"), std::string::npos) << r.out;
}

TEST_F(EmitWrite, MissingFolderFailsAndLeavesNothing) {
  const fs::path out = dir_ / "no" / "such" / "f.hlsl";
  const auto r = sh(emit() + "--no-measure -o " + out.string());
  EXPECT_NE(r.code, 0) << r.out;
  EXPECT_FALSE(fs::exists(out));
}

TEST_F(EmitWrite, FileGetsWhatStdoutGets) {
  const fs::path out = dir_ / "m.hlsl";
  const auto a = sh(emit() + "--no-measure -o " + out.string());
  ASSERT_EQ(a.code, 0) << a.out;
  const auto b = sh(emit() + "--no-measure 2>/dev/null");
  ASSERT_EQ(b.code, 0);
  std::ifstream f(out);
  std::stringstream text;
  text << f.rdbuf();
  EXPECT_EQ(text.str(), b.out);
  EXPECT_FALSE(fs::exists(out.string() + ".tmp"));
}

// --table re-measures the header's error on that table, and the line names it and its rows
// (it is often not the table the search fitted, whose errors the lines above give).
TEST_F(EmitWrite, HeaderNamesTheTableItMeasuredOn) {
  const std::string table = std::string(LGP_SOURCE_DIR) + "/examples/quickstart.csv";
  const auto r = sh(emit() + "--no-measure --table " + table + " 2>/dev/null");
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream f(table);
  size_t rows = 0;
  for (std::string l; std::getline(f, l);) rows += !l.empty();
  EXPECT_NE(r.out.find("// Error (this code, float arithmetic, on quickstart.csv, " +
                       std::to_string(rows - 1) + " rows): B rmse "),
            std::string::npos)
      << r.out;
}

}  // namespace
