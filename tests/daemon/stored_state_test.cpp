// What lgpd reads back from its own store and from a run's data file, changed behind its back
// (hardening round 3): a database row nested 100k deep (front or config), a row with a status
// or id that is not one, a checkpoint row with an island emptied, and a run's table rewritten with
// other columns. Each gets an answer (a 4xx or 5xx naming the problem, the bad row left out of the
// listing, the checkpoint refused), and lgpd keeps serving.
#include "daemon_harness.hpp"
#include "store_rows.hpp"

namespace lgpd_test {
namespace {

// A finished run on a fresh lgpd in `state`, the daemon stopped again; its id.
std::string finishedRun(const fs::path& state, const json& cfg) {
  Daemon d(state);
  if (!d.start()) return "";
  const std::string id = d.submit(cfg);
  if (id.empty() || d.waitDone(id).value("status", "") != "finished") return "";
  d.stop();
  return id;
}

TEST(StoredState, DeepRowsAreRefusedAndTheDaemonKeepsServing) {
  TempDir tmp("deeprows");
  const fs::path state = tmp.path() / "state";
  const json cfg = runConfig(writeGridTable(tmp.path()), 3);
  const std::string a = finishedRun(state, cfg), b = finishedRun(state, cfg);
  ASSERT_FALSE(a.empty());
  ASSERT_FALSE(b.empty());
  ASSERT_TRUE(
      execSql(state, "UPDATE fronts SET front = ?1 WHERE run_id = ?2", deepCbor(), a, true));
  ASSERT_TRUE(execSql(state, "UPDATE runs SET config = ?1 WHERE id = ?2", deepText(), b));
  Daemon d(state);
  ASSERT_TRUE(d.start()) << d.log();
  // The deep front: a 500 that says so (it is lgpd's own state that is broken), no crash.
  Reply r = d.get("/api/v1/runs/" + a + "/front");
  EXPECT_EQ(r.status, 500) << r.body;
  ASSERT_TRUE(d.alive()) << d.log();
  EXPECT_NE(d.log().find("nested deeper than 64 levels"), std::string::npos) << d.log();
  r = d.get("/api/v1/runs/" + a + "/front/0/code");
  EXPECT_EQ(r.status, 500) << r.body;
  // The deep config: its run is a 500, the listing leaves it out and says why.
  r = d.get("/api/v1/runs/" + b);
  EXPECT_EQ(r.status, 500) << r.body;
  ASSERT_TRUE(d.alive()) << d.log();
  r = d.get("/api/v1/runs");
  ASSERT_EQ(r.status, 200) << r.body;
  ASSERT_EQ(r.j()["runs"].size(), 1u) << r.body;
  EXPECT_EQ(r.j()["runs"][0]["id"], a);
  ASSERT_EQ(r.j()["unreadable"].size(), 1u) << r.body;
  EXPECT_NE(r.j()["unreadable"][0].get<std::string>().find("nested deeper"), std::string::npos);
  EXPECT_EQ(d.stop(), 0) << d.log();
}

TEST(StoredState, ABadStatusOrIdLeavesOneRowOutNotTheListing) {
  TempDir tmp("badstatus");
  const fs::path state = tmp.path() / "state";
  const json cfg = runConfig(writeGridTable(tmp.path()), 3);
  // b's table is inline: lgpd writes it to <data-dir>/tables/<id>.json before the job starts.
  json inline_cfg = cfg;
  inline_cfg["data"] = {{"table", jsonTable({"x", "y"})}};
  const std::string a = finishedRun(state, cfg), b = finishedRun(state, inline_cfg),
                    c = finishedRun(state, cfg);
  ASSERT_FALSE(a.empty() || b.empty() || c.empty());
  ASSERT_TRUE(execSql(state, "UPDATE runs SET status = ?1 WHERE id = ?2", "\x1b]0;pwned\x07", a));
  // A queued run whose id is a path: its table would be written outside the data dir.
  ASSERT_TRUE(execSql(state, "UPDATE runs SET id = ?1, status = 'queued' WHERE id = ?2",
                      "../../escaped", b));
  Daemon d(state);
  ASSERT_TRUE(d.start()) << d.log();
  const Reply r = d.get("/api/v1/runs");
  ASSERT_EQ(r.status, 200) << r.body;
  ASSERT_EQ(r.j()["runs"].size(), 1u) << r.body;
  EXPECT_EQ(r.j()["runs"][0]["id"], c);
  EXPECT_EQ(r.j()["unreadable"].size(), 2u) << r.body;
  EXPECT_EQ(d.get("/api/v1/runs/" + a).status, 500);
  EXPECT_EQ(d.get("/api/v1/runs/" + c).status, 200);
  // The scheduler passes the queued row over, saying so; nothing is written outside.
  bool skipped = false;
  for (int i = 0; i < 200 && !skipped; ++i, sleepMs(50))
    skipped =
        d.log().find("a run row with a bad id '../../escaped' is skipped") != std::string::npos;
  EXPECT_TRUE(skipped) << d.log();
  EXPECT_FALSE(fs::exists(tmp.path() / "escaped.json"));
  // The log names the rows without their escape sequences.
  EXPECT_EQ(d.log().find('\x1b'), std::string::npos);
  EXPECT_EQ(d.stop(), 0) << d.log();
}

TEST(StoredState, ATamperedCheckpointIsRefusedAndTheRunStartsOver) {
  TempDir tmp("tamperedck");
  const fs::path state = tmp.path() / "state";
  json cfg = runConfig(writeGridTable(tmp.path()), 0);
  cfg["search"]["wall_time_s"] = 600;  // stopped by the test
  std::string id;
  {
    Daemon d(state);
    ASSERT_TRUE(d.start({"--checkpoint-interval", "0.05"})) << d.log();
    id = d.submit(cfg);
    ASSERT_FALSE(id.empty());
    const json run = d.waitFor(id, [](const json& r) { return r["checkpoint"].is_object(); });
    ASSERT_TRUE(run["checkpoint"].is_object()) << run.dump();
    EXPECT_EQ(d.stop(), 0) << d.log();  // the run stays "running", with its checkpoint
  }
  json ck = storedCheckpoint(state, id);
  ASSERT_TRUE(ck.is_object());
  for (const char* key : {"population", "rank", "crowd"}) ck["islands"][0][key] = json::array();
  const auto bytes = json::to_cbor(ck);
  ASSERT_TRUE(execSql(state, "UPDATE checkpoints SET state = ?1 WHERE run_id = ?2",
                      std::string(bytes.begin(), bytes.end()), id, true));
  Daemon d(state);
  ASSERT_TRUE(d.start()) << d.log();
  const json run = d.waitFor(id, [&](const json& r) {
    return d.log().find("checkpoint rejected") != std::string::npos && r.value("generation", 0) > 0;
  });
  ASSERT_TRUE(d.alive()) << d.log();
  EXPECT_NE(d.log().find("checkpoint rejected (checkpoint: island 0 holds 0 programs"),
            std::string::npos)
      << d.log();
  EXPECT_EQ(run.value("status", ""), "running") << run.dump();
  EXPECT_EQ(d.post("/api/v1/runs/" + id + "/cancel", "").status, 200);
  EXPECT_EQ(d.waitDone(id).value("status", ""), "cancelled");
  EXPECT_EQ(d.stop(), 0) << d.log();
}

// A run with no column list in its config takes the table file's own: rewritten, the front's
// program would read columns that are not there (a crash) or other ones (wrong answers).
TEST(StoredState, ResidualsOnARewrittenTableAre409) {
  TempDir tmp("rewritten");
  const fs::path state = tmp.path() / "state";
  const fs::path table = tmp.path() / "t.json";
  std::vector<std::string> inputs;
  for (int i = 0; i < 30; ++i) inputs.push_back("x" + std::to_string(i));
  std::ofstream(table) << jsonTable(inputs).dump();
  const json cfg = {{"data", {{"path", table.string()}}},
                    {"search", {{"population", 32}, {"generations", 5}, {"threads", 1}}}};
  const std::string id = finishedRun(state, cfg);
  ASSERT_FALSE(id.empty());
  Daemon d(state);
  ASSERT_TRUE(d.start()) << d.log();
  ASSERT_EQ(d.get("/api/v1/runs/" + id + "/front/0/residuals").status, 200);
  d.stop();
  for (const auto& now : {std::vector<std::string>{"x0"}, std::vector<std::string>{"u", "v"}}) {
    std::ofstream(table) << jsonTable(now).dump();
    ASSERT_TRUE(d.start()) << d.log();  // a fresh table cache
    const json front = d.get("/api/v1/runs/" + id + "/front").j();
    ASSERT_FALSE(front["members"].empty());
    for (size_t k = 0; k < front["members"].size(); ++k) {
      Reply r;
      for (int i = 0; i < 100; ++i) {  // the table loads on the background thread
        r = d.get("/api/v1/runs/" + id + "/front/" + std::to_string(k) + "/residuals");
        if (r.status != 503) break;
        sleepMs(50);
      }
      ASSERT_TRUE(d.alive()) << d.log();
      EXPECT_EQ(r.status, 409) << now.size() << " inputs, member " << k << ": " << r.body;
      EXPECT_NE(r.body.find("the run's table no longer has the front's columns"), std::string::npos)
          << r.body;
    }
    d.stop();
  }
}

// A long run's history keeps its lifecycle events: the newest 5000 rows come back, and every
// started / resumed / finished / cancelled row however old (an overnight run with progress rows
// every second has 28,800 by morning; its "resumed" row of the evening must not drop out).
TEST(StoredState, HistoryKeepsLifecycleEventsPastItsNewestRows) {
  TempDir tmp("history");
  const fs::path state = tmp.path() / "state";
  const std::string id = finishedRun(state, runConfig(writeGridTable(tmp.path()), 3));
  ASSERT_FALSE(id.empty());
  {  // 6000 plain progress rows after the run's own, as a long run would have written
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open((state / "lgpd.sqlite3").c_str(), &db), SQLITE_OK);
    const std::string sql =
        "WITH RECURSIVE n(i) AS (SELECT 1 UNION ALL SELECT i + 1 FROM n WHERE i < 6000) "
        "INSERT INTO progress (run_id, t, generation, evaluations, elapsed_s, best_error, "
        "front_size, event) SELECT '" +
        id + "', 2e9 + i, 3, i, i, 0.5, 1, '' FROM n";
    char* err = nullptr;
    const int rc = sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &err);
    const std::string msg = err ? err : "";
    sqlite3_free(err);
    sqlite3_close(db);
    ASSERT_EQ(rc, SQLITE_OK) << msg;
  }
  Daemon d(state);
  ASSERT_TRUE(d.start()) << d.log();
  Reply r = d.get("/api/v1/runs/" + id + "/history");
  ASSERT_EQ(r.status, 200) << r.body;
  const json hist = r.j()["history"];
  int started = 0, finished = 0, plain = 0;
  for (const auto& h : hist) {
    started += h["event"] == "started";
    finished += h["event"] == "finished";
    plain += h["event"] == "";
  }
  EXPECT_EQ(started, 1);
  EXPECT_EQ(finished, 1);
  EXPECT_EQ(plain, 5000);                       // the newest 5000 rows are all plain ones here
  EXPECT_EQ(hist.front()["event"], "started");  // oldest first
  EXPECT_EQ(d.stop(), 0) << d.log();
}

}  // namespace
}  // namespace lgpd_test
