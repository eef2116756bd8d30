// lgpd HTTP API against a real daemon: submit, list, status, front, member, code, residuals,
// history, cancel, delete; bad input gets the right 4xx and never a crash; bearer token and
// loopback rules; the `lgp submit` / `lgp status` client.
#include <cmath>

#include "daemon_harness.hpp"

namespace lgpd_test {
namespace {

class ApiTest : public ::testing::Test {
 protected:
  void SetUp() override {
    tmp_.emplace("api");
    table_ = writeGridTable(tmp_->path());
    // Small body limit so the oversized-body case stays cheap.
    fs::path cfg = tmp_->path() / "lgpd.json";
    std::ofstream(cfg) << json{{"max_body_bytes", 65536}}.dump();
    daemon_.emplace(tmp_->path() / "state");
    ASSERT_TRUE(daemon_->start({"--config", cfg.string(), "--checkpoint-interval", "0.2",
                                "--progress-interval", "0.05", "--front-interval", "0.2"}));
  }
  void TearDown() override {
    if (daemon_) {
      EXPECT_TRUE(daemon_->alive()) << daemon_->log();
      EXPECT_EQ(daemon_->stop(), 0) << daemon_->log();
    }
  }
  std::optional<TempDir> tmp_;
  std::optional<Daemon> daemon_;
  fs::path table_;
};

TEST_F(ApiTest, SubmitStatusFrontCodeResiduals) {
  Daemon& d = *daemon_;
  json cfg = runConfig(table_, 15);
  cfg["name"] = "grid test";
  Reply sub;
  std::string id = d.submit(cfg, &sub);
  ASSERT_EQ(sub.status, 201) << sub.body;
  ASSERT_EQ(id.size(), 16u);
  EXPECT_EQ(sub.j().value("status", ""), "queued");

  Reply list = d.get("/api/v1/runs");
  ASSERT_EQ(list.status, 200);
  ASSERT_EQ(list.j()["runs"].size(), 1u);
  EXPECT_EQ(list.j()["runs"][0]["id"], id);
  EXPECT_EQ(list.j()["runs"][0]["name"], "grid test");

  json run = d.waitDone(id);
  ASSERT_EQ(run.value("status", ""), "finished") << run.dump() << d.log();
  EXPECT_EQ(run["generation"], 15);
  // Every generation scores at least the population's 32 offspring.
  EXPECT_GE(run["evaluations"].get<uint64_t>(), 32u * 15u);
  EXPECT_GT(run["elapsed_s"].get<double>(), 0.0);
  EXPECT_TRUE(run["best"].contains("error"));
  EXPECT_TRUE(run["best"].contains("cost"));
  EXPECT_TRUE(run["best"].contains("discontinuity"));
  EXPECT_EQ(run["stop_reason"], "generations");
  EXPECT_EQ(run["config"]["search"]["generations"], 15);

  Reply front = d.get("/api/v1/runs/" + id + "/front");
  ASSERT_EQ(front.status, 200) << front.body;
  json f = front.j();
  EXPECT_EQ(f["format"], "lgp-front/1");
  EXPECT_TRUE(f["lgpd"]["final"].get<bool>());
  ASSERT_GT(f["members"].size(), 0u);
  EXPECT_EQ(f["members"].size(), run["front_size"].get<size_t>());
  // The run's counters are the final front's.
  EXPECT_EQ(run["evaluations"], f["progress"]["evaluations"]);
  EXPECT_EQ(run["generation"], f["progress"]["generation"]);
  // (The front is built, with its members' measured costs, just before the final counters.)
  EXPECT_GE(run["elapsed_s"].get<double>(), f["progress"]["elapsed_s"].get<double>());
  const size_t last = f["members"].size() - 1;

  Reply member = d.get("/api/v1/runs/" + id + "/front/" + std::to_string(last));
  ASSERT_EQ(member.status, 200);
  EXPECT_EQ(member.j()["cost"], f["members"][last]["cost"]);

  for (const char* lang : {"hlsl", "glsl", "cpp"}) {
    Reply code = d.get("/api/v1/runs/" + id + "/front/0/code?lang=" + lang);
#ifdef LGPD_TEST_HAVE_EMIT
    EXPECT_EQ(code.status, 200) << lang << ": " << code.body;
    EXPECT_NE(code.body.find("lgp_fit"), std::string::npos) << code.body;
#else
    EXPECT_EQ(code.status, 503) << code.body;
#endif
  }
  EXPECT_EQ(d.get("/api/v1/runs/" + id + "/front/0/code?lang=wgsl").status, 400);
  EXPECT_EQ(d.get("/api/v1/runs/" + id + "/front/9999/code?lang=hlsl").status, 404);

  // Residuals: one signed error per row, consistent with the member's float32 RMSE.
  Reply res = d.get("/api/v1/runs/" + id + "/front/" + std::to_string(last) + "/residuals");
  ASSERT_EQ(res.status, 200) << res.body;
  json rj = res.j();
  EXPECT_EQ(rj["rows"], 144);
  EXPECT_EQ(rj["inputs"], json({"x", "y"}));
  ASSERT_EQ(rj["outputs"].size(), 1u);
  const auto& resid = rj["outputs"][0]["residual"];
  ASSERT_EQ(resid.size(), 144u);
  EXPECT_EQ(rj["columns"]["x"].size(), 144u);
  double s2 = 0;
  for (const auto& e : resid) s2 += e.get<double>() * e.get<double>();
  double rmse = std::sqrt(s2 / 144);
  double want = f["members"][last]["outputs"][0]["float32"]["rmse"].get<double>();
  EXPECT_NEAR(rmse, want, 1e-4 * std::max(1.0, want)) << "residual RMSE vs front metrics";

  // Every metric, by its one definition, equals the front's (the search's float32 figures).
  for (const char* metric : {"rmse", "max_abs", "mae", "mean_rel"}) {
    const double front_m = f["members"][last]["outputs"][0]["float32"][metric].get<double>();
    EXPECT_NEAR(rj["outputs"][0][metric].get<double>(), front_m, 1e-4 * std::max(1e-3, front_m))
        << metric;
  }
  // The languages the export speaks (the page's tabs).
  Reply langs = d.get("/api/v1/languages");
  ASSERT_EQ(langs.status, 200) << langs.body;
  EXPECT_EQ(langs.j()["languages"][0]["name"], "hlsl") << langs.body;
  EXPECT_EQ(langs.j()["languages"].size(), 3u) << langs.body;

  Reply hist = d.get("/api/v1/runs/" + id + "/history");
  ASSERT_EQ(hist.status, 200);
  auto h = hist.j()["history"];
  ASSERT_GE(h.size(), 2u);
  EXPECT_EQ(h.front()["event"], "started");
  EXPECT_EQ(h.back()["event"], "finished");

  // A finished run cannot be cancelled; it can be deleted, once.
  EXPECT_EQ(d.post("/api/v1/runs/" + id + "/cancel", "").status, 409);
  Reply del = d.del("/api/v1/runs/" + id);
  EXPECT_EQ(del.status, 200) << del.body;
  EXPECT_EQ(d.get("/api/v1/runs/" + id).status, 404);
  EXPECT_EQ(d.get("/api/v1/runs/" + id + "/front").status, 404);
  EXPECT_EQ(d.del("/api/v1/runs/" + id).status, 404);
  EXPECT_EQ(d.get("/api/v1/runs").j()["runs"].size(), 0u);
}

// Structure, round 2: lgpd's residual metrics ignored the table's row weights. They are the
// metrics' one definition now, the weights included, and agree with the front's.
TEST_F(ApiTest, ResidualMetricsHonourRowWeights) {
  Daemon& d = *daemon_;
  json table = jsonTable({"x", "y"}, 64);
  json w = json::array();
  for (int r = 0; r < 64; ++r) w.push_back(r < 16 ? 8.0 : 0.25);
  table["weights"] = w;
  json cfg = {{"data", {{"table", table}}},
              {"search", {{"population", 32}, {"generations", 5}, {"threads", 1}}}};
  std::string id = d.submit(cfg);
  ASSERT_FALSE(id.empty());
  ASSERT_EQ(d.waitDone(id).value("status", ""), "finished") << d.log();
  json f = d.get("/api/v1/runs/" + id + "/front").j();
  const size_t last = f["members"].size() - 1;
  Reply res;
  for (int i = 0; i < 100; ++i) {
    res = d.get("/api/v1/runs/" + id + "/front/" + std::to_string(last) + "/residuals");
    if (res.status != 503) break;
    sleepMs(50);
  }
  ASSERT_EQ(res.status, 200) << res.body;
  const json body = res.j();
  const json& out = body["outputs"][0];
  for (const char* metric : {"rmse", "mae", "mean_rel"}) {
    const double want = f["members"][last]["outputs"][0]["float32"][metric].get<double>();
    EXPECT_NEAR(out[metric].get<double>(), want, 1e-4 * std::max(1e-3, want)) << metric;
  }
}

TEST_F(ApiTest, CancelKeepsFrontAndDeleteRemovesRunningRun) {
  Daemon& d = *daemon_;
  // Budgets large enough that both runs are still going when cancelled.
  std::string a = d.submit(runConfig(table_, 1000000, 32, 1));
  std::string b = d.submit(runConfig(table_, 1000000, 32, 2));
  ASSERT_FALSE(a.empty());
  ASSERT_FALSE(b.empty());
  // One job slot: b waits in the queue while a runs, and the API answers meanwhile.
  json ra = d.waitFor(a, [](const json& r) {
    return r.value("status", "") == "running" && r.value("front_size", 0) > 0;
  });
  ASSERT_EQ(ra.value("status", ""), "running") << ra.dump() << d.log();
  EXPECT_EQ(d.get("/api/v1/runs/" + b).j().value("status", ""), "queued");
  ASSERT_EQ(d.get("/api/v1/runs").status, 200);

  // Cancelling the queued run needs no search.
  Reply cb = d.post("/api/v1/runs/" + b + "/cancel", "");
  ASSERT_EQ(cb.status, 200) << cb.body;
  EXPECT_EQ(cb.j().value("status", ""), "cancelled");

  Reply ca = d.post("/api/v1/runs/" + a + "/cancel", "");
  ASSERT_EQ(ca.status, 200) << ca.body;
  json done = d.waitDone(a);
  EXPECT_EQ(done.value("status", ""), "cancelled") << done.dump();
  EXPECT_EQ(done.value("stop_reason", ""), "stopped");
  Reply front = d.get("/api/v1/runs/" + a + "/front");
  ASSERT_EQ(front.status, 200) << "a cancelled run keeps its front";
  EXPECT_GT(front.j()["members"].size(), 0u);
  EXPECT_TRUE(front.j()["lgpd"]["final"].get<bool>());
  EXPECT_EQ(d.post("/api/v1/runs/" + a + "/cancel", "").status, 409);

  // Delete while running.
  std::string c = d.submit(runConfig(table_, 1000000, 32, 3));
  json rc = d.waitFor(c, [](const json& r) { return r.value("status", "") == "running"; });
  ASSERT_EQ(rc.value("status", ""), "running");
  EXPECT_EQ(d.del("/api/v1/runs/" + c).status, 200);
  EXPECT_EQ(d.get("/api/v1/runs/" + c).status, 404);
  // The slot frees up: a new run starts and finishes.
  std::string e = d.submit(runConfig(table_, 3));
  EXPECT_EQ(d.waitDone(e).value("status", ""), "finished");
  EXPECT_EQ(d.get("/api/v1/runs/" + c).status, 404) << "a deleted run never comes back";
}

TEST_F(ApiTest, BadInputGets4xxAndNeverACrash) {
  Daemon& d = *daemon_;
  auto expectError = [&](const Reply& r, int status, const std::string& what) {
    EXPECT_EQ(r.status, status) << what << ": " << r.body;
    json j = r.j();
    EXPECT_TRUE(j.is_object() && j.contains("error")) << what << ": " << r.body;
    return j;
  };
  // Malformed JSON.
  expectError(d.post("/api/v1/runs", "{\"data\": {"), 400, "malformed JSON");
  expectError(d.post("/api/v1/runs", ""), 400, "empty body");
  expectError(d.post("/api/v1/runs", "[1, 2]"), 400, "not an object");
  // A wrong field type names the field.
  json bad = runConfig(table_, 5);
  bad["search"]["population"] = "many";
  json j = expectError(d.post("/api/v1/runs", bad.dump()), 400, "wrong type");
  EXPECT_EQ(j.value("field", ""), "/search/population") << j.dump();
  bad = runConfig(table_, 5);
  bad["search"]["population"] = 2;
  j = expectError(d.post("/api/v1/runs", bad.dump()), 400, "out of range");
  EXPECT_EQ(j.value("field", ""), "/search/population") << j.dump();
  bad = runConfig(table_, 5);
  bad["search"]["popsize"] = 10;
  expectError(d.post("/api/v1/runs", bad.dump()), 400, "unknown key");
  bad = runConfig(table_, 5);
  bad["name"] = 42;
  j = expectError(d.post("/api/v1/runs", bad.dump()), 400, "name type");
  EXPECT_EQ(j.value("field", ""), "/name");
  bad = runConfig(tmp_->path() / "no-such-table.csv", 5);
  expectError(d.post("/api/v1/runs", bad.dump()), 400, "missing data file");
  bad = runConfig(table_, 5);
  bad["data"]["outputs"] = {"nope"};
  expectError(d.post("/api/v1/runs", bad.dump()), 400, "unknown column");

  // Oversized body (the daemon was started with max_body_bytes = 65536).
  std::string big = "{\"name\": \"" + std::string(200000, 'x') + "\"}";
  Reply over = d.post("/api/v1/runs", big);
  EXPECT_EQ(over.status, 413) << over.body;

  // Unknown and malformed ids.
  expectError(d.get("/api/v1/runs/0123456789abcdef"), 404, "unknown run");
  expectError(d.get("/api/v1/runs/0123456789abcdef/front"), 404, "unknown run front");
  expectError(d.post("/api/v1/runs/0123456789abcdef/cancel", ""), 404, "unknown run cancel");
  expectError(d.del("/api/v1/runs/0123456789abcdef"), 404, "unknown run delete");
  for (const char* path :
       {"/api/v1/runs/..%2F..%2Fetc%2Fpasswd", "/api/v1/runs/..", "/api/v1/runs/%2e%2e",
        "/api/v1/runs/abc", "/api/v1/runs/0123456789ABCDEF", "/api/v1/runs/1'%20OR%20'1'='1",
        "/api/v1/runs/..%2f/front", "/api/v1/runs/0123456789abcdef0"}) {
    Reply r = d.get(path);
    EXPECT_GE(r.status, 400) << path;
    EXPECT_LT(r.status, 500) << path;
  }
  EXPECT_EQ(d.get("/api/v1/runs/..%2F..%2Fetc%2Fpasswd").status, 400);
  EXPECT_EQ(d.del("/api/v1/runs/..%2F..").status, 400);
  // A raw "../" in the request target (no client-side normalisation).
  {
    httplib::Client c("127.0.0.1", d.port());
    auto r = c.Get("/api/v1/runs/../../../etc/passwd");
    ASSERT_TRUE(r);
    EXPECT_GE(r->status, 400);
    EXPECT_LT(r->status, 500);
    EXPECT_EQ(r->body.find("root:"), std::string::npos);
  }
  expectError(d.get("/api/v1/runs/0123456789abcdef/front/x/code"), 400, "bad member index");
  expectError(d.get("/api/v1/nope"), 404, "unknown route");
  expectError(d.request("DELETE", "/api/v1/runs"), 405, "wrong method");

  // Still alive and consistent: nothing was stored by any of the above.
  EXPECT_TRUE(d.alive());
  EXPECT_EQ(d.get("/api/v1/health").status, 200);
  EXPECT_EQ(d.get("/api/v1/runs").j()["runs"].size(), 0u);
}

// lgpd took search.exhaustive, never ran it, and the front had no certificate (hardening round
// 3, F12): it is refused, naming the field and where to run it.
TEST_F(ApiTest, ExhaustiveEnumerationIsRefusedNotIgnored) {
  Daemon& d = *daemon_;
  json cfg = runConfig(table_, 3);
  cfg["search"]["exhaustive"] = {{"max_ops", 2}};
  Reply r;
  EXPECT_TRUE(d.submit(cfg, &r).empty());
  EXPECT_EQ(r.status, 400) << r.body;
  EXPECT_EQ(r.j().value("field", ""), "/search/exhaustive") << r.body;
  EXPECT_NE(r.body.find("lgp run"), std::string::npos) << r.body;
  cfg["search"]["exhaustive"]["max_ops"] = 0;  // off: an ordinary run
  EXPECT_FALSE(d.submit(cfg, &r).empty()) << r.body;
}

TEST_F(ApiTest, InlineTableAndPage) {
  Daemon& d = *daemon_;
  json table = {{"format", "lgp-table/1"},
                {"inputs", {"x"}},
                {"outputs", {"y"}},
                {"columns", {{"x", json::array()}, {"y", json::array()}}}};
  for (int i = 0; i < 64; ++i) {
    double x = i / 63.0;
    table["columns"]["x"].push_back(x);
    table["columns"]["y"].push_back(x * x + 0.25);
  }
  json cfg = {{"data", {{"table", table}}},
              {"search", {{"population", 24}, {"generations", 5}, {"threads", 1}}}};
  std::string id = d.submit(cfg);
  ASSERT_FALSE(id.empty());
  EXPECT_EQ(d.waitDone(id).value("status", ""), "finished") << d.log();
  EXPECT_EQ(d.get("/api/v1/runs/" + id + "/front").status, 200);

  Reply page = d.get("/");
  EXPECT_EQ(page.status, 200);
  EXPECT_NE(page.body.find("id=\"pareto\""), std::string::npos);
  Reply script = d.get("/app.js");
  EXPECT_EQ(script.status, 200);
  // Self-contained: no external script, stylesheet, font, image or fetch; its one script is
  // lgpd's own /app.js. (The only URL in either is the SVG namespace, which is an
  // identifier, not a resource.)
  for (std::string body : {page.body, script.body}) {
    for (size_t p = 0; (p = body.find("http://www.w3.org/2000/svg", p)) != std::string::npos;)
      body.erase(p, 26);
    EXPECT_EQ(body.find("http://"), std::string::npos);
    EXPECT_EQ(body.find("https://"), std::string::npos);
    EXPECT_EQ(body.find("//cdn"), std::string::npos);
    EXPECT_EQ(body.find("<link"), std::string::npos);
    EXPECT_EQ(body.find("@import"), std::string::npos);
    EXPECT_EQ(body.find("@font-face"), std::string::npos);
  }
  size_t scripts = 0;
  for (size_t p = 0; (p = page.body.find("<script", p)) != std::string::npos; ++p) ++scripts;
  EXPECT_EQ(scripts, 1u);
  EXPECT_NE(page.body.find("<script src=\"/app.js\"></script>"), std::string::npos);
}

TEST(ApiAuth, NonLoopbackNeedsTokenAndTokenIsEnforced) {
  TempDir tmp("auth");
  {
    std::string out;
    int code =
        runProgram({LGPD_BIN, "--data-dir", (tmp.path() / "a").string(), "--listen", "0.0.0.0:0"},
                   &out, tmp.path() / "a.log", 30);
    EXPECT_EQ(code, 2) << "a non-loopback bind without a token must be refused";
  }
  fs::path cfg = tmp.path() / "lgpd.json";
  const std::string token = "0123456789abcdef-test-token";
  std::ofstream(cfg) << json{{"token", token}}.dump();
  Daemon d(tmp.path() / "b");
  ASSERT_TRUE(d.start({"--config", cfg.string()}));
  // /api/v1/health is open (start() polls it); everything else needs the token.
  EXPECT_EQ(d.get("/api/v1/runs").status, 401);
  EXPECT_EQ(d.request("GET", "/api/v1/runs", "", {{"Authorization", "Bearer wrong"}}).status, 401);
  EXPECT_EQ(d.get("/").status, 200) << "the static page asks for the token itself";
  d.setToken(token);
  EXPECT_EQ(d.get("/api/v1/runs").status, 200);
  EXPECT_EQ(d.stop(), 0);
}

TEST_F(ApiTest, CliSubmitStatusAndFront) {
  Daemon& d = *daemon_;
  // The config names its table relative to itself, as `lgp run` would read it.
  fs::path cfg_path = tmp_->path() / "cfg.json";
  json cfg = runConfig("table.csv", 5);
  std::ofstream(cfg_path) << cfg.dump(2);
  const fs::path log = tmp_->path() / "cli.log";
  std::string out;
  int code = runProgram({LGP_CLI_BIN, "submit", cfg_path.string(), "--daemon", d.url(), "--name",
                         "from cli", "--wait"},
                        &out, log, 120);
  ASSERT_EQ(code, 0) << out;
  std::string id = out.substr(0, out.find('\n'));
  ASSERT_EQ(id.size(), 16u) << out;
  EXPECT_EQ(d.get("/api/v1/runs/" + id).j().value("status", ""), "finished");

  code = runProgram({LGP_CLI_BIN, "status", "--daemon", d.url()}, &out, log, 60);
  EXPECT_EQ(code, 0);
  EXPECT_NE(out.find(id), std::string::npos) << out;
  EXPECT_NE(out.find("from cli"), std::string::npos) << out;
  // The URL can also come from the environment.
  code = runProgram({LGP_CLI_BIN, "status", id}, &out, log, 60, {"LGP_DAEMON=" + d.url()});
  EXPECT_EQ(code, 0);
  EXPECT_NE(out.find("finished"), std::string::npos) << out;
  code =
      runProgram({LGP_CLI_BIN, "status", "0123456789abcdef", "--daemon", d.url()}, &out, log, 60);
  EXPECT_EQ(code, 1) << "unknown run";
  // A bad config is reported with its field, and nothing is queued.
  cfg["search"]["population"] = "x";
  std::ofstream(cfg_path) << cfg.dump(2);
  code = runProgram({LGP_CLI_BIN, "submit", cfg_path.string(), "--daemon", d.url()}, &out, log, 60);
  EXPECT_EQ(code, 1);
  EXPECT_EQ(d.get("/api/v1/runs").j()["runs"].size(), 1u);
  // Unreachable daemon: a clear error, exit 1.
  code = runProgram({LGP_CLI_BIN, "status", "--daemon", "http://127.0.0.1:1"}, &out, log, 60);
  EXPECT_EQ(code, 1);
}

// Paths in lgpd's --config file are relative to that file, like a run config's; lgpd's working
// directory (the test's) holds no "tables" folder, so a cwd-relative data_base_dir would refuse
// the submission's relative table path.
TEST(DaemonConfigPaths, RelativeToTheConfigFile) {
  TempDir tmp("cfg-paths");
  fs::create_directories(tmp.path() / "conf" / "tables");
  writeGridTable(tmp.path() / "conf" / "tables");
  ASSERT_FALSE(fs::exists(fs::current_path() / "tables" / "table.csv"));
  fs::path cfg = tmp.path() / "conf" / "lgpd.json";
  std::ofstream(cfg) << json{{"data_base_dir", "tables"}}.dump();
  Daemon d(tmp.path() / "state");
  ASSERT_TRUE(d.start({"--config", cfg.string()}));
  Reply r;
  const std::string id = d.submit(runConfig("table.csv", 3), &r);
  EXPECT_FALSE(id.empty()) << r.status << " " << r.body;
  if (!id.empty()) {
    EXPECT_EQ(d.waitDone(id).value("status", ""), "finished") << d.log();
  }
  EXPECT_EQ(d.stop(), 0) << d.log();
}

}  // namespace
}  // namespace lgpd_test
