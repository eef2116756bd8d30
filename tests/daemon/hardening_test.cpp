// lgpd against hostile and careless input (issue 10): slow (slowloris) clients, weak tokens,
// a deep or duplicate-keyed daemon config, and empty, corrupt or missing databases.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>

#include <regex>

#include "daemon_harness.hpp"

namespace lgpd_test {
namespace {

// A TCP connection to 127.0.0.1:port from the local address `src` (any of 127.0.0.0/8 works
// on Linux, so one test can be several clients). -1 on failure.
int connectFrom(const std::string& src, int port) {
  int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return -1;
  sockaddr_in a{};
  a.sin_family = AF_INET;
  ::inet_pton(AF_INET, src.c_str(), &a.sin_addr);
  if (::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
    ::close(fd);
    return -1;
  }
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(static_cast<uint16_t>(port));
  ::inet_pton(AF_INET, "127.0.0.1", &to.sin_addr);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&to), sizeof to) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

bool sendAll(int fd, const std::string& s) {
  size_t off = 0;
  while (off < s.size()) {
    ssize_t n = ::send(fd, s.data() + off, s.size() - off, MSG_NOSIGNAL);
    if (n <= 0) return false;
    off += static_cast<size_t>(n);
  }
  return true;
}

// Reads until the peer closes or `timeout_s` passes.
std::string readAll(int fd, double timeout_s) {
  std::string out;
  auto until = std::chrono::steady_clock::now() + std::chrono::milliseconds(int(timeout_s * 1000));
  char buf[8192];
  for (;;) {
    auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
                    until - std::chrono::steady_clock::now())
                    .count();
    if (left <= 0) break;
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, static_cast<int>(left)) <= 0) break;
    ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n <= 0) break;
    out.append(buf, static_cast<size_t>(n));
  }
  return out;
}

// The status code of a raw HTTP response ("HTTP/1.1 413 ..."), 0 if none.
int statusOf(const std::string& response) {
  std::smatch m;
  if (std::regex_search(response, m, std::regex("^HTTP/1\\.[01] (\\d{3})"))) return std::stoi(m[1]);
  return 0;
}

std::string nested(const std::string& open, const std::string& inner, const std::string& close,
                   int depth) {
  std::string s;
  s.reserve((open.size() + close.size()) * depth + inner.size());
  for (int i = 0; i < depth; ++i) s += open;
  s += inner;
  for (int i = 0; i < depth; ++i) s += close;
  return s;
}

class Hardening : public ::testing::Test {
 protected:
  void SetUp() override {
    tmp_.emplace("hardening");
    table_ = writeGridTable(tmp_->path());
    fs::path cfg = tmp_->path() / "lgpd.json";
    std::ofstream(cfg) << json{{"max_body_bytes", 1 << 20}}.dump();
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
  size_t runCount() const { return daemon_->get("/api/v1/runs").j()["runs"].size(); }
  // A POST of `body` that must be refused with `status`; returns the error JSON.
  json refused(const std::string& body, int status, const std::string& what) {
    Reply r = daemon_->post("/api/v1/runs", body);
    EXPECT_EQ(r.status, status) << what << ": " << r.body.substr(0, 500);
    json j = r.j();
    EXPECT_TRUE(j.is_object() && j.contains("error")) << what << ": " << r.body.substr(0, 500);
    EXPECT_TRUE(daemon_->alive()) << what;
    return j;
  }
  std::optional<TempDir> tmp_;
  std::optional<Daemon> daemon_;
  fs::path table_;
};

// Sockets that each send the start of a request, then one byte a second, from `src`.
class SlowClients {
 public:
  SlowClients(const std::string& src, int port, int n) {
    for (int i = 0; i < n; ++i) {
      int fd = connectFrom(src, port);
      if (fd < 0) continue;
      sendAll(fd, "GET /api/v1/runs HTTP/1.1\r\nHost: x\r\nX-Slow: ");
      fds_.push_back(fd);
    }
    thread_ = std::thread([this] {
      while (!stop_.load()) {
        for (int fd : fds_) (void)!::send(fd, "x", 1, MSG_NOSIGNAL | MSG_DONTWAIT);
        for (int k = 0; k < 10 && !stop_.load(); ++k) sleepMs(100);
      }
    });
  }
  ~SlowClients() {
    stop_.store(true);
    thread_.join();
    for (int fd : fds_) ::close(fd);
  }
  size_t opened() const { return fds_.size(); }

 private:
  std::vector<int> fds_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

TEST_F(Hardening, SlowClientsDoNotStopTheApi) {
  Daemon& d = *daemon_;
  for (int n : {8, 16, 40}) {
    SlowClients slow("127.0.0.2", d.port(), n);
    ASSERT_EQ(slow.opened(), static_cast<size_t>(n));
    sleepMs(300);
    // Another client is served, within a generous bound.
    httplib::Client c("127.0.0.1", d.port());
    c.set_connection_timeout(5);
    c.set_read_timeout(10);
    const auto t0 = std::chrono::steady_clock::now();
    auto res = c.Get("/api/v1/runs");
    ASSERT_TRUE(res) << n << " slow connections: no answer";
    EXPECT_EQ(res->status, 200);
    EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(5)) << n;
  }
  // One address beyond its bound (http_threads / 2 = 8) gets 429 at once.
  SlowClients slow("127.0.0.3", d.port(), 8);
  sleepMs(300);
  int fd = connectFrom("127.0.0.3", d.port());
  ASSERT_GE(fd, 0);
  sendAll(fd, "GET /api/v1/health HTTP/1.1\r\nHost: x\r\n\r\n");
  std::string r = readAll(fd, 5);
  ::close(fd);
  EXPECT_EQ(statusOf(r), 429) << r;
  EXPECT_EQ(d.get("/api/v1/health").status, 200) << "other addresses are still served";
}

TEST(HardeningServe, SlowRequestIsDroppedAtItsDeadline) {
  TempDir tmp("slowreq");
  fs::path cfg = tmp.path() / "lgpd.json";
  std::ofstream(cfg) << json{{"request_timeout_s", 2}, {"read_timeout_s", 1}}.dump();
  Daemon d(tmp.path() / "state");
  ASSERT_TRUE(d.start({"--config", cfg.string()}));
  // One byte every 0.5 s never trips the 1 s read timeout, but the request as a whole has
  // 2 s: the connection is closed within a few seconds.
  int fd = connectFrom("127.0.0.1", d.port());
  ASSERT_GE(fd, 0);
  sendAll(fd, "GET /api/v1/runs HTTP/1.1\r\nHost: x\r\n");
  bool closed = false;
  std::string answer;
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (!closed && std::chrono::steady_clock::now() < until) {
    if (::send(fd, "X", 1, MSG_NOSIGNAL) < 0) closed = true;
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 500) > 0) {
      char buf[512];
      const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
      if (n <= 0)
        closed = true;
      else
        answer.append(buf, static_cast<size_t>(n));
    }
  }
  ::close(fd);
  EXPECT_TRUE(closed) << "a request trickling in for 20 s was still being read";
  EXPECT_TRUE(answer.empty() || statusOf(answer) == 400) << answer;
  EXPECT_EQ(d.stop(), 0);
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
