// lgpd against a hostile page in a browser on the same machine (issue 21): DNS rebinding (a
// Host naming another site), cross-site POST and DELETE (a foreign Origin), and the requests a
// page can send without a preflight (no Content-Type, text/plain, an empty-body POST). Every
// case is sent byte for byte on a raw socket, so the headers are exactly the ones given.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>

#include <map>
#include <regex>

#include "daemon_harness.hpp"

namespace lgpd_test {
namespace {

struct RawReply {
  int status = 0;
  std::string headers;
  std::string body;
  json j() const { return json::parse(body, nullptr, false); }
};

// One request on a fresh loopback connection (Connection: close is added); the response.
RawReply raw(int port, const std::string& method, const std::string& path,
             const std::vector<std::string>& headers, const std::string& body = "") {
  std::string req = method + " " + path + " HTTP/1.1\r\n";
  for (const auto& h : headers) req += h + "\r\n";
  if (method == "POST" || !body.empty())
    req += "Content-Length: " + std::to_string(body.size()) + "\r\n";
  req += "Connection: close\r\n\r\n" + body;
  int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(static_cast<uint16_t>(port));
  ::inet_pton(AF_INET, "127.0.0.1", &to.sin_addr);
  if (fd < 0 || ::connect(fd, reinterpret_cast<sockaddr*>(&to), sizeof to) != 0) {
    if (fd >= 0) ::close(fd);
    return {};
  }
  ::send(fd, req.data(), req.size(), MSG_NOSIGNAL);
  std::string out;
  char buf[8192];
  for (;;) {
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 10000) <= 0) break;
    ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n <= 0) break;
    out.append(buf, static_cast<size_t>(n));
  }
  ::close(fd);
  RawReply r;
  std::smatch m;
  if (std::regex_search(out, m, std::regex("^HTTP/1\\.[01] (\\d{3})"))) r.status = std::stoi(m[1]);
  const auto split = out.find("\r\n\r\n");
  r.headers = out.substr(0, split);
  if (split != std::string::npos) r.body = out.substr(split + 4);
  return r;
}

class CrossSite : public ::testing::Test {
 protected:
  void SetUp() override {
    tmp_.emplace("cross-site");
    table_ = writeGridTable(tmp_->path());
    fs::path cfg = tmp_->path() / "lgpd.json";
    std::ofstream(cfg) << json{{"allowed_hosts", {"lgp.test"}},
                               {"allowed_origins", {"https://ui.lgp.test"}}}
                              .dump();
    daemon_.emplace(tmp_->path() / "state");
    ASSERT_TRUE(daemon_->start({"--config", cfg.string()}));
    host_ = "Host: 127.0.0.1:" + std::to_string(daemon_->port());
    self_ = "Origin: http://127.0.0.1:" + std::to_string(daemon_->port());
    // A long run, so that it can still be cancelled at the end.
    id_ = daemon_->submit(runConfig(table_, 1000000));
    ASSERT_FALSE(id_.empty());
  }
  void TearDown() override {
    if (daemon_) {
      EXPECT_EQ(daemon_->stop(), 0) << daemon_->log();
    }
  }
  RawReply send(const std::string& method, const std::string& path,
                const std::vector<std::string>& headers, const std::string& body = "") const {
    return raw(daemon_->port(), method, path, headers, body);
  }
  size_t runCount() const { return daemon_->get("/api/v1/runs").j()["runs"].size(); }
  std::string config() const { return runConfig(table_, 5).dump(); }

  std::optional<TempDir> tmp_;
  std::optional<Daemon> daemon_;
  fs::path table_;
  std::string host_, self_, id_;
};

TEST_F(CrossSite, OnlyHostsThatNameTheDaemonAreAnswered) {
  const std::string port = std::to_string(daemon_->port());
  for (const std::string& h :
       std::vector<std::string>{"127.0.0.1", "127.0.0.1:" + port, "localhost", "LocalHost:" + port,
                                "[::1]", "[::1]:" + port, "lgp.test:" + port})
    EXPECT_EQ(send("GET", "/api/v1/runs", {"Host: " + h}).status, 200) << h;
  // A rebinding page sends its own name: no read, no delete, not even the page or health.
  for (const std::string& h :
       std::vector<std::string>{"evil.example", "evil.example:" + port, "127.0.0.1.evil.example",
                                "localhost.evil.example:" + port, "[::2]:" + port, "lgp.test.",
                                "evil.example:" + port + "/x"}) {
    for (const char* path : {"/api/v1/runs", "/api/v1/health", "/"}) {
      RawReply r = send("GET", path, {"Host: " + h});
      EXPECT_EQ(r.status, 403) << h << " " << path << ": " << r.body;
    }
    RawReply r = send("GET", "/api/v1/runs", {"Host: " + h, "Origin: http://" + h});
    EXPECT_EQ(r.status, 403) << h;
    EXPECT_EQ(r.body.find(id_), std::string::npos) << "a foreign Host read the runs: " << r.body;
    if (h.find('/') == std::string::npos) {
      EXPECT_NE(r.j().value("error", "").find("Host header '" + h + "'"), std::string::npos)
          << r.body;
    }
    r = send("DELETE", "/api/v1/runs/" + id_, {"Host: " + h, "Origin: http://" + h});
    EXPECT_EQ(r.status, 403) << h;
  }
  // No Host, or two.
  EXPECT_EQ(send("GET", "/api/v1/runs", {}).status, 400);
  EXPECT_EQ(send("GET", "/api/v1/runs", {host_, "Host: evil.example"}).status, 400);
  EXPECT_EQ(daemon_->get("/api/v1/runs/" + id_).status, 200) << "the run was deleted";
}

TEST_F(CrossSite, ForeignOriginsCannotChangeRuns) {
  const std::string port = std::to_string(daemon_->port());
  const std::string json_type = "Content-Type: application/json";
  for (const std::string& origin : std::vector<std::string>{
           "http://evil.example", "null", "http://127.0.0.1:1", "http://127.0.0.1",
           "http://localhost:" + port, "http://lgp.test", "https://ui.lgp.test:8443", "garbage"}) {
    const std::string o = "Origin: " + origin;
    EXPECT_EQ(send("POST", "/api/v1/runs", {host_, o, json_type}, config()).status, 403) << o;
    EXPECT_EQ(send("POST", "/api/v1/runs/" + id_ + "/cancel", {host_, o, json_type}).status, 403)
        << o;
    RawReply r = send("DELETE", "/api/v1/runs/" + id_, {host_, o});
    EXPECT_EQ(r.status, 403) << o;
    EXPECT_NE(r.j().value("error", "").find("Origin '" + origin + "'"), std::string::npos)
        << r.body;
    // Reads carry no CORS grant, so the browser keeps the answer from the page.
    r = send("GET", "/api/v1/runs", {host_, o});
    EXPECT_EQ(r.status, 200) << o;
    EXPECT_EQ(r.headers.find("Access-Control-Allow"), std::string::npos) << r.headers;
  }
  EXPECT_EQ(runCount(), 1u);
  EXPECT_FALSE(daemon_->get("/api/v1/runs/" + id_).j().value("cancel_requested", true));
  // The daemon's own origin (the inspection page), a listed one, and none (curl) are accepted.
  EXPECT_EQ(send("POST", "/api/v1/runs", {host_, self_, json_type}, config()).status, 201);
  EXPECT_EQ(
      send("POST", "/api/v1/runs",
           {"Host: localhost:" + port, "Origin: http://LOCALHOST:" + port, json_type}, config())
          .status,
      201);
  EXPECT_EQ(
      send("POST", "/api/v1/runs", {host_, "Origin: https://ui.lgp.test", json_type}, config())
          .status,
      201);
  EXPECT_EQ(send("POST", "/api/v1/runs", {host_, json_type}, config()).status, 201);
  EXPECT_EQ(runCount(), 5u);
}

TEST_F(CrossSite, PostsWithoutAJsonTypeGet415) {
  // What a no-cors fetch can send: a Blob body with no type, text/plain, a form; and an
  // empty-body POST to cancel with no type or text/plain.
  for (const std::vector<std::string>& type : {std::vector<std::string>{},
                                               {"Content-Type: text/plain"},
                                               {"Content-Type: application/x-www-form-urlencoded"},
                                               {"Content-Type: "}}) {
    const std::string what = type.empty() ? "no Content-Type" : type[0];
    auto headers = type;
    headers.push_back(host_);
    RawReply r = send("POST", "/api/v1/runs", headers, config());
    EXPECT_EQ(r.status, 415) << what << ": " << r.body;
    r = send("POST", "/api/v1/runs/" + id_ + "/cancel", headers);
    EXPECT_EQ(r.status, 415) << what << ": " << r.body;
    headers.push_back(self_);
    EXPECT_EQ(send("POST", "/api/v1/runs/" + id_ + "/cancel", headers).status, 415) << what;
  }
  EXPECT_EQ(runCount(), 1u);
  EXPECT_FALSE(daemon_->get("/api/v1/runs/" + id_).j().value("cancel_requested", true));
  RawReply r =
      send("POST", "/api/v1/runs/" + id_ + "/cancel", {host_, "Content-Type: application/json"});
  EXPECT_EQ(r.status, 200) << r.body;
}

// A page on another site must not frame the inspection page (and lure clicks onto its
// buttons), and an injected inline script must not run in it (hardening round 3, F9).
TEST_F(CrossSite, ThePageCannotBeFramedAndRunsNoInlineScript) {
  const RawReply page = send("GET", "/", {host_});
  ASSERT_EQ(page.status, 200);
  std::smatch m;
  ASSERT_TRUE(std::regex_search(
      page.headers, m, std::regex("\r\nContent-Security-Policy: ([^\r]*)", std::regex::icase)))
      << page.headers;
  // The policy's directives, by name.
  std::map<std::string, std::string> policy;
  const std::string csp = m[1];
  for (size_t a = 0; a < csp.size();) {
    size_t b = std::min(csp.find(';', a), csp.size());
    std::string d = csp.substr(a, b - a);
    d.erase(0, d.find_first_not_of(' '));
    policy[d.substr(0, d.find(' '))] = d;
    a = b + 1;
  }
  EXPECT_EQ(policy["frame-ancestors"], "frame-ancestors 'none'") << csp;
  EXPECT_EQ(policy["script-src"], "script-src 'self'") << csp;
  // Every answer, the API's too, refuses to be framed by browsers that predate CSP 2.
  for (const char* path : {"/", "/app.js", "/api/v1/runs", "/api/v1/health"}) {
    const RawReply r = send("GET", path, {host_});
    EXPECT_TRUE(
        std::regex_search(r.headers, std::regex("\r\nX-Frame-Options: DENY\r?", std::regex::icase)))
        << path << ":\n"
        << r.headers;
  }
  // The page's script is lgpd's own file, and it asks before it cancels a run (as it does
  // before a delete): the POST comes after window.confirm in the cancel button's handler.
  const RawReply js = send("GET", "/app.js", {host_});
  ASSERT_EQ(js.status, 200);
  EXPECT_NE(js.headers.find("text/javascript"), std::string::npos) << js.headers;
  const size_t handler = js.body.find("title: \"cancel: stop and keep the front\"");
  ASSERT_NE(handler, std::string::npos);
  const size_t ask = js.body.find("window.confirm(", handler);
  const size_t post = js.body.find("/cancel\"", handler);
  ASSERT_NE(ask, std::string::npos);
  ASSERT_NE(post, std::string::npos);
  EXPECT_LT(ask, post) << js.body.substr(handler, 600);
  EXPECT_NE(js.body.substr(ask, post - ask).find("return"), std::string::npos)
      << js.body.substr(handler, 600);
}

TEST(CrossSiteConfig, AllowedHostsAndOriginsAreValidated) {
  TempDir tmp("cross-site-config");
  for (const json& bad :
       {json{{"allowed_hosts", {"evil.example:80"}}}, json{{"allowed_hosts", {"Upper.Case"}}},
        json{{"allowed_hosts", {"a b"}}}, json{{"allowed_hosts", "x"}},
        json{{"allowed_origins", {"evil.example"}}}, json{{"allowed_origins", {"http://x/path"}}},
        json{{"allowed_origins", {"ftp://x"}}}}) {
    fs::path cfg = tmp.path() / "lgpd.json";
    std::ofstream(cfg) << bad.dump();
    std::string out;
    const fs::path log = tmp.path() / "cfg.log";
    std::error_code ec;
    fs::remove(log, ec);
    EXPECT_EQ(runProgram({LGPD_BIN, "--data-dir", (tmp.path() / "s").string(), "--config",
                          cfg.string(), "--listen", "127.0.0.1:0"},
                         &out, log, 30),
              2)
        << bad.dump();
    std::ifstream f(log);
    std::string err((std::istreambuf_iterator<char>(f)), {});
    EXPECT_NE(err.find(bad.begin().key()), std::string::npos) << err;
  }
}

TEST(CrossSiteAuth, BearerSchemeIsCaseInsensitive) {
  TempDir tmp("cross-site-auth");
  const std::string token = "0123456789abcdef-token";
  fs::path cfg = tmp.path() / "lgpd.json";
  std::ofstream(cfg) << json{{"token", token}}.dump();
  Daemon d(tmp.path() / "state");
  ASSERT_TRUE(d.start({"--config", cfg.string()}));
  const std::string host = "Host: 127.0.0.1:" + std::to_string(d.port());
  for (const std::string& auth :
       std::vector<std::string>{"Bearer " + token, "bearer " + token, "BEARER " + token,
                                "bEaReR   " + token, "Bearer " + token + " "})
    EXPECT_EQ(raw(d.port(), "GET", "/api/v1/runs", {host, "Authorization: " + auth}).status, 200)
        << auth;
  for (const std::string& auth :
       std::vector<std::string>{"Bearer", "Bearer " + token + "x", "Bearer" + token,
                                "Basic " + token, "Bearerx " + token, "bearer"})
    EXPECT_EQ(raw(d.port(), "GET", "/api/v1/runs", {host, "Authorization: " + auth}).status, 401)
        << auth;
  EXPECT_EQ(raw(d.port(), "GET", "/api/v1/runs", {host}).status, 401);
  EXPECT_EQ(d.stop(), 0);
}

}  // namespace
}  // namespace lgpd_test
