// `mpirun -np 2 lgp run` on localhost: the front is valid and islands migrated across ranks;
// the synchronous mode is reproducible; budgets and signals stop every rank and the front is
// still written; a killed rank ends the job, and the last checkpoint resumes on 2 ranks, on 3
// and in one process.
#include <gtest/gtest.h>

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>
#include "../shell.hpp"
#include "../skip.hpp"

#include <array>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

using lgp_test::Result;
using lgp_test::sh;

json readJson(const fs::path& p) {
  std::ifstream in(p);
  return json::parse(in);
}

class Mpi : public ::testing::Test {
 protected:
  fs::path dir = fs::temp_directory_path() / ("lgp_mpi_" + std::to_string(getpid()));

  void SetUp() override {
    if (!fs::exists(LGP_MPIEXEC))
      LGP_SKIP_UNLESS_REQUIRED() << "no MPI launcher at " << LGP_MPIEXEC;
    // Open MPI refuses to start as root without these (CI runs as root).
    if (geteuid() == 0) {
      setenv("OMPI_ALLOW_RUN_AS_ROOT", "1", 1);
      setenv("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1", 1);
    }
    fs::create_directories(dir);
    std::ofstream csv(dir / "t.csv");
    csv << "x,y,f\n";
    for (int i = 0; i < 24; ++i)
      for (int j = 0; j < 24; ++j) {
        const double x = (i + 0.5) / 24, y = (j + 0.5) / 24;
        csv << x << "," << y << "," << x * x / (y + 0.5) + 0.25 << "\n";
      }
  }
  void TearDown() override { fs::remove_all(dir); }

  json base(int generations, const std::string& migration = "async") const {
    return {{"data", {{"path", "t.csv"}, {"inputs", {"x", "y"}}, {"outputs", {"f"}}}},
            {"program", {{"max_length", 16}, {"constants", 4}}},
            {"search",
             {{"population", 80},
              {"generations", generations},
              {"seed", 3},
              {"threads", 1},
              {"islands", {{"count", 4}, {"migration_interval", 3}, {"migrants", 2}}}}},
            {"mpi", {{"migration", migration}}},
            {"output",
             {{"front_json", (dir / "front.json").string()},
              {"front_csv", ""},
              {"progress_interval_s", 0.2}}}};
  }
  std::string config(const json& j, const std::string& name = "c.json") const {
    std::ofstream(dir / name) << j.dump();
    return (dir / name).string();
  }
  static std::string mpirun(int np) {
    return std::string(LGP_MPIEXEC) + " --oversubscribe -np " + std::to_string(np) + " " +
           LGP_CLI_PATH;
  }
  // A front written by rank 0: members with finite errors, nothing dominated, programs.
  static void expectValidFront(const json& f) {
    ASSERT_EQ(f["format"], "lgp-front/1");
    ASSERT_GT(f["members"].size(), 0u);
    for (const auto& m : f["members"]) {
      ASSERT_TRUE(m["error"].is_number()) << m.dump();
      EXPECT_GE(m["error"].get<double>(), 0.0);
      EXPECT_TRUE(m.contains("program"));
    }
  }
  // Two runs of `j` on 2 ranks (sync migration): each writes a valid front with migrants across
  // ranks that passes `check`; their members and evaluation counts.
  std::array<std::string, 2> twoSyncRuns(const json& j,
                                         const std::function<void(const json&)>& check = {}) {
    const std::string cfg = config(j);
    std::array<std::string, 2> fronts;
    for (auto& out : fronts) {
      const auto r = sh(mpirun(2) + " run " + cfg + " -q");
      EXPECT_EQ(r.code, 0) << r.out;
      if (r.code != 0) break;
      const auto f = readJson(dir / "front.json");
      expectValidFront(f);
      EXPECT_GT(f["progress"]["remote_migrants"].get<int>(), 0);
      if (check) check(f);
      out = membersOf(f) + f["progress"]["evaluations"].dump();
    }
    return fronts;
  }
  static std::string membersOf(const json& f) {
    json out = json::array();
    for (const auto& m : f["members"]) out.push_back({m["program"], m["error"], m["cost"]});
    return out.dump();
  }
};

TEST_F(Mpi, TwoRanksWriteOneValidFrontAndMigrateAcrossRanks) {
  const auto r =
      sh(mpirun(2) + " run " + config(base(30)) + " --status " + (dir / "status.json").string());
  ASSERT_EQ(r.code, 0) << r.out;
  // Rank 0 alone prints and writes.
  EXPECT_NE(r.out.find("2 MPI ranks (async migration)"), std::string::npos) << r.out;
  const auto f = readJson(dir / "front.json");
  expectValidFront(f);
  const auto& p = f["progress"];
  EXPECT_EQ(p["ranks"], 2);
  EXPECT_EQ(p["islands"], 4);
  EXPECT_EQ(p["generation"], 30);
  EXPECT_EQ(p["stop_reason"], "generations");
  // 10 migration rounds, 4 islands: islands 1 -> 2 and 3 -> 0 cross ranks every round.
  EXPECT_GE(p["migrants"].get<int>(), 40);
  EXPECT_GE(p["remote_migrants"].get<int>(), 20);
  EXPECT_LT(p["remote_migrants"].get<int>(), p["migrants"].get<int>());
  const auto st = readJson(dir / "status.json");
  EXPECT_EQ(st["format"], "lgp-status/1");
  EXPECT_EQ(st["ranks"], 2);
  EXPECT_TRUE(st["finished"].get<bool>());
  EXPECT_EQ(st["evaluations"], p["evaluations"]);
}

TEST_F(Mpi, SyncMigrationIsReproducible) {
  const auto fronts = twoSyncRuns(base(24, "sync"));
  EXPECT_EQ(fronts[0], fronts[1]);
}

// The search-4 representations over MPI: the output layer and weighted operands travel
// between ranks (migrants are programs with their extra genes and coefficients), the sync mode
// stays reproducible, and every member of the front is a one-output program that reproduces
// its score in double precision.
TEST_F(Mpi, OutputLayerAndWeightsMigrateReproducibly) {
  json j = base(24, "sync");
  j["program"] = {{"max_length", 16}, {"constants", 10}, {"genes", 2}};
  j["search"]["linear_scaling"] = true;
  j["search"]["variation"] = {{"weight_rate", 0.3}, {"weight_min_length", 0}};
  const auto fronts = twoSyncRuns(j, [](const json& f) {
    for (const auto& m : f["members"]) {
      ASSERT_EQ(m["outputs"].size(), 1u) << m.dump();
      const auto& o = m["outputs"][0];
      EXPECT_NEAR(o["float32"]["rmse"].get<double>(), o["double"]["rmse"].get<double>(),
                  1e-4 * (1 + o["double"]["rmse"].get<double>()))
          << o.dump();
    }
  });
  EXPECT_EQ(fronts[0], fronts[1]);
}

// Island profiles over MPI: an island's profile (and its share of the population) follows its
// global index, so islands 0 and 2 (one on each rank) hold only small programs, and as many as
// their share gives, whatever arrives from the other rank; the sync
// mode stays reproducible with either topology (by_profile: every batch crosses ranks).
TEST_F(Mpi, IslandProfilesHoldOnEveryRank) {
  for (const std::string topology : {"ring", "by_profile"}) {
    SCOPED_TRACE(topology);
    json j = base(24, "sync");
    j["search"]["islands"]["topology"] = topology;
    j["search"]["variation"] = {{"weight_rate", 0.3}, {"weight_min_length", 0}};
    j["search"]["islands"]["profiles"] = {
        {{"max_length", 5}, {"constants", 1}, {"weight_rate", 0}, {"share", 0.5}}, json::object()};
    const std::vector<size_t> sizes = {13, 27, 13, 27};  // 80 programs at shares 0.5, 1, 0.5, 1
    const fs::path ck = dir / "ck.json";
    const std::string cfg = config(j);
    std::array<std::string, 2> fronts;
    for (auto& out : fronts) {
      fs::remove(ck);
      const auto r = sh(mpirun(2) + " run " + cfg + " -q --checkpoint " + ck.string());
      ASSERT_EQ(r.code, 0) << r.out;
      const auto f = readJson(dir / "front.json");
      expectValidFront(f);
      EXPECT_GT(f["progress"]["remote_migrants"].get<int>(), 0);
      out = membersOf(f);
      const auto state = readJson(ck);
      ASSERT_EQ(state["parts"].size(), 2u);
      int global = 0, small = 0, longer = 0;
      for (const auto& part : state["parts"])
        for (const auto& isl : part["islands"]) {
          EXPECT_EQ(isl["population"].size(), sizes[global]) << "island " << global;
          for (const auto& m : isl["population"]) {
            const auto& code = m["program"]["code"];
            if (global % 2 == 1) {
              longer += code.size() > 5;
              continue;
            }
            ++small;
            EXPECT_LE(code.size(), 5u) << "island " << global << ": " << m.dump();
            for (const auto& in : code)
              for (size_t a = 1; a < in.size(); ++a) {
                const std::string operand = in[a];
                EXPECT_TRUE(operand[0] != 'c' || operand == "c0") << "island " << global;
              }
          }
          ++global;
        }
      EXPECT_EQ(global, 4);
      EXPECT_GT(small, 0);
      EXPECT_GT(longer, 0);
    }
    EXPECT_EQ(fronts[0], fronts[1]);
  }
}

TEST_F(Mpi, EvaluationAndWallTimeBudgetsStopEveryRank) {
  for (const std::string mode : {"async", "sync"}) {
    auto j = base(0, mode);
    j["search"]["max_evaluations"] = 60000;
    auto r = sh(mpirun(2) + " run " + config(j) + " -q");
    ASSERT_EQ(r.code, 0) << r.out;
    auto f = readJson(dir / "front.json");
    expectValidFront(f);
    EXPECT_EQ(f["progress"]["stop_reason"], "evaluations") << mode;
    EXPECT_GE(f["progress"]["evaluations"].get<double>(), 60000);
    j = base(0, mode);
    j["search"]["wall_time_s"] = 1.0;
    r = sh(mpirun(2) + " run " + config(j) + " -q");
    ASSERT_EQ(r.code, 0) << r.out;
    f = readJson(dir / "front.json");
    expectValidFront(f);
    EXPECT_EQ(f["progress"]["stop_reason"], "wall_time") << mode;
  }
}

// Starts mpirun in the background; returns its pid.
pid_t spawn(const std::string& cmd, const fs::path& log) {
  const pid_t pid = fork();
  if (pid == 0) {
    const std::string full = "exec " + cmd + " > " + log.string() + " 2>&1";
    execl("/bin/sh", "sh", "-c", full.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  return pid;
}

int waitFor(pid_t pid) {
  int st = 0;
  waitpid(pid, &st, 0);
  return WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
}

bool waitUntil(const std::function<bool()>& ok, double seconds) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (std::chrono::steady_clock::now() < end) {
    if (ok()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return ok();
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// The pid of the lgp process that is MPI rank `rank` of a job running config `cfg`.
pid_t rankPid(const std::string& cfg, int rank) {
  const std::string want = "OMPI_COMM_WORLD_RANK=" + std::to_string(rank);
  for (const auto& e : fs::directory_iterator("/proc")) {
    const std::string name = e.path().filename();
    if (name.find_first_not_of("0123456789") != std::string::npos) continue;
    const std::string cmdline = slurp(e.path() / "cmdline");
    if (cmdline.find(cfg) == std::string::npos || cmdline.find("mpirun") != std::string::npos)
      continue;
    const std::string env = slurp(e.path() / "environ");
    for (size_t at = 0; at < env.size();) {
      const size_t end = env.find('\0', at);
      if (env.compare(at, end - at, want) == 0) return std::stoi(name);
      if (end == std::string::npos) break;
      at = end + 1;
    }
  }
  return -1;
}

TEST_F(Mpi, SignalsStopEveryRankAndTheFrontIsWritten) {
  // SIGUSR1 is the launcher-friendly stop (mpirun forwards it); SIGINT is Ctrl-C, after which
  // mpirun gives the ranks about a second.
  for (int sig : {SIGUSR1, SIGINT}) {
    auto j = base(0);
    j["search"]["wall_time_s"] = 60;
    const std::string cfg = config(j);
    fs::remove(dir / "front.json");
    const pid_t pid = spawn(mpirun(2) + " run " + cfg + " -q", dir / "log.txt");
    ASSERT_TRUE(waitUntil([&] { return rankPid(cfg, 1) > 0; }, 20));
    std::this_thread::sleep_for(std::chrono::milliseconds(1500));
    kill(pid, sig);
    waitFor(pid);
    ASSERT_TRUE(fs::exists(dir / "front.json")) << slurp(dir / "log.txt");
    const auto f = readJson(dir / "front.json");
    expectValidFront(f);
    EXPECT_EQ(f["progress"]["stop_reason"], "stopped");
    EXPECT_EQ(f["progress"]["ranks"], 2);
  }
}

TEST_F(Mpi, AKilledRankEndsTheJobAndTheCheckpointResumes) {
  auto j = base(0);
  j["search"]["generations"] = 1000000;
  const std::string cfg = config(j);
  const fs::path ck = dir / "ck.json";
  const pid_t pid = spawn(
      mpirun(2) + " run " + cfg + " -q --checkpoint " + ck.string() + " --checkpoint-interval 0.2",
      dir / "log.txt");
  ASSERT_TRUE(waitUntil([&] { return fs::exists(ck); }, 30)) << slurp(dir / "log.txt");
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  const pid_t victim = rankPid(cfg, 1);
  ASSERT_GT(victim, 0);
  kill(victim, SIGKILL);
  const int code = waitFor(pid);
  EXPECT_NE(code, 0);
  const std::string log = slurp(dir / "log.txt");
  EXPECT_NE(log.find("rank 1"), std::string::npos) << log;
  EXPECT_FALSE(fs::exists(dir / "front.json"));

  // The checkpoint is whole (rename is atomic) and made of both ranks' parts.
  const auto state = readJson(ck);
  EXPECT_EQ(state["format"], "lgp-checkpoint/2");
  EXPECT_EQ(state["ranks"], 2);
  EXPECT_EQ(state["parts"].size(), 2u);
  const int generation = state["generation"];
  ASSERT_GT(generation, 0);
  const std::string more = " --generations " + std::to_string(generation + 15);
  // The same rank count resumes each rank exactly; another count deals the islands anew; one
  // process takes all of them.
  for (const std::string& launch : {mpirun(2), mpirun(3), std::string(LGP_CLI_PATH)}) {
    fs::copy_file(ck, dir / "resume.json", fs::copy_options::overwrite_existing);
    const auto r = sh(launch + " run " + cfg + " -q --resume --checkpoint " +
                      (dir / "resume.json").string() + more);
    ASSERT_EQ(r.code, 0) << launch << "\n" << r.out;
    const auto f = readJson(dir / "front.json");
    expectValidFront(f);
    EXPECT_EQ(f["progress"]["generation"], generation + 15) << launch;
    EXPECT_GT(f["progress"]["evaluations"].get<double>(), state["evaluations"].get<double>());
  }
  // The async checkpoint's ranks may stand a generation apart; a sync resume lines them up
  // (else their migration rounds would not match and the ranks would wait for each other).
  auto sync = j;
  sync["mpi"]["migration"] = "sync";
  fs::copy_file(ck, dir / "resume.json", fs::copy_options::overwrite_existing);
  const auto r = sh(mpirun(2) + " run " + config(sync, "sync.json") + " -q --resume --checkpoint " +
                    (dir / "resume.json").string() + more);
  ASSERT_EQ(r.code, 0) << r.out;
  expectValidFront(readJson(dir / "front.json"));
}

TEST_F(Mpi, BadInputIsReportedOnceAndEveryRankExits) {
  auto j = base(5);
  j["search"]["population"] = "many";
  auto r = sh(mpirun(2) + " run " + config(j));
  EXPECT_NE(r.code, 0);
  const std::string msg = "/search/population: must be an integer";
  const size_t at = r.out.find(msg);
  ASSERT_NE(at, std::string::npos) << r.out;
  EXPECT_EQ(r.out.find(msg, at + 1), std::string::npos) << "printed twice:\n" << r.out;
  // Three ranks need three islands of at least 4 individuals.
  j = base(5);
  j["search"]["population"] = 8;
  r = sh(mpirun(3) + " run " + config(j));
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.out.find("3 ranks need at least 12 individuals"), std::string::npos) << r.out;
  // A missing data file: only rank 0 reads it.
  j = base(5);
  j["data"]["path"] = "missing.csv";
  r = sh(mpirun(2) + " run " + config(j));
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.out.find("missing.csv"), std::string::npos) << r.out;
}

}  // namespace
