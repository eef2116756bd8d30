// `lgp status`, `lgp front --daemon` and `lgp submit` against a hostile daemon (hardening round
// 3, F5): a server's run ids, names, statuses, stop reasons, errors and front names reached
// the terminal raw (title, clear-screen, OSC 52 clipboard and hyperlink sequences got
// through). Here an in-process HTTP server answers with such text; the CLI prints it escaped.
#include <thread>

#include "../terminal_sequences.hpp"
#include "daemon_harness.hpp"

namespace lgpd_test {
namespace {

using lgp_test::actsOnTerminal;
using lgp_test::kClipboard;
using lgp_test::kCsi;
using lgp_test::kTitle;

class HostileServer : public ::testing::Test {
 protected:
  void SetUp() override {
    const json run = {{"id", "0123456789abcdef" + kTitle},
                      {"name", kClipboard + "night run"},
                      {"status", "failed" + kCsi},
                      {"generation", 3},
                      {"evaluations", 10},
                      {"stop_reason", kTitle + "stopped"},
                      {"error", kClipboard + "boom"},
                      {"best", {{"error", {{"value", 0.1}, {"member", 0}}}}}};
    srv_.Get("/api/v1/runs", [run](const httplib::Request&, httplib::Response& res) {
      res.set_content(json{{"runs", {run}}}.dump(), "application/json");
    });
    srv_.Get(R"(/api/v1/runs/([0-9a-f]+)/front)",
             [](const httplib::Request&, httplib::Response& res) {
               json front = {{"format", "lgp-front/1"},
                             {"table", {{"inputs", {"x"}}, {"outputs", {"f"}}}},
                             {"members", json::array()},
                             {"lgpd", {{"final", true}, {"generation", 3}}}};
               res.set_content(front.dump(), "application/json");
             });
    srv_.Get(R"(/api/v1/runs/([0-9a-f]+))", [run](const httplib::Request&, httplib::Response& res) {
      res.set_content(run.dump(), "application/json");
    });
    srv_.Post("/api/v1/runs", [](const httplib::Request&, httplib::Response& res) {
      res.status = 400;
      res.set_content(json{{"error", kTitle + "refused" + kCsi}}.dump(), "application/json");
    });
    port_ = srv_.bind_to_any_port("127.0.0.1");
    thread_ = std::thread([this] { srv_.listen_after_bind(); });
    for (int i = 0; i < 200 && !srv_.is_running(); ++i) sleepMs(10);
    url_ = "http://127.0.0.1:" + std::to_string(port_);
  }
  void TearDown() override {
    srv_.stop();
    thread_.join();
  }
  // lgp with `args`: exit code, stdout and stderr together.
  int lgp(const std::vector<std::string>& args, std::string* out) {
    TempDir tmp("hostile");
    std::vector<std::string> argv = {LGP_CLI_BIN};
    argv.insert(argv.end(), args.begin(), args.end());
    const int code = runProgram(argv, out, tmp.path() / "err.log", 60);
    std::ifstream err(tmp.path() / "err.log");
    *out += std::string(std::istreambuf_iterator<char>(err), {});
    return code;
  }
  httplib::Server srv_;
  std::thread thread_;
  int port_ = 0;
  std::string url_;
};

TEST_F(HostileServer, StatusPrintsTheServersTextAsText) {
  std::string out;
  EXPECT_EQ(lgp({"status", "--daemon", url_}, &out), 0) << out;
  EXPECT_FALSE(actsOnTerminal(out)) << out;
  EXPECT_NE(out.find("\\x1B]52;c;ZWNobyBwd25lZA==\\x07night run"), std::string::npos) << out;
  EXPECT_EQ(lgp({"status", "0123456789abcdef", "--daemon", url_}, &out), 0) << out;
  EXPECT_FALSE(actsOnTerminal(out)) << out;
  EXPECT_NE(out.find("failed\\u009B31m"), std::string::npos) << out;
  EXPECT_NE(out.find("\\x1B]0;pwned\\x07stopped"), std::string::npos) << out;
  EXPECT_EQ(lgp({"status", "--json", "--daemon", url_}, &out), 0) << out;
  EXPECT_FALSE(actsOnTerminal(out)) << out;
}

TEST_F(HostileServer, FrontAndSubmitPrintTheServersTextAsText) {
  std::string out;
  EXPECT_EQ(lgp({"front", "0123456789abcdef", "--daemon", url_}, &out), 0) << out;
  EXPECT_FALSE(actsOnTerminal(out)) << out;
  TempDir tmp("hostile-submit");
  const fs::path cfg = tmp.path() / "c.json";
  std::ofstream(cfg) << runConfig(writeGridTable(tmp.path()), 3).dump();
  EXPECT_EQ(lgp({"submit", cfg.string(), "--daemon", url_}, &out), 1) << out;
  EXPECT_NE(out.find("\\x1B]0;pwned\\x07refused\\u009B31m"), std::string::npos) << out;
  EXPECT_FALSE(actsOnTerminal(out)) << out;
}

}  // namespace
}  // namespace lgpd_test
