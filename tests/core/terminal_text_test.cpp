// Text from files on its way to a terminal (hardening round 3, F5): `lgp front` printed a
// front's cost_model, error_metric and an undecodable member's names raw, and `lgp emit`
// quoted an unknown operator's name raw in its error, so a front could set the window title,
// clear the screen, write the clipboard (OSC 52) or plant a hyperlink. Every such text is
// printed escaped (io/terminal_text.hpp).
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "../shell.hpp"
#include "../terminal_sequences.hpp"
#include "lgp/io/terminal_text.hpp"

namespace {

namespace fs = std::filesystem;
using lgp_test::sh;

using lgp_test::actsOnTerminal;
using lgp_test::kClear;
using lgp_test::kClipboard;
using lgp_test::kCsi;
using lgp_test::kLink;
using lgp_test::kTitle;

TEST(TerminalText, ControlsAreEscapedAndLettersKept) {
  EXPECT_EQ(lgp::terminalSafe("mu r_2 \xc2\xb5 \xe2\x88\x9a"), "mu r_2 \xc2\xb5 \xe2\x88\x9a");
  EXPECT_EQ(lgp::terminalSafe(kTitle), "\\x1B]0;pwned\\x07");
  EXPECT_EQ(lgp::terminalSafe("a\nb\tc\x7f"), "a\\x0Ab\\x09c\\x7F");
  EXPECT_EQ(lgp::terminalSafe(kCsi), "\\u009B31m");
  // Bytes that are not UTF-8: a lone C1 byte, a truncated sequence, an overlong NUL.
  EXPECT_EQ(lgp::terminalSafe("\x9b"
                              "1m"),
            "\\x9B1m");
  EXPECT_EQ(lgp::terminalSafe("x\xe2\x88"), "x\\xE2\\x88");
  EXPECT_EQ(lgp::terminalSafe("\xc0\x80"), "\\xC0\\x80");
  for (const auto& s : {kTitle, kClear, kClipboard, kLink, kCsi})
    EXPECT_FALSE(actsOnTerminal(lgp::terminalSafe(s))) << s;
  // JSON for a terminal: the same value, nothing a terminal acts on.
  const nlohmann::json j = {{"name", kTitle + kCsi}};
  EXPECT_FALSE(actsOnTerminal(lgp::terminalJson(j)));
  EXPECT_EQ(nlohmann::json::parse(lgp::terminalJson(j)), j);
}

class TerminalCli : public ::testing::Test {
 protected:
  fs::path dir = fs::temp_directory_path() / ("lgp_terminal_" + std::to_string(getpid()));
  void SetUp() override {
    fs::create_directories(dir);
    {
      std::ofstream csv(dir / "t.csv");
      csv << "x,y,f\n";
      for (int i = 0; i < 8; ++i)
        for (int j = 0; j < 8; ++j) csv << i / 8.0 << "," << j / 8.0 << "," << i * j / 64.0 << "\n";
    }
    const nlohmann::json cfg = {
        {"data", {{"path", "t.csv"}, {"inputs", {"x", "y"}}, {"outputs", {"f"}}}},
        {"search", {{"population", 24}, {"generations", 3}, {"threads", 1}}},
        {"output", {{"front_json", "front.json"}, {"front_csv", ""}}}};
    std::ofstream(dir / "c.json") << cfg.dump();
    const auto run = sh(lgp() + " run " + (dir / "c.json").string() + " -q");
    ASSERT_EQ(run.code, 0) << run.out;
    std::ifstream in(dir / "front.json");
    front = nlohmann::json::parse(in);
  }
  void TearDown() override { fs::remove_all(dir); }
  std::string lgp() const { return std::string(LGP_CLI_PATH); }
  fs::path write(const nlohmann::json& j) const {
    std::ofstream(dir / "hostile.json") << j.dump();
    return dir / "hostile.json";
  }
  nlohmann::json front;
};

TEST_F(TerminalCli, FrontPrintsHostileTextAsText) {
  nlohmann::json j = front;
  j["cost_model"] = kTitle + "gpu";
  j["error_metric"] = kClear + kClipboard;
  j["cost_measured_info"] = {{"families", {kLink}}};
  // A member whose program does not decode: its stored names and expression are shown.
  j["members"][0]["program"]["code"][0][0] = "nope";
  j["members"][0]["outputs"][0]["name"] = kCsi + "f";
  j["members"][0]["outputs"][0]["expression"] = kTitle + "x*y";
  const auto r = sh(lgp() + " front " + write(j).string());
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_FALSE(actsOnTerminal(r.out)) << r.out;
  EXPECT_NE(r.out.find("cost model \\x1B]0;pwned\\x07gpu"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("\\x1B]0;pwned\\x07x*y"), std::string::npos) << r.out;
  const auto as_json = sh(lgp() + " front --json " + write(j).string());
  ASSERT_EQ(as_json.code, 0) << as_json.out;
  EXPECT_FALSE(actsOnTerminal(as_json.out));
}

TEST_F(TerminalCli, EmitQuotesAnUnknownOperatorAsText) {
  nlohmann::json j = front;
  for (auto& m : j["members"]) m["program"]["code"][0][0] = kTitle + kClipboard + "op";
  const auto r = sh(lgp() + " emit " + write(j).string() + " --member 0 --no-measure");
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("unknown operator"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("\\x1B]0;pwned\\x07"), std::string::npos) << r.out;
  EXPECT_FALSE(actsOnTerminal(r.out)) << r.out;
}

}  // namespace
