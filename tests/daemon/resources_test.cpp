// lgpd at the machine's limits (issue 21): one daemon per data dir, a full disk, a bounded
// queue, threads capped at the core count, populations bounded by memory, a run whose
// threads cannot be started, and a data file swapped for a link after submit. Each case ends
// with the daemon still up.
#include <sched.h>

#include <cerrno>
#include <cstring>

#include "daemon_harness.hpp"

namespace lgpd_test {
namespace {

int usableCores() {
  cpu_set_t set;
  CPU_ZERO(&set);
  if (::sched_getaffinity(0, sizeof set, &set) == 0) return CPU_COUNT(&set);
  return static_cast<int>(std::thread::hardware_concurrency());
}

std::string readFile(const fs::path& p) {
  std::ifstream f(p);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

fs::path writeDaemonConfig(const fs::path& dir, const json& j) {
  fs::path p = dir / "lgpd.json";
  std::ofstream(p) << j.dump();
  return p;
}

// --- one daemon per data dir ---------------------------------------------------------------

TEST(OneDaemonPerDataDir, SecondDaemonExitsNamingTheFirstOnesPid) {
  TempDir tmp("lock");
  const fs::path state = tmp.path() / "state";
  Daemon first(state);
  ASSERT_TRUE(first.start());
  const pid_t holder = first.pid();

  const fs::path log = tmp.path() / "second.log";
  std::string out;
  const int code = runProgram({LGPD_BIN, "--data-dir", state.string(), "--listen", "127.0.0.1:0"},
                              &out, log, 30);
  const std::string err = readFile(log);
  EXPECT_EQ(code, 1) << err;
  EXPECT_NE(err.find("in use by another lgpd (pid " + std::to_string(holder) + ","),
            std::string::npos)
      << err;
  EXPECT_TRUE(first.alive());
  EXPECT_EQ(first.get("/api/v1/health").status, 200);

  // The lock goes with the process: the next lgpd on the dir starts, also after a kill -9.
  first.kill9();
  Daemon again(state);
  ASSERT_TRUE(again.start());
}

// --- a full disk -------------------------------------------------------------------------

// A run that can no longer write its checkpoint is failed with the reason, not left
// "running"; DELETE then works, and once there is room again the daemon takes new runs.
TEST(FullDisk, RunThatCannotWriteIsFailedWithTheReason) {
  TempDir tmp("fulldisk");
  SmallDisk disk(tmp.path() / "disk", 24);
  if (!disk.mounted()) GTEST_SKIP() << "cannot mount a small tmpfs here: " << disk.why();
  const fs::path table = writeGridTable(tmp.path());
  Daemon d(disk.dir() / "state");
  ASSERT_TRUE(d.start({"--checkpoint-interval", "0.05", "--progress-interval", "0.02",
                       "--front-interval", "0.05"}));
  const std::string id = d.submit(runConfig(table, 1 << 30));
  ASSERT_FALSE(id.empty());
  json r =
      d.waitFor(id, [](const json& run) { return run["checkpoint"].is_object() || runEnded(run); });
  ASSERT_EQ(r.value("status", ""), "running") << r.dump();
  ASSERT_GT(disk.fill(), 0u);

  r = d.waitFor(id, runEnded, 60);
  EXPECT_EQ(r.value("status", ""), "failed") << r.dump();
  const std::string error = r.value("error", "");
  EXPECT_NE(error.find("cannot store the run's"), std::string::npos) << error;
  EXPECT_NE(error.find("disk is full"), std::string::npos) << error;

  EXPECT_EQ(d.del("/api/v1/runs/" + id).status, 200);
  EXPECT_EQ(d.get("/api/v1/runs/" + id).status, 404);
  EXPECT_TRUE(d.alive());

  disk.unfill();
  const std::string next = d.submit(runConfig(table, 3));
  ASSERT_FALSE(next.empty());
  EXPECT_EQ(d.waitDone(next).value("status", ""), "finished");
}

// With the disk full, cancelling a queued and a running run and deleting both still work.
TEST(FullDisk, CancelAndDeleteWorkOnAFullDisk) {
  TempDir tmp("fullcancel");
  SmallDisk disk(tmp.path() / "disk", 24);
  if (!disk.mounted()) GTEST_SKIP() << "cannot mount a small tmpfs here: " << disk.why();
  const fs::path table = writeGridTable(tmp.path());
  Daemon d(disk.dir() / "state");
  // Nothing is written while the runs go (every interval is an hour): the first writes after
  // the disk fills are the cancels.
  ASSERT_TRUE(d.start({"--jobs", "1", "--checkpoint-interval", "3600", "--progress-interval",
                       "3600", "--front-interval", "3600"}));
  const std::string running = d.submit(runConfig(table, 1 << 30));
  ASSERT_FALSE(running.empty());
  json r = d.waitFor(running, [](const json& run) { return run.value("status", "") != "queued"; });
  ASSERT_EQ(r.value("status", ""), "running") << r.dump();
  const std::string queued = d.submit(runConfig(table, 1 << 30));
  ASSERT_FALSE(queued.empty());
  ASSERT_GT(disk.fill(), 0u);

  Reply c = d.post("/api/v1/runs/" + queued + "/cancel", "{}");
  EXPECT_EQ(c.status, 200) << c.body;
  EXPECT_EQ(d.get("/api/v1/runs/" + queued).j().value("status", ""), "cancelled");
  c = d.post("/api/v1/runs/" + running + "/cancel", "{}");
  EXPECT_EQ(c.status, 200) << c.body;
  r = d.waitFor(running, runEnded, 60);
  EXPECT_EQ(r.value("status", ""), "cancelled") << r.dump();

  for (const auto& id : {queued, running}) {
    Reply del = d.del("/api/v1/runs/" + id);
    EXPECT_EQ(del.status, 200) << del.body;
    EXPECT_EQ(d.get("/api/v1/runs/" + id).status, 404);
  }
  EXPECT_TRUE(d.alive());
}

// --- resource bounds -----------------------------------------------------------------------

// Past max_queued_runs a submission gets 429 with Retry-After; once a run leaves the queue,
// submissions are taken again.
TEST(Bounds, QueuePastItsBoundGets429WithRetryAfter) {
  TempDir tmp("queue");
  const fs::path table = writeGridTable(tmp.path());
  const fs::path cfg = writeDaemonConfig(tmp.path(), {{"max_queued_runs", 2}});
  Daemon d(tmp.path() / "state");
  ASSERT_TRUE(d.start({"--config", cfg.string(), "--jobs", "1"}));
  const std::string first = d.submit(runConfig(table, 1 << 30));
  ASSERT_FALSE(first.empty());
  json r = d.waitFor(first, [](const json& run) { return run.value("status", "") != "queued"; });
  ASSERT_EQ(r.value("status", ""), "running") << r.dump();
  std::vector<std::string> queued;
  for (int i = 0; i < 2; ++i) {
    queued.push_back(d.submit(runConfig(table, 1 << 30)));
    ASSERT_FALSE(queued.back().empty()) << "submission " << i;
  }
  httplib::Client c("127.0.0.1", d.port());
  auto res = c.Post("/api/v1/runs", runConfig(table, 3).dump(), "application/json");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 429) << res->body;
  EXPECT_EQ(res->get_header_value("Retry-After"), "30");
  EXPECT_NE(res->body.find("max_queued_runs is 2"), std::string::npos) << res->body;

  // A cancelled run leaves the queue: there is room for one more.
  EXPECT_EQ(d.post("/api/v1/runs/" + queued[0] + "/cancel", "{}").status, 200);
  EXPECT_FALSE(d.submit(runConfig(table, 3)).empty());
  for (const auto& id : {first, queued[1]}) d.post("/api/v1/runs/" + id + "/cancel", "{}");
  EXPECT_TRUE(d.alive());
}

// search.threads above the cores lgpd may use runs on that many cores.
TEST(Bounds, ThreadsAreCappedAtTheCoreCount) {
  TempDir tmp("threads");
  const fs::path table = writeGridTable(tmp.path());
  Daemon d(tmp.path() / "state");
  ASSERT_TRUE(d.start());
  const int cores = usableCores();
  json cfg = runConfig(table, 2);
  cfg["search"]["threads"] = std::max(64, 4 * cores);
  const std::string id = d.submit(cfg);
  ASSERT_FALSE(id.empty());
  ASSERT_EQ(d.waitDone(id).value("status", ""), "finished") << d.log();
  json front = d.get("/api/v1/runs/" + id + "/front").j();
  ASSERT_TRUE(front.is_object());
  const int used = front["progress"]["threads"].get<int>();
  EXPECT_GE(used, 1);
  EXPECT_LE(used, cores);
}

// A population whose programs would not fit the daemon's memory bound is refused at submit,
// naming the field; one that fits is taken.
TEST(Bounds, PopulationBeyondTheMemoryBoundGets400) {
  TempDir tmp("memory");
  const fs::path table = writeGridTable(tmp.path());
  const fs::path dcfg = writeDaemonConfig(tmp.path(), {{"max_run_memory_mb", 64}});
  Daemon d(tmp.path() / "state");
  ASSERT_TRUE(d.start({"--config", dcfg.string()}));
  json cfg = runConfig(table, 1, 1 << 20);
  cfg["program"] = {{"max_length", 255}, {"constants", 255}};
  Reply r;
  EXPECT_TRUE(d.submit(cfg, &r).empty());
  EXPECT_EQ(r.status, 400) << r.body;
  EXPECT_EQ(r.j().value("field", ""), "/search/population") << r.body;
  EXPECT_NE(r.body.find("max_run_memory_mb"), std::string::npos) << r.body;

  // Islands weigh more than these short programs: the message names them.
  cfg = runConfig(table, 1, 16384);
  cfg["program"] = {{"max_length", 12}, {"constants", 0}};
  cfg["search"]["islands"] = {{"count", 4096}};
  EXPECT_TRUE(d.submit(cfg, &r).empty());
  EXPECT_EQ(r.status, 400) << r.body;
  EXPECT_EQ(r.j().value("field", ""), "/search/islands/count") << r.body;

  cfg = runConfig(table, 1, 64);
  const std::string id = d.submit(cfg, &r);
  EXPECT_FALSE(id.empty()) << r.body;
}

// The semantic cache is allocated in full when the search starts (about 136 bytes an entry):
// 2^26 entries are about 9 GiB, and 2^23 took lgpd from 10 to 1032 MB (hardening round 3,
// F4). It counts against the bound, and a cache too large is named.
TEST(Bounds, ASemanticCacheBeyondTheMemoryBoundGets400) {
  TempDir tmp("cachememory");
  const fs::path table = writeGridTable(tmp.path());
  const fs::path dcfg = writeDaemonConfig(tmp.path(), {{"max_run_memory_mb", 256}});
  Daemon d(tmp.path() / "state");
  ASSERT_TRUE(d.start({"--config", dcfg.string()}));
  for (int entries : {1 << 26, 1 << 23}) {
    json cfg = runConfig(table, 1, 64);
    cfg["search"]["semantic_cache"] = entries;
    Reply r;
    EXPECT_TRUE(d.submit(cfg, &r).empty()) << entries;
    EXPECT_EQ(r.status, 400) << r.body;
    EXPECT_EQ(r.j().value("field", ""), "/search/semantic_cache") << r.body;
    EXPECT_NE(r.body.find("semantic cache of " + std::to_string(entries) + " entries"),
              std::string::npos)
        << r.body;
  }
  // One that fits (2^20 entries, about 136 MiB), and the cache off, are taken.
  for (int entries : {1 << 20, 0}) {
    json cfg = runConfig(table, 1, 64);
    cfg["search"]["semantic_cache"] = entries;
    Reply r;
    EXPECT_FALSE(d.submit(cfg, &r).empty()) << entries << ": " << r.body;
  }
  EXPECT_EQ(d.stop(), 0) << d.log();
}

// A run whose threads cannot be started (here: a limit of no extra thread, as a machine at
// its thread limit) fails with the reason; the daemon goes on and runs the next one.
TEST(Bounds, ThreadCreationFailureFailsTheRunNotTheDaemon) {
  if (usableCores() < 2) GTEST_SKIP() << "one core: a search never starts a second thread";
  TempDir tmp("threadfail");
  const fs::path table = writeGridTable(tmp.path());
  Daemon d(tmp.path() / "state");
  ::setenv("LGPD_TEST_THREAD_LIMIT", "0", 1);
  auto started = d.start();
  ::unsetenv("LGPD_TEST_THREAD_LIMIT");
  ASSERT_TRUE(started);
  json cfg = runConfig(table, 3);
  cfg["search"]["threads"] = 2;
  const std::string id = d.submit(cfg);
  ASSERT_FALSE(id.empty());
  json r = d.waitDone(id);
  EXPECT_EQ(r.value("status", ""), "failed") << r.dump();
  EXPECT_NE(r.value("error", "").find("cannot start the search's 2 threads"), std::string::npos)
      << r.dump();
  EXPECT_TRUE(d.alive());
  const std::string next = d.submit(runConfig(table, 3));  // one thread: nothing to start
  ASSERT_FALSE(next.empty());
  EXPECT_EQ(d.waitDone(next).value("status", ""), "finished");
}

// --- paths checked where they are opened ----------------------------------------------------

// A data file inside allowed_data_dirs, replaced by a link to a file outside after submit,
// is refused when the job starts: the run fails naming the field and never reads the file.
TEST(DataPaths, FileSwappedForALinkOutsideAfterSubmitIsRefusedAtJobStart) {
  TempDir tmp("swap");
  const fs::path allowed = tmp.path() / "allowed", outside = tmp.path() / "outside";
  fs::create_directories(allowed);
  fs::create_directories(outside);
  const fs::path inside_table = writeGridTable(allowed);
  const fs::path outside_table = writeGridTable(outside);
  const fs::path dcfg = writeDaemonConfig(tmp.path(), {{"allowed_data_dirs", {allowed.string()}}});
  Daemon d(tmp.path() / "state");
  ASSERT_TRUE(d.start({"--config", dcfg.string(), "--jobs", "1"}));

  Reply r;
  EXPECT_TRUE(d.submit(runConfig(outside_table, 3), &r).empty());
  EXPECT_EQ(r.status, 400) << r.body;
  EXPECT_EQ(r.j().value("field", ""), "/data/path") << r.body;

  // One run holds the only job slot, so the second waits in the queue while its file is
  // swapped.
  const std::string blocker = d.submit(runConfig(inside_table, 1 << 30));
  ASSERT_FALSE(blocker.empty());
  json b = d.waitFor(blocker, [](const json& run) { return run.value("status", "") != "queued"; });
  ASSERT_EQ(b.value("status", ""), "running") << b.dump();
  const std::string id = d.submit(runConfig(inside_table, 3), &r);
  ASSERT_FALSE(id.empty()) << r.body;
  fs::remove(inside_table);
  fs::create_symlink(outside_table, inside_table);
  EXPECT_EQ(d.post("/api/v1/runs/" + blocker + "/cancel", "{}").status, 200);

  json run = d.waitDone(id);
  EXPECT_EQ(run.value("status", ""), "failed") << run.dump();
  const std::string error = run.value("error", "");
  EXPECT_NE(error.find("/data/path: " + inside_table.string() +
                       " is outside the daemon's allowed_data_dirs"),
            std::string::npos)
      << error;
  EXPECT_EQ(error.find(outside.string()), std::string::npos) << error;
  EXPECT_EQ(d.get("/api/v1/runs/" + id + "/front").status, 404);
  EXPECT_TRUE(d.alive());
}

}  // namespace
}  // namespace lgpd_test
