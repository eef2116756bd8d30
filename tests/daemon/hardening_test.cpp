// lgpd against hostile and careless input (issue 10): weak tokens, a deep or
// duplicate-keyed daemon config, and empty, corrupt or missing databases.
#include "daemon_harness.hpp"

namespace lgpd_test {
namespace {

std::string nested(const std::string& open, const std::string& inner, const std::string& close,
                   int depth) {
  std::string s;
  s.reserve((open.size() + close.size()) * depth + inner.size());
  for (int i = 0; i < depth; ++i) s += open;
  s += inner;
  for (int i = 0; i < depth; ++i) s += close;
  return s;
}

TEST(HardeningConfig, TokenNeedsSixteenNonSpaceCharacters) {
  TempDir tmp("token");
  for (const std::string& token :
       {std::string(16, ' '), std::string("short"), std::string(" a b c d e f g h ")}) {
    fs::path cfg = tmp.path() / "lgpd.json";
    std::ofstream(cfg) << json{{"token", token}}.dump();
    std::string out;
    const fs::path log = tmp.path() / "token.log";
    std::error_code ec;
    fs::remove(log, ec);
    int code = runProgram({LGPD_BIN, "--data-dir", (tmp.path() / "s").string(), "--config",
                           cfg.string(), "--listen", "127.0.0.1:0"},
                          &out, log, 30);
    EXPECT_EQ(code, 2) << "token '" << token << "' was accepted";
    std::ifstream f(log);
    std::string err((std::istreambuf_iterator<char>(f)), {});
    EXPECT_NE(err.find("non-space"), std::string::npos) << err;
  }
  // A deep or duplicate-keyed daemon config is refused with the reason, not a crash.
  fs::path deep = tmp.path() / "deep.json";
  std::ofstream(deep) << nested("{\"mpi\":", "{}", "}", 100000);
  std::string out;
  EXPECT_EQ(
      runProgram({LGPD_BIN, "--data-dir", (tmp.path() / "s").string(), "--config", deep.string()},
                 &out, tmp.path() / "deep.log", 30),
      2);
  fs::path dup = tmp.path() / "dup.json";
  std::ofstream(dup) << R"({"max_jobs": 1, "max_jobs": 4})";
  EXPECT_EQ(
      runProgram({LGPD_BIN, "--data-dir", (tmp.path() / "s").string(), "--config", dup.string()},
                 &out, tmp.path() / "dup.log", 30),
      2);
}

TEST(HardeningStore, EmptyOrCorruptDatabaseIsAnErrorUnlessInit) {
  TempDir tmp("db");
  auto startFails = [&](const fs::path& dir, const std::string& want) {
    std::string out;
    const fs::path log = tmp.path() / "db.log";
    std::error_code ec;
    fs::remove(log, ec);
    int code = runProgram({LGPD_BIN, "--data-dir", dir.string(), "--listen", "127.0.0.1:0"}, &out,
                          log, 30);
    std::ifstream f(log);
    std::string err((std::istreambuf_iterator<char>(f)), {});
    EXPECT_EQ(code, 1) << err;
    EXPECT_NE(err.find(want), std::string::npos) << err;
    EXPECT_NE(err.find("--init"), std::string::npos) << err;
  };
  // A 0-byte database.
  fs::path a = tmp.path() / "a";
  fs::create_directories(a);
  std::ofstream(a / "lgpd.sqlite3").close();
  startFails(a, "is empty (0 bytes)");
  // Not SQLite at all.
  fs::path b = tmp.path() / "b";
  fs::create_directories(b);
  std::ofstream(b / "lgpd.sqlite3") << std::string(8192, 'z');
  startFails(b, "not an SQLite database");
  // A data dir lgpd has used, whose database is gone.
  fs::path c = tmp.path() / "c";
  {
    Daemon d(c);
    ASSERT_TRUE(d.start());
    ASSERT_FALSE(d.submit(runConfig(writeGridTable(tmp.path()), 3)).empty());
    EXPECT_EQ(d.stop(), 0);
  }
  for (const char* f : {"lgpd.sqlite3", "lgpd.sqlite3-wal", "lgpd.sqlite3-shm"}) fs::remove(c / f);
  startFails(c, "is missing");
  // --init keeps the bad file aside and starts empty.
  {
    Daemon d(a);
    ASSERT_TRUE(d.start({"--init"})) << d.log();
    EXPECT_EQ(d.get("/api/v1/runs").j()["runs"].size(), 0u);
    EXPECT_EQ(d.stop(), 0);
  }
  bool kept = false;
  for (const auto& e : fs::directory_iterator(a))
    if (e.path().filename().string().rfind("lgpd.sqlite3.broken-", 0) == 0) kept = true;
  EXPECT_TRUE(kept) << "the empty file was not kept aside";
  // The next start needs no --init; a fresh dir needs none either.
  {
    Daemon d(a);
    ASSERT_TRUE(d.start()) << d.log();
    EXPECT_EQ(d.stop(), 0);
  }
}

}  // namespace
}  // namespace lgpd_test
