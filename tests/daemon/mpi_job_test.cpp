// lgpd runs a job over MPI when its run config sets mpi.np: validation at submit, the exact
// argument vector (no shell; only np comes from the request), a failing launcher, shutdown
// and relaunch semantics, and end-to-end runs with the real `mpirun --oversubscribe -np 2`
// (finish, cancel, SIGTERM/kill -9 of lgpd and resume). The mpirun cases skip themselves
// when mpirun is not installed; the others use small shell scripts as the launcher.
#include <sys/stat.h>

#include <algorithm>

#include "../skip.hpp"
#include "daemon_harness.hpp"

namespace lgpd_test {
namespace {

const std::vector<std::string> kFlags = {
    "--checkpoint-interval", "0.3", "--progress-interval", "0.05", "--front-interval", "0.2"};

std::string findInPath(const std::string& name) {
  const char* path = std::getenv("PATH");
  std::stringstream ss(path ? path : "/usr/bin:/bin");
  std::string dir;
  while (std::getline(ss, dir, ':'))
    if (!dir.empty() && ::access((fs::path(dir) / name).c_str(), X_OK) == 0)
      return (fs::path(dir) / name).string();
  return "";
}

fs::path writeScript(const fs::path& p, const std::string& text) {
  std::ofstream(p) << text;
  ::chmod(p.c_str(), 0755);
  return p;
}

fs::path writeJson(const fs::path& p, const json& j) {
  std::ofstream(p) << j.dump(2);
  return p;
}

std::vector<std::string> readLines(const fs::path& p) {
  std::ifstream f(p);
  std::vector<std::string> out;
  for (std::string line; std::getline(f, line);) out.push_back(line);
  return out;
}

std::string readFile(const fs::path& p) {
  std::ifstream f(p);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

// Live (non-zombie) processes whose command line contains `needle`: what a launch left.
std::vector<std::string> processesMentioning(const std::string& needle) {
  std::vector<std::string> out;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator("/proc", ec)) {
    const std::string pid = e.path().filename().string();
    if (pid.find_first_not_of("0123456789") != std::string::npos) continue;
    std::string cmd = readFile(e.path() / "cmdline");  // empty for zombies
    std::replace(cmd.begin(), cmd.end(), '\0', ' ');
    if (cmd.find(needle) != std::string::npos) out.push_back(pid + ": " + cmd);
  }
  return out;
}

// Polls until no process mentions `needle` (or ~timeout_s); returns what is left.
std::vector<std::string> waitNoProcesses(const std::string& needle, double timeout_s = 10) {
  std::vector<std::string> left;
  for (int i = 0; i < timeout_s * 20; ++i) {
    left = processesMentioning(needle);
    if (left.empty()) break;
    sleepMs(50);
  }
  return left;
}

json mpiConfig(const fs::path& table, int np, int generations, int population = 40) {
  json cfg = runConfig(table, generations, population);
  cfg["mpi"] = {{"np", np}};
  return cfg;
}

std::string joined(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += x + "\n";
  return s;
}

// --- validation --------------------------------------------------------------------------

TEST(MpiSubmit, InvalidRequestsGet400NamingTheField) {
  TempDir tmp("mpi-validate");
  fs::path table = writeGridTable(tmp.path());
  // /bin/true as the launcher: these requests must be refused before anything runs.
  fs::path cfg =
      writeJson(tmp.path() / "lgpd.json",
                {{"mpi", {{"launcher", "/bin/true"}, {"max_np", 4}, {"lgp", LGP_CLI_BIN}}}});
  Daemon d(tmp.path() / "state");
  ASSERT_TRUE(d.start({"--config", cfg.string()}));
  auto expect400 = [&](json body, const std::string& field, const std::string& what) {
    Reply r;
    EXPECT_EQ(d.submit(body, &r), "") << what;
    EXPECT_EQ(r.status, 400) << what << ": " << r.body;
    EXPECT_EQ(r.j().value("field", ""), field) << what << ": " << r.body;
    return r.j().value("error", "");
  };
  std::string err = expect400(mpiConfig(table, 5, 10), "/mpi/np", "np above max_np");
  EXPECT_NE(err.find("[1, 4]"), std::string::npos) << err;
  expect400(mpiConfig(table, -1, 10), "/mpi/np", "negative np");
  json c = mpiConfig(table, 1, 10);
  c["mpi"]["np"] = "two";
  expect400(c, "/mpi/np", "np of the wrong type");
  c = mpiConfig(table, 2, 10);
  c["mpi"]["launcher"] = "/bin/sh";
  err = expect400(c, "/mpi", "a launcher in the request");
  EXPECT_NE(err.find("launcher"), std::string::npos) << err;
  c = mpiConfig(table, 2, 10);
  c["mpi"]["hostfile"] = "/etc/passwd";
  expect400(c, "/mpi", "a hostfile in the request");
  c = mpiConfig(table, 2, 10);
  c["mpi"]["args"] = {"--oversubscribe"};
  expect400(c, "/mpi/args", "launcher args in the request");
  c = mpiConfig(table, 2, 10);
  c["data"]["outputs"] = {"f", "g"};
  c["search"]["multi_output"] = {{"mode", "two_step"}, {"first", "f"}};
  err = expect400(c, "/search/multi_output/mode", "two_step over MPI");
  EXPECT_NE(err.find("MPI"), std::string::npos) << err;
  EXPECT_EQ(d.get("/api/v1/runs").j()["runs"].size(), 0u) << "nothing may be queued";
  EXPECT_EQ(d.stop(), 0) << d.log();
}

TEST(MpiSubmit, NoUsableLauncherRefusesMpiRunsOnly) {
  TempDir tmp("mpi-nolauncher");
  fs::path table = writeGridTable(tmp.path());
  fs::path cfg =
      writeJson(tmp.path() / "lgpd.json", {{"mpi", {{"launcher", "no-such-mpi-launcher-x"}}}});
  Daemon d(tmp.path() / "state");
  ASSERT_TRUE(d.start({"--config", cfg.string()}));
  Reply r;
  EXPECT_EQ(d.submit(mpiConfig(table, 1, 10), &r), "");
  EXPECT_EQ(r.status, 400) << r.body;
  EXPECT_EQ(r.j().value("field", ""), "/mpi/np") << r.body;
  EXPECT_NE(r.j().value("error", "").find("no-such-mpi-launcher-x"), std::string::npos) << r.body;
  // In-process runs (np 0, the default) are unaffected.
  std::string id = d.submit(mpiConfig(table, 0, 5));
  ASSERT_FALSE(id.empty());
  EXPECT_EQ(d.waitDone(id).value("status", ""), "finished") << d.log();
  EXPECT_EQ(d.stop(), 0) << d.log();
}

TEST(MpiDaemonConfig, BadMpiSectionIsRefusedAtStartNamingTheKey) {
  TempDir tmp("mpi-dcfg");
  const std::vector<std::pair<json, std::string>> cases = {
      {{{"mpi", {{"max_np", 0}}}}, "/mpi/max_np"},
      {{{"mpi", {{"args", {"--oversubscribe", 3}}}}}, "/mpi/args/1"},
      {{{"mpi", {{"args", "--oversubscribe"}}}}, "/mpi/args"},
      {{{"mpi", {{"launcher", ""}}}}, "/mpi/launcher"},
      {{{"mpi", {{"np", 2}}}}, "/mpi/np: unknown key"},
      {{{"mpi", {{"stop_grace_s", 0}}}}, "/mpi/stop_grace_s"},
      {{{"mpi", 3}}, "/mpi: must be an object"}};
  int n = 0;
  for (const auto& [j, want] : cases) {
    fs::path cfg = writeJson(tmp.path() / ("c" + std::to_string(n) + ".json"), j);
    fs::path log = tmp.path() / ("c" + std::to_string(n++) + ".log");
    std::string out;
    int code = runProgram({LGPD_BIN, "--data-dir", (tmp.path() / "s").string(), "--listen",
                           "127.0.0.1:0", "--config", cfg.string()},
                          &out, log, 30);
    EXPECT_EQ(code, 2) << j.dump();
    EXPECT_NE(readFile(log).find(want), std::string::npos) << j.dump() << ": " << readFile(log);
  }
}

// --- the launch itself, with scripts as the launcher ---------------------------------------

// Records its argv, environment, signal mask, descriptors and process group, then fails.
std::string recordingLauncher(const fs::path& record, int exit_code) {
  return "#!/bin/sh\n"
         "{\n"
         "  echo '--- launch'\n"
         "  for a in \"$@\"; do printf 'arg:%s\\n' \"$a\"; done\n"
         "  echo \"env:OMPI_ALLOW_RUN_AS_ROOT=${OMPI_ALLOW_RUN_AS_ROOT:-}\"\n"
         "  echo \"env:OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=${OMPI_ALLOW_RUN_AS_ROOT_CONFIRM:-}\"\n"
         "  grep '^SigBlk' /proc/self/status\n"
         "  for f in /proc/$$/fd/*; do echo \"fd:$(readlink \"$f\")\"; done\n"
         "  echo \"pgrp:$(cut -d' ' -f5 /proc/$$/stat) pid:$$\"\n"
         "} >> '" +
         record.string() +
         "'\n"
         "echo 'launcher exploded on purpose' >&2\n"
         "exit " +
         std::to_string(exit_code) + "\n";
}

TEST(MpiLaunch, ExactArgvNoShellAndAFailingLauncherFailsTheRunOnce) {
  TempDir tmp("mpi-argv");
  fs::path table = writeGridTable(tmp.path());
  fs::path record = tmp.path() / "record.txt";
  fs::path launcher = writeScript(tmp.path() / "launcher.sh", recordingLauncher(record, 3));
  fs::path cfg = writeJson(tmp.path() / "lgpd.json",
                           {{"mpi",
                             {{"launcher", launcher.string()},
                              {"args", {"--oversubscribe", "--mca", "btl self,vader"}},
                              {"lgp", LGP_CLI_BIN},
                              {"max_np", 8}}}});
  const fs::path state = tmp.path() / "state";
  std::string id;
  {
    Daemon d(state);
    ASSERT_TRUE(d.start({"--config", cfg.string(), "--checkpoint-interval", "0.2"}));
    json run = mpiConfig(table, 3, 10);
    run["name"] = "$(touch /tmp/lgpd-pwned); `id` 'quoted'";
    run["output"] = {{"front_json", (tmp.path() / "not-here.json").string()}};
    Reply r;
    id = d.submit(run, &r);
    ASSERT_FALSE(id.empty()) << r.body;
    json done = d.waitDone(id, 30);
    ASSERT_EQ(done.value("status", ""), "failed") << done.dump() << d.log();
    const std::string err = done.value("error", "");
    EXPECT_NE(err.find("exited with status 3"), std::string::npos) << err;
    EXPECT_NE(err.find("launcher exploded on purpose"), std::string::npos) << err;
    EXPECT_TRUE(d.alive()) << d.log();
    // The daemon keeps serving: an in-process run still finishes.
    std::string ok = d.submit(runConfig(table, 3));
    EXPECT_EQ(d.waitDone(ok, 30).value("status", ""), "finished");
    EXPECT_EQ(d.stop(), 0) << d.log();
  }
  const fs::path work = state / "mpi" / id;
  std::vector<std::string> args;
  std::string rest;
  for (const auto& line : readLines(record)) {
    if (line.rfind("arg:", 0) == 0)
      args.push_back(line.substr(4));
    else
      rest += line + "\n";
  }
  const std::vector<std::string> want = {"-np",
                                         "3",
                                         "--oversubscribe",
                                         "--mca",
                                         "btl self,vader",
                                         fs::path(LGP_CLI_BIN).lexically_normal().string(),
                                         "run",
                                         (work / "run.json").string(),
                                         "-q",
                                         "-o",
                                         (work / "front.json").string(),
                                         "--csv",
                                         "",
                                         "--checkpoint",
                                         (work / "checkpoint.json").string(),
                                         "--checkpoint-interval",
                                         "0.2",
                                         "--status",
                                         (work / "status.json").string()};
  EXPECT_EQ(args, want) << joined(args);
  EXPECT_FALSE(fs::exists("/tmp/lgpd-pwned"));
  // Root needs OpenMPI's opt-in; the child starts with no signal blocked (lgpd blocks
  // SIGINT/SIGTERM in its own threads), in its own process group, without lgpd's database
  // or sockets.
  if (::geteuid() == 0) {
    EXPECT_NE(rest.find("env:OMPI_ALLOW_RUN_AS_ROOT=1\n"), std::string::npos) << rest;
    EXPECT_NE(rest.find("env:OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1\n"), std::string::npos) << rest;
  }
  EXPECT_NE(rest.find("SigBlk:\t0000000000000000"), std::string::npos) << rest;
  EXPECT_EQ(rest.find("sqlite3"), std::string::npos) << rest;
  EXPECT_EQ(rest.find("socket:"), std::string::npos) << rest;
  for (const auto& line : readLines(record))
    if (line.rfind("pgrp:", 0) == 0) {
      auto sp = line.find(' ');
      EXPECT_EQ(line.substr(5, sp - 5), line.substr(line.find("pid:") + 4)) << line;
    }
  // The config the child reads: data path absolute, outputs in the work dir, not the request's.
  json written = json::parse(readFile(work / "run.json"));
  EXPECT_EQ(written["data"]["path"], table.string());
  EXPECT_EQ(written["output"]["front_json"], (work / "front.json").string());
  EXPECT_EQ(written["output"]["checkpoint"], (work / "checkpoint.json").string());
  EXPECT_EQ(written["mpi"]["np"], 3);
  EXPECT_FALSE(written.contains("name"));

  // A restart does not relaunch a failed run.
  {
    Daemon d(state);
    ASSERT_TRUE(d.start({"--config", cfg.string()}));
    sleepMs(1500);
    EXPECT_EQ(d.get("/api/v1/runs/" + id).j().value("status", ""), "failed");
    EXPECT_EQ(d.stop(), 0) << d.log();
  }
  auto lines = readLines(record);
  EXPECT_EQ(std::count(lines.begin(), lines.end(), "--- launch"), 1) << "launched once";
  // A failed run keeps its work dir (the launcher's log) until the run is deleted.
  EXPECT_TRUE(fs::exists(work / "launcher.log"));
  {
    Daemon d(state);
    ASSERT_TRUE(d.start({"--config", cfg.string()}));
    EXPECT_EQ(d.del("/api/v1/runs/" + id).status, 200);
    EXPECT_FALSE(fs::exists(work));
    EXPECT_EQ(d.stop(), 0) << d.log();
  }
}

// A launcher that ignores SIGUSR1 and SIGTERM is killed with its process group after the
// grace periods; deleting a running MPI run stops its launcher and removes its work dir.
TEST(MpiLaunch, StubbornLauncherIsKilledAndDeleteCleansUp) {
  TempDir tmp("mpi-stubborn");
  fs::path table = writeGridTable(tmp.path());
  fs::path stubborn = writeScript(tmp.path() / "stubborn.sh",
                                  "#!/bin/sh\n"
                                  "trap '' USR1 TERM\n"
                                  "while :; do sleep 0.05; done\n");
  fs::path cfg = writeJson(
      tmp.path() / "lgpd.json",
      {{"mpi", {{"launcher", stubborn.string()}, {"lgp", LGP_CLI_BIN}, {"stop_grace_s", 0.5}}}});
  Daemon d(tmp.path() / "state");
  ASSERT_TRUE(d.start({"--config", cfg.string()}));
  auto running = [](const json& j) { return j.value("status", "") == "running"; };
  std::string a = d.submit(mpiConfig(table, 2, 100));
  ASSERT_EQ(d.waitFor(a, running, 30).value("status", ""), "running");
  sleepMs(300);  // the script installs its traps
  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_EQ(d.post("/api/v1/runs/" + a + "/cancel", "").status, 200);
  json done = d.waitDone(a, 30);
  const double took = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_EQ(done.value("status", ""), "cancelled") << done.dump() << d.log();
  EXPECT_GE(took, 0.9) << "SIGKILL only after both grace periods";
  EXPECT_TRUE(waitNoProcesses(stubborn.string()).empty())
      << joined(processesMentioning(stubborn.string()));
  EXPECT_NE(d.log().find("sending SIGTERM"), std::string::npos) << d.log();

  std::string b = d.submit(mpiConfig(table, 2, 100));
  ASSERT_EQ(d.waitFor(b, running, 30).value("status", ""), "running");
  const fs::path work = tmp.path() / "state" / "mpi" / b;
  EXPECT_TRUE(fs::exists(work));
  EXPECT_EQ(d.del("/api/v1/runs/" + b).status, 200);
  EXPECT_EQ(d.get("/api/v1/runs/" + b).status, 404);
  for (int i = 0; i < 200 && fs::exists(work); ++i) sleepMs(50);
  EXPECT_FALSE(fs::exists(work)) << "the work dir of a deleted run goes";
  EXPECT_TRUE(waitNoProcesses(stubborn.string()).empty());
  EXPECT_EQ(d.stop(), 0) << d.log();
}

// Shutdown leaves an MPI run "running" (its launcher gets SIGUSR1); the next lgpd relaunches
// it, and a relaunch that fails marks it failed instead of retrying forever.
TEST(MpiLaunch, ShutdownKeepsTheRunAndAFailedRelaunchEndsIt) {
  TempDir tmp("mpi-relaunch");
  fs::path table = writeGridTable(tmp.path());
  fs::path record = tmp.path() / "record.txt";
  fs::path usr1 = tmp.path() / "usr1.txt";
  // Stands in for a long search: stops on SIGUSR1 like lgp run does (exit 130).
  fs::path sleeper = writeScript(tmp.path() / "sleeper.sh",
                                 "#!/bin/sh\n"
                                 "trap 'echo usr1 >> \"" +
                                     usr1.string() +
                                     "\"; exit 130' USR1\n"
                                     "while :; do sleep 0.05; done\n");
  fs::path failing = writeScript(tmp.path() / "failing.sh", recordingLauncher(record, 1));
  fs::path cfg1 = writeJson(tmp.path() / "a.json",
                            {{"mpi", {{"launcher", sleeper.string()}, {"lgp", LGP_CLI_BIN}}}});
  fs::path cfg2 = writeJson(tmp.path() / "b.json",
                            {{"mpi", {{"launcher", failing.string()}, {"lgp", LGP_CLI_BIN}}}});
  const fs::path state = tmp.path() / "state";
  std::string id;
  {
    Daemon d(state);
    ASSERT_TRUE(d.start({"--config", cfg1.string()}));
    id = d.submit(mpiConfig(table, 2, 100));
    ASSERT_FALSE(id.empty());
    json r = d.waitFor(
        id, [](const json& j) { return j.value("status", "") == "running"; }, 30);
    ASSERT_EQ(r.value("status", ""), "running") << r.dump();
    sleepMs(300);  // the script installs its trap
    EXPECT_EQ(d.stop(), 0) << d.log();
  }
  EXPECT_EQ(readLines(usr1).size(), 1u) << "shutdown sends SIGUSR1 to the launcher";
  EXPECT_TRUE(waitNoProcesses(sleeper.string()).empty());
  {
    Daemon d(state);
    ASSERT_TRUE(d.start({"--config", cfg2.string()}));
    json done = d.waitDone(id, 30);
    EXPECT_EQ(done.value("status", ""), "failed") << done.dump() << d.log();
    EXPECT_NE(done.value("error", "").find("exited with status 1"), std::string::npos)
        << done.dump();
    EXPECT_EQ(d.stop(), 0) << d.log();
  }
  {
    Daemon d(state);
    ASSERT_TRUE(d.start({"--config", cfg2.string()}));
    sleepMs(1500);
    EXPECT_EQ(d.get("/api/v1/runs/" + id).j().value("status", ""), "failed");
    EXPECT_EQ(d.stop(), 0) << d.log();
  }
  auto lines = readLines(record);
  EXPECT_EQ(std::count(lines.begin(), lines.end(), "--- launch"), 1) << "relaunched once";
}

// --- end to end with the real mpirun --------------------------------------------------------

class MpirunTest : public ::testing::Test {
 protected:
  void SetUp() override {
#ifndef LGPD_TEST_HAVE_MPI
    LGP_SKIP_UNLESS_REQUIRED()
        << "lgp is built without MPI (LGP_WITH_MPI=OFF): it refuses to run under mpirun";
#endif
    mpirun_ = findInPath("mpirun");
    if (mpirun_.empty())
      LGP_SKIP_UNLESS_REQUIRED() << "mpirun not found in PATH (apt install openmpi-bin)";
    tmp_.emplace("mpirun");
    table_ = writeGridTable(tmp_->path(), 16);
    // The default launcher ("mpirun" from PATH) and the default lgp (found next to lgpd).
    cfg_ = writeJson(tmp_->path() / "lgpd.json", {{"mpi", {{"args", {"--oversubscribe"}}}}});
    state_ = tmp_->path() / "state";
  }
  std::vector<std::string> flags() const {
    auto f = kFlags;
    f.insert(f.end(), {"--config", cfg_.string()});
    return f;
  }
  std::string mpirun_;
  std::optional<TempDir> tmp_;
  fs::path table_, cfg_, state_;
};

TEST_F(MpirunTest, TwoRanksFinishWithAFrontInTheStore) {
  Daemon d(state_);
  ASSERT_TRUE(d.start(flags()));
  EXPECT_NE(d.log().find("MPI runs: " + mpirun_), std::string::npos) << d.log();
  std::string id = d.submit(mpiConfig(table_, 2, 30));
  ASSERT_FALSE(id.empty());
  json done = d.waitDone(id, 60);
  ASSERT_EQ(done.value("status", ""), "finished") << done.dump() << d.log();
  EXPECT_EQ(done["generation"], 30);
  EXPECT_EQ(done["stop_reason"], "generations");
  EXPECT_GT(done["evaluations"].get<uint64_t>(), 0u);
  EXPECT_GT(done["front_size"].get<int>(), 0);
  EXPECT_TRUE(done["best"].contains("error"));
  Reply front = d.get("/api/v1/runs/" + id + "/front");
  ASSERT_EQ(front.status, 200) << front.body;
  json f = front.j();
  EXPECT_EQ(f["format"], "lgp-front/1");
  EXPECT_TRUE(f["lgpd"]["final"].get<bool>());
  ASSERT_GT(f["members"].size(), 0u);
  EXPECT_EQ(f["members"].size(), done["front_size"].get<size_t>());
  EXPECT_EQ(f["progress"]["ranks"], 2) << "the islands ran on two ranks";
  // The stored front serves the other routes like an in-process one.
  EXPECT_EQ(d.get("/api/v1/runs/" + id + "/front/0/residuals").status, 200);
  json hist = d.get("/api/v1/runs/" + id + "/history").j()["history"];
  ASSERT_GE(hist.size(), 2u);
  EXPECT_EQ(hist.front()["event"], "started");
  EXPECT_EQ(hist.back()["event"], "finished");
  // Removed right after the run's end is committed.
  for (int i = 0; i < 100 && fs::exists(state_ / "mpi" / id); ++i) sleepMs(50);
  EXPECT_FALSE(fs::exists(state_ / "mpi" / id)) << "a finished run's work dir is removed";
  EXPECT_EQ(d.stop(), 0) << d.log();
}

TEST_F(MpirunTest, AFullDiskFailsTheRunWithTheReason) {
  // The data dir on a small tmpfs: once it is full, neither the ranks' files nor the store's
  // checkpoints can be written, and the run must end "failed" with a reason, not stay
  // "running"; DELETE still works.
  SmallDisk disk(tmp_->path() / "disk", 48);
  if (!disk.mounted()) GTEST_SKIP() << "cannot mount a small tmpfs here: " << disk.why();
  Daemon d(disk.dir() / "state");
  ASSERT_TRUE(d.start(flags()));
  std::string id = d.submit(mpiConfig(table_, 2, 1000000));
  ASSERT_FALSE(id.empty());
  json r = d.waitFor(
      id, [](const json& j) { return j["checkpoint"].is_object() || runEnded(j); }, 60);
  ASSERT_EQ(r.value("status", ""), "running") << r.dump() << d.log();
  ASSERT_GT(disk.fill(), 0u);
  r = d.waitDone(id, 90);
  EXPECT_EQ(r.value("status", ""), "failed") << r.dump() << d.log();
  // Whichever write failed first: the store's (the launch is stopped) or a rank's.
  const std::string error = r.value("error", "");
  EXPECT_TRUE(error.find("cannot store the run's") != std::string::npos ||
              error.find("MPI launch failed") != std::string::npos)
      << error;
  std::printf("the run's error: %s\n", error.substr(0, 300).c_str());
  EXPECT_EQ(d.del("/api/v1/runs/" + id).status, 200);
  EXPECT_TRUE(d.alive());
  disk.unfill();
  EXPECT_EQ(d.stop(), 0) << d.log();
}

TEST_F(MpirunTest, CancelEndsTheRunCancelledWithAFront) {
  Daemon d(state_);
  ASSERT_TRUE(d.start(flags()));
  std::string id = d.submit(mpiConfig(table_, 2, 1000000));
  ASSERT_FALSE(id.empty());
  json r = d.waitFor(
      id,
      [](const json& j) {
        const std::string st = j.value("status", "");
        return (st != "running" && st != "queued") || j.value("generation", 0) > 0;
      },
      30);
  ASSERT_EQ(r.value("status", ""), "running") << r.dump() << d.log();
  ASSERT_GT(r.value("generation", 0), 0) << "progress comes from the status file";
  Reply c = d.post("/api/v1/runs/" + id + "/cancel", "");
  ASSERT_EQ(c.status, 200) << c.body;
  EXPECT_EQ(c.j().value("status", ""), "cancelling");
  json done = d.waitDone(id, 30);
  ASSERT_EQ(done.value("status", ""), "cancelled") << done.dump() << d.log();
  EXPECT_EQ(done.value("stop_reason", ""), "stopped");
  Reply front = d.get("/api/v1/runs/" + id + "/front");
  ASSERT_EQ(front.status, 200) << "a cancelled MPI run keeps its front";
  EXPECT_GT(front.j()["members"].size(), 0u);
  EXPECT_TRUE(front.j()["lgpd"]["final"].get<bool>());
  EXPECT_TRUE(waitNoProcesses((state_ / "mpi" / id).string()).empty())
      << joined(processesMentioning((state_ / "mpi" / id).string()));
  EXPECT_EQ(d.stop(), 0) << d.log();
}

// lgpd stops (SIGTERM) or dies (kill -9) while an MPI run goes; no search is left running,
// and the next lgpd resumes the run from its checkpoint and finishes it to the budget.
class MpirunInterrupt : public MpirunTest, public ::testing::WithParamInterface<bool> {};

TEST_P(MpirunInterrupt, NextLgpdResumesFromTheCheckpoint) {
  const bool hard = GetParam();
  json run = mpiConfig(table_, 2, 0);
  run["search"]["wall_time_s"] = 4;
  std::string id;
  int checkpoint_before = -1;
  const std::string work = (state_ / "mpi").string();
  {
    Daemon d(state_);
    ASSERT_TRUE(d.start(flags()));
    id = d.submit(run);
    ASSERT_FALSE(id.empty());
    json r = d.waitFor(
        id,
        [](const json& j) {
          const std::string st = j.value("status", "");
          return (st != "running" && st != "queued") || j["checkpoint"].is_object();
        },
        30);
    ASSERT_EQ(r.value("status", ""), "running") << r.dump() << d.log();
    ASSERT_TRUE(r["checkpoint"].is_object()) << r.dump();
    checkpoint_before = r["checkpoint"]["generation"].get<int>();
    // lgpd rebuilds a live front from each checkpoint of the MPI run.
    Reply live = d.get("/api/v1/runs/" + id + "/front");
    ASSERT_EQ(live.status, 200) << live.body << d.log();
    EXPECT_FALSE(live.j()["lgpd"]["final"].get<bool>());
    EXPECT_GT(live.j()["members"].size(), 0u);
    if (hard)
      d.kill9();
    else
      EXPECT_EQ(d.stop(), 0) << d.log();
  }
  // kill -9: PR_SET_PDEATHSIG takes mpirun, and mpirun its ranks.
  auto left = waitNoProcesses(work, 15);
  EXPECT_TRUE(left.empty()) << "orphaned search processes:\n" << joined(left);
  // Without the work dir's checkpoint the relaunch restores the store's.
  if (hard) fs::remove(state_ / "mpi" / id / "checkpoint.json");

  Daemon d(state_);
  ASSERT_TRUE(d.start(flags()));
  json done = d.waitDone(id, 60);
  ASSERT_EQ(done.value("status", ""), "finished") << done.dump() << d.log();
  EXPECT_EQ(done["resumes"], 1);
  EXPECT_EQ(done["stop_reason"], "wall_time") << "as lgp run's final status reports it";
  EXPECT_GE(done["elapsed_s"].get<double>(), 3.9) << "the budget counts time before the stop";
  json hist = d.get("/api/v1/runs/" + id + "/history").j()["history"];
  int resumed_at = -1;
  bool after_resume = false, monotone = true;
  for (const auto& h : hist) {
    if (h["event"] == "resumed") {
      resumed_at = h["generation"];
      after_resume = true;
    } else if (after_resume) {
      monotone = monotone && h["generation"].get<int>() >= resumed_at;
    }
  }
  EXPECT_GE(resumed_at, checkpoint_before) << hist.dump();
  EXPECT_TRUE(monotone) << "the relaunch continued from the checkpoint, not from 0\n"
                        << hist.dump();
  Reply f = d.get("/api/v1/runs/" + id + "/front");
  ASSERT_EQ(f.status, 200);
  EXPECT_TRUE(f.j()["lgpd"]["final"].get<bool>());
  EXPECT_GT(f.j()["members"].size(), 0u);
  EXPECT_EQ(d.stop(), 0) << d.log();
}

INSTANTIATE_TEST_SUITE_P(Daemon, MpirunInterrupt, ::testing::Values(false, true),
                         [](const ::testing::TestParamInfo<bool>& p) {
                           return p.param ? "Kill9" : "Sigterm";
                         });

}  // namespace
}  // namespace lgpd_test
