// The `lgp` CLI end to end: a run writes its front, bad input exits non-zero with a message
// naming the field (or file, row and column), and Ctrl-C still writes the front.
#include <gtest/gtest.h>

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>
#include "../shell.hpp"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <thread>

namespace {

namespace fs = std::filesystem;

using lgp_test::Result;
using lgp_test::sh;

class Cli : public ::testing::Test {
 protected:
  fs::path dir = fs::temp_directory_path() / ("lgp_cli_" + std::to_string(getpid()));
  void SetUp() override {
    fs::create_directories(dir);
    std::ofstream csv(dir / "t.csv");
    csv << "x,y,f\n";
    for (int i = 0; i < 16; ++i)
      for (int j = 0; j < 16; ++j) {
        const double x = (i + 0.5) / 16, y = (j + 0.5) / 16;
        csv << x << "," << y << "," << x * y + 0.5 << "\n";
      }
  }
  void TearDown() override { fs::remove_all(dir); }
  std::string lgp() const { return std::string(LGP_CLI_PATH); }
  fs::path config(const nlohmann::json& j, const std::string& name = "c.json") {
    std::ofstream(dir / name) << j.dump();
    return dir / name;
  }
  nlohmann::json base(int generations) {
    return {{"data", {{"path", "t.csv"}, {"inputs", {"x", "y"}}, {"outputs", {"f"}}}},
            {"search", {{"population", 60}, {"generations", generations}, {"seed", 2}}},
            {"output",
             {{"front_json", (dir / "front.json").string()},
              {"front_csv", (dir / "front.csv").string()}}}};
  }
};

TEST_F(Cli, RunWritesFrontAndFrontPrintsIt) {
  const auto r = sh(lgp() + " run " + config(base(5)).string() + " -q");
  ASSERT_EQ(r.code, 0) << r.out;
  ASSERT_TRUE(fs::exists(dir / "front.json"));
  ASSERT_TRUE(fs::exists(dir / "front.csv"));
  std::ifstream in(dir / "front.json");
  const auto j = nlohmann::json::parse(in);
  EXPECT_EQ(j["format"], "lgp-front/1");
  ASSERT_GT(j["members"].size(), 0u);
  const auto& m = j["members"][0];
  for (const char* k : {"error", "cost", "discontinuity", "cost_by_target", "outputs", "program"})
    EXPECT_TRUE(m.contains(k)) << k;
  EXPECT_TRUE(m["outputs"][0].contains("expression"));
  const auto f = sh(lgp() + " front " + (dir / "front.json").string());
  EXPECT_EQ(f.code, 0);
  EXPECT_NE(f.out.find("expression"), std::string::npos);
  EXPECT_NE(f.out.find("members"), std::string::npos);
}

TEST_F(Cli, ConfigOutputsAreRelativeToTheConfigAndCliPathsToTheWorkingDirectory) {
  // The config lives in sub/ and names its table and outputs relative to itself; the run
  // starts in cwd/, so only the command line's paths land there.
  fs::create_directories(dir / "sub");
  fs::create_directories(dir / "cwd");
  fs::copy_file(dir / "t.csv", dir / "sub" / "t.csv");
  auto j = base(3);
  j["output"] = {{"front_json", "named-front.json"}, {"front_csv", "named-front.csv"}};
  const std::string cfg = config(j, "sub/c.json").string();
  auto r = sh("cd " + (dir / "cwd").string() + " && " + lgp() + " run ../sub/c.json -q");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_TRUE(fs::exists(dir / "sub" / "named-front.json"));
  EXPECT_TRUE(fs::exists(dir / "sub" / "named-front.csv"));
  EXPECT_FALSE(fs::exists(dir / "cwd" / "named-front.json"));
  r = sh("cd " + (dir / "cwd").string() + " && " + lgp() + " front ../sub/named-front.json");
  EXPECT_EQ(r.code, 0) << r.out;
  r = sh("cd " + (dir / "cwd").string() + " && " + lgp() + " run " + cfg +
         " -q -o cli-front.json --csv cli-front.csv --checkpoint ck.json --status st.json");
  ASSERT_EQ(r.code, 0) << r.out;
  for (const char* f : {"cli-front.json", "cli-front.csv", "ck.json", "st.json"}) {
    EXPECT_TRUE(fs::exists(dir / "cwd" / f)) << f;
    EXPECT_FALSE(fs::exists(dir / "sub" / f)) << f;
  }
}

TEST_F(Cli, BadConfigNamesTheFieldAndExitsNonZero) {
  auto j = base(5);
  j["search"]["population"] = "lots";
  auto r = sh(lgp() + " run " + config(j).string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find("/search/population: must be an integer"), std::string::npos) << r.out;
  j = base(5);
  j["search"]["popsize"] = 5;
  r = sh(lgp() + " run " + config(j).string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find("/search/popsize: unknown key"), std::string::npos) << r.out;
  std::ofstream(dir / "broken.json") << "{\"data\": ";
  r = sh(lgp() + " run " + (dir / "broken.json").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find("invalid JSON"), std::string::npos) << r.out;
  r = sh(lgp() + " run " + (dir / "missing.json").string());
  EXPECT_EQ(r.code, 2);
  r = sh(lgp() + " frobnicate");
  EXPECT_EQ(r.code, 2);
  r = sh(lgp() + " front " + (dir / "t.csv").string());
  EXPECT_EQ(r.code, 2);
}

TEST_F(Cli, BadCsvNamesFileRowAndColumn) {
  std::ofstream(dir / "bad.csv") << "x,y,f\n1,2,3\n4,oops,6\n";
  auto j = base(5);
  j["data"]["path"] = "bad.csv";
  const auto r = sh(lgp() + " run " + config(j).string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find("bad.csv: line 3, column 2: not a decimal number"), std::string::npos)
      << r.out;
}

TEST_F(Cli, InterruptStillWritesTheFront) {
  auto j = base(0);
  j["search"]["generations"] = 0;
  j["search"]["wall_time_s"] = 60;
  j["output"]["progress_interval_s"] = 0;  // a status row every generation
  const std::string cfg = config(j).string();
  const std::string status = (dir / "status.json").string();
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    const std::string bin = lgp();
    execl(bin.c_str(), bin.c_str(), "run", cfg.c_str(), "-q", "--status", status.c_str(),
          static_cast<char*>(nullptr));
    _exit(127);
  }
  // Interrupt once the search is under way (its status file shows a generation done): the
  // handler is installed by then and the front has members. A bounded poll, not a fixed sleep.
  int generation = -1;
  for (int i = 0; i < 3000 && generation < 1; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    std::ifstream in(status);
    const auto st = nlohmann::json::parse(in, nullptr, false);
    if (st.is_object() && st["generation"].is_number_integer()) generation = st["generation"];
  }
  if (generation < 1) {
    kill(pid, SIGKILL);
    waitpid(pid, nullptr, 0);
    FAIL() << "no generation within 30 s";
  }
  kill(pid, SIGINT);
  int st = 0;
  waitpid(pid, &st, 0);
  ASSERT_TRUE(WIFEXITED(st));
  EXPECT_EQ(WEXITSTATUS(st), 130);
  ASSERT_TRUE(fs::exists(dir / "front.json"));
  std::ifstream in(dir / "front.json");
  const auto front = nlohmann::json::parse(in);
  EXPECT_EQ(front["progress"]["stop_reason"], "stopped");
  EXPECT_GT(front["members"].size(), 0u);
}

TEST_F(Cli, CheckpointResumeAndStatusFile) {
  // A run stopped at generation 6 with a checkpoint, resumed to 12, ends with the front of an
  // uninterrupted 12-generation run: the checkpoint holds the whole state.
  const std::string cfg = config(base(6)).string();
  const std::string ck = (dir / "ck.json").string(), st = (dir / "status.json").string();
  auto r = sh(lgp() + " run " + cfg + " -q --checkpoint " + ck + " --status " + st);
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream sin(st);
  const auto status = nlohmann::json::parse(sin);
  EXPECT_EQ(status["format"], "lgp-status/1");
  EXPECT_EQ(status["generation"], 6);
  EXPECT_TRUE(status["finished"].get<bool>());
  r = sh(lgp() + " run " + cfg + " -q --checkpoint " + ck + " --resume --generations 12 -o " +
         (dir / "resumed.json").string());
  ASSERT_EQ(r.code, 0) << r.out;
  r = sh(lgp() + " run " + cfg + " -q --generations 12 -o " + (dir / "straight.json").string());
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream a(dir / "resumed.json"), b(dir / "straight.json");
  const auto ja = nlohmann::json::parse(a), jb = nlohmann::json::parse(b);
  EXPECT_EQ(ja["progress"]["generation"], 12);
  EXPECT_EQ(ja["members"], jb["members"]);
  // Resuming needs a checkpoint that exists and fits the config.
  r = sh(lgp() + " run " + cfg + " -q --checkpoint " + (dir / "none.json").string() + " --resume");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find("none.json: no checkpoint file there"), std::string::npos) << r.out;
  r = sh(lgp() + " run " + cfg + " -q --resume");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find("--resume: no checkpoint file named"), std::string::npos) << r.out;
  auto other = base(6);
  other["search"]["population"] = 64;
  r = sh(lgp() + " run " + config(other, "other.json").string() + " -q --checkpoint " + ck +
         " --resume");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find("made with a different config"), std::string::npos) << r.out;
}

TEST_F(Cli, FrontEveryWritesTheFrontSoFar) {
  // A 2.5 s run with a snapshot every second: at0001s and at0002s, fronts of their moment.
  auto j = base(0);
  j["search"]["wall_time_s"] = 2.5;
  const std::string cfg = config(j).string();
  auto r = sh(lgp() + " run " + cfg + " -q --front-every 1");
  ASSERT_EQ(r.code, 0) << r.out;
  double last = 0;
  for (const char* name : {"front.at0001s.json", "front.at0002s.json"}) {
    ASSERT_TRUE(fs::exists(dir / name)) << name;
    std::ifstream in(dir / name);
    const auto f = nlohmann::json::parse(in);
    EXPECT_EQ(f["format"], "lgp-front/1");
    EXPECT_GT(f["members"].size(), 0u);
    const double t = f["progress"]["elapsed_s"].get<double>();
    EXPECT_GT(t, last) << name;
    last = t;
  }
  EXPECT_FALSE(fs::exists(dir / "front.at0003s.json"));
  std::ifstream fin(dir / "front.json");
  EXPECT_GE(nlohmann::json::parse(fin)["progress"]["elapsed_s"].get<double>(), last);
  r = sh(lgp() + " run " + cfg + " -q --front-every 0");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find("--front-every: must be a number of seconds > 0"), std::string::npos)
      << r.out;
}

}  // namespace

// A full disk (/dev/full: every write fails with ENOSPC) is an error with a message and a
// non-zero exit, never a truncated output with exit 0. Standard output fails only when its
// buffer is flushed at the end, so that is where lgp must look.
TEST_F(Cli, StandardOutputOnAFullDiskExitsNonZero) {
  if (!fs::is_character_file("/dev/full")) GTEST_SKIP() << "this machine has no /dev/full";
  auto r = sh(lgp() + " run " + config(base(3)).string() + " -q");
  ASSERT_EQ(r.code, 0) << r.out;
  const std::string front = (dir / "front.json").string(), table = (dir / "t.csv").string();
  for (const std::string& args : std::vector<std::string>{
           " front " + front, " front " + front + " --json", " --help", " front --help",
           " score " + table + " -e 'f = x * y + 0.5' --inputs x,y --outputs f --no-measure",
           " score " + table +
               " -e 'f = x * y + 0.5' --inputs x,y --outputs f --no-measure --json"}) {
    // stdout to /dev/full, stderr (the message) to the pipe.
    r = sh("{ " + lgp() + args + " >/dev/full; }");
    EXPECT_EQ(r.code, 1) << "lgp" << args << "\n" << r.out;
    EXPECT_NE(r.out.find("error: cannot write the output (standard output)"), std::string::npos)
        << "lgp" << args << "\n"
        << r.out;
  }
  // The same commands with a working stdout still exit 0.
  r = sh(lgp() + " front " + front + " >/dev/null");
  EXPECT_EQ(r.code, 0) << r.out;
}

// Files named on the command line or in the config: a path that is a device (here a symlink
// to /dev/full) is written in place and its failure reported; a temp file renamed over it
// would have replaced the link (or, as root, the device node) and exited 0.
TEST_F(Cli, OutputFilesOnAFullDiskExitNonZero) {
  if (!fs::is_character_file("/dev/full")) GTEST_SKIP() << "this machine has no /dev/full";
  const fs::path full = dir / "full";
  fs::create_symlink("/dev/full", full);
  auto r = sh(lgp() + " run " + config(base(3)).string() + " -q");
  ASSERT_EQ(r.code, 0) << r.out;
  const std::string front = (dir / "front.json").string(), cfg = (dir / "c.json").string();
  for (const std::string& args : std::vector<std::string>{
           " run " + cfg + " -q -o " + full.string(), " run " + cfg + " -q --csv " + full.string(),
           " run " + cfg + " -q --checkpoint " + full.string(),
           " front " + front + " --snap -o " + full.string()}) {
    r = sh(lgp() + args);
    EXPECT_NE(r.code, 0) << "lgp" << args << "\n" << r.out;
    EXPECT_NE(r.out.find("No space left on device"), std::string::npos) << "lgp" << args << "\n"
                                                                        << r.out;
    EXPECT_TRUE(fs::is_symlink(full)) << "lgp" << args << " replaced the link with a file";
  }
  EXPECT_TRUE(fs::is_character_file("/dev/full"));
}
