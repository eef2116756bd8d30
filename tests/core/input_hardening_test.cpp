// Hostile and careless input to tables, result files and `lgp run` (issue 10): every case
// that crashed, stalled or was accepted without a word is refused with a message that names
// the file, field, column or row, and a run never ends with an empty front and exit 0.
#include <gtest/gtest.h>

#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>
#include "../shell.hpp"

#include <cfloat>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "lgp/core/table.hpp"
#include "lgp/eval/objectives.hpp"
#include "lgp/io/result.hpp"

namespace lgp {
namespace {

namespace fs = std::filesystem;

using lgp_test::Result;
using lgp_test::sh;

bool contains(const std::string& s, const std::string& what) {
  return s.find(what) != std::string::npos;
}

class Hardening : public ::testing::Test {
 protected:
  fs::path dir = fs::temp_directory_path() / ("lgp_hardening_" + std::to_string(getpid()));
  void SetUp() override {
    fs::create_directories(dir);
    std::ofstream csv(dir / "t.csv");
    csv << "x,y,f,w\n";
    for (int i = 0; i < 8; ++i)
      for (int j = 0; j < 8; ++j) {
        const double x = (i + 0.5) / 8, y = (j + 0.5) / 8;
        csv << x << "," << y << "," << x * y + 0.5 << ",1\n";
      }
  }
  void TearDown() override { fs::remove_all(dir); }
  fs::path write(const std::string& name, const std::string& text) {
    std::ofstream(dir / name, std::ios::binary) << text;
    return dir / name;
  }
  std::string lgp() const { return std::string(LGP_CLI_PATH); }
  nlohmann::json base() {
    return {{"data", {{"path", "t.csv"}, {"inputs", {"x", "y"}}, {"outputs", {"f"}}}},
            {"search", {{"population", 40}, {"generations", 2}, {"seed", 1}, {"threads", 1}}},
            {"output", {{"front_json", (dir / "front.json").string()}, {"front_csv", ""}}}};
  }
  Result run(const nlohmann::json& cfg) {
    write("c.json", cfg.dump());
    // `timeout`: a case that hangs fails the test instead of stalling the suite.
    return sh("timeout 60 " + lgp() + " run " + (dir / "c.json").string() + " -q");
  }
  Result runWithReference(const std::string& expr) {
    auto cfg = base();
    cfg["references"] = {{{"name", "hostile"}, {"expr", expr}}};
    return run(cfg);
  }
  std::string csvWith(const std::string& f_value, const std::string& w_value = "1") {
    std::string s = "x,y,f,w\n";
    for (int i = 0; i < 4; ++i)
      s += std::to_string(0.1 + 0.2 * i) + ",0.5," + (i == 2 ? f_value : "0.25") + "," +
           (i == 1 ? w_value : "1") + "\n";
    return s;
  }
};

// --- tables ------------------------------------------------------------------------------

TEST_F(Hardening, DirectoryAsDataPathNamesThePath) {
  fs::create_directories(dir / "d.csv");
  auto csv = readTableFile(dir / "d.csv");
  ASSERT_FALSE(csv.hasValue());
  EXPECT_EQ(csv.error(), (dir / "d.csv").string() + ": is a directory");
  fs::create_directories(dir / "d.json");
  auto js = readTableFile(dir / "d.json");
  ASSERT_FALSE(js.hasValue());
  EXPECT_EQ(js.error(), (dir / "d.json").string() + ": is a directory");
  auto cfg = base();
  cfg["data"]["path"] = "d.json";
  const auto r = run(cfg);
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_TRUE(contains(r.out, (dir / "d.json").string() + ": is a directory")) << r.out;
  EXPECT_FALSE(contains(r.out, "underflow")) << r.out;
}

TEST_F(Hardening, FifoAsDataPathIsRefusedWithoutBlocking) {
  const fs::path fifo = dir / "f.csv";
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  auto t = readTableFile(fifo);  // no writer: a blocking open would never return
  ASSERT_FALSE(t.hasValue());
  EXPECT_EQ(t.error(),
            fifo.string() + ": not a regular file (a FIFO, socket or device is not read)");
  auto cfg = base();
  cfg["data"]["path"] = "f.csv";
  const auto r = run(cfg);
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_TRUE(contains(r.out, "f.csv: not a regular file")) << r.out;
  auto front = readFrontJson(fifo);
  ASSERT_FALSE(front.hasValue());
  EXPECT_TRUE(contains(front.error(), "not a regular file")) << front.error();
}

TEST_F(Hardening, Utf8ByteOrderMarkIsSkipped) {
  auto t = readCsv(write("bom.csv", "\xEF\xBB\xBFmu,r,A\n0.5,0.25,1\n0.75,0.5,2\n"));
  ASSERT_TRUE(t.hasValue()) << t.error();
  ASSERT_EQ(t->names.size(), 3u);
  EXPECT_EQ(t->names[0], "mu");
  EXPECT_EQ(t->columns[0][1], 0.75);
  auto sel = selectColumns(*t, {"mu", "r"}, {"A"}, "", "bom.csv");
  EXPECT_TRUE(sel.hasValue()) << sel.error();
  // Only at the start: elsewhere it is part of a cell and not a number.
  auto mid = readCsv(write("bom2.csv",
                           "mu,r,A\n0.5,\xEF\xBB\xBF"
                           "0.25,1\n"));
  EXPECT_FALSE(mid.hasValue());
}

TEST_F(Hardening, SubnormalsAreFiniteAndOverflowIsNamed) {
  auto t = readCsv(write("sub.csv", csvWith("1e-310")));
  ASSERT_TRUE(t.hasValue()) << t.error();
  EXPECT_EQ(t->columns[2][2], 1e-310);
  auto zero = readCsv(write("zero.csv", csvWith("1e-400")));  // underflows to 0: finite
  ASSERT_TRUE(zero.hasValue()) << zero.error();
  EXPECT_EQ(zero->columns[2][2], 0.0);
  auto big = readCsv(write("big.csv", csvWith("1e999")));
  ASSERT_FALSE(big.hasValue());
  EXPECT_TRUE(contains(big.error(), "line 4, column 3: outside the range of double"))
      << big.error();
  auto nan = readCsv(write("nan.csv", csvWith("nan")));
  ASSERT_FALSE(nan.hasValue());
  EXPECT_TRUE(contains(nan.error(), "line 4, column 3: inf or nan")) << nan.error();
}

TEST_F(Hardening, ValuesBeyondFloat32AreRefusedWithColumnAndRow) {
  for (const char* v : {"1e39", "-1e39", "1e300", "1e308"}) {
    auto raw = readCsv(write("t39.csv", csvWith(v)));
    ASSERT_TRUE(raw.hasValue()) << raw.error();
    auto t = selectColumns(*raw, {"x", "y"}, {"f"}, "", "t39.csv");
    ASSERT_FALSE(t.hasValue()) << v;
    EXPECT_TRUE(contains(t.error(), "t39.csv: column 'f', row 3: ")) << t.error();
    EXPECT_TRUE(contains(t.error(), "beyond the float32 range")) << t.error();
  }
  // FLT_MAX is in range, and so is its 9-digit spelling, which rounds to it.
  char flt_max[64];
  std::snprintf(flt_max, sizeof flt_max, "%.9g", static_cast<double>(FLT_MAX));
  EXPECT_GT(std::strtod(flt_max, nullptr), static_cast<double>(FLT_MAX));
  auto raw = readCsv(write("max.csv", csvWith(flt_max)));
  ASSERT_TRUE(raw.hasValue());
  EXPECT_TRUE(selectColumns(*raw, {"x", "y"}, {"f"}, "", "max.csv").hasValue());
  // Inputs too: the evaluation reads them as float.
  auto in = selectColumns(*raw, {"x", "f"}, {"y"}, "", "max.csv");
  EXPECT_TRUE(in.hasValue());
  auto raw39 = readCsv(write("in39.csv", csvWith("1e39")));
  auto in39 = selectColumns(*raw39, {"x", "f"}, {"y"}, "", "in39.csv");
  ASSERT_FALSE(in39.hasValue());
  EXPECT_TRUE(contains(in39.error(), "column 'f', row 3")) << in39.error();
  // And `lgp run` stops before the search.
  write("t.csv", csvWith("1e39"));
  const auto r = run(base());
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_TRUE(contains(r.out, "column 'f', row 3: 1e+39 is beyond the float32 range")) << r.out;
  write("t.csv", csvWith("1e300"));
  const auto r300 = run(base());
  EXPECT_EQ(r300.code, 2) << r300.out;
}

TEST_F(Hardening, HugeWeightsAreRefused) {
  auto raw = readCsv(write("w.csv", csvWith("0.5", "1e308")));
  ASSERT_TRUE(raw.hasValue()) << raw.error();
  auto t = selectColumns(*raw, {"x", "y"}, {"f"}, "w", "w.csv");
  ASSERT_FALSE(t.hasValue());
  EXPECT_TRUE(contains(t.error(), "w.csv: weights, row 2: 1e+308 is beyond the float32 range"))
      << t.error();
  // Every weight 1e308: each and their sum overflow.
  Table all;
  all.input_names = {"x"};
  all.output_names = {"f"};
  all.inputs = {{0, 1, 2}};
  all.outputs = {{0, 1, 2}};
  all.weights = {1e308, 1e308, 1e308};
  EXPECT_FALSE(all.validate());
  all.weights = {3e38, 3e38, 3e38};  // within float32 each; the double sum is fine too
  EXPECT_TRUE(all.validate());
  auto cfg = base();
  write("t.csv", csvWith("0.5", "1e308"));
  cfg["data"]["weights"] = "w";
  const auto r = run(cfg);
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_TRUE(contains(r.out, "weights, row 2")) << r.out;
}

TEST_F(Hardening, ChannelTargetsBeyondFloat32AreRefused) {
  Table t;
  t.input_names = {"x"};
  t.output_names = {"A", "B"};
  t.inputs = {{0, 1}};
  t.outputs = {{3e38, 1}, {3e38, 1}};
  ASSERT_TRUE(t.validate());
  ErrorConfig ec;
  EXPECT_TRUE(checkErrorNumerics(t, ec));
  ec.channels = {{"A+B", {1, 1}}};  // 6e38 in row 1
  const Status s = checkErrorNumerics(t, ec);
  ASSERT_FALSE(s);
  EXPECT_TRUE(contains(s.message(), "error channel 'A+B', row 1")) << s.message();
}

TEST_F(Hardening, JsonTablesUseTheCheckedParser) {
  auto dup =
      readJsonTable(write("dup.json", R"({"columns": {"x": [1, 2], "x": [3, 4], "f": [0, 1]}})"));
  ASSERT_FALSE(dup.hasValue());
  EXPECT_TRUE(contains(dup.error(), "dup.json: ")) << dup.error();
  EXPECT_TRUE(contains(dup.error(), "appears twice")) << dup.error();
  std::string deep = R"({"columns": {"x": [1], "f": [2]}, "meta": )";
  deep += std::string(100000, '[') + std::string(100000, ']') + "}";
  auto d = readJsonTable(write("deep.json", deep));
  ASSERT_FALSE(d.hasValue());
  EXPECT_TRUE(contains(d.error(), "nested deeper than")) << d.error();
  auto sub = readJsonTable(write("sub.json", R"({"columns": {"x": [1e-310], "f": [2]}})"));
  ASSERT_TRUE(sub.hasValue()) << sub.error();
  ASSERT_GE(sub->find("x"), 0);
  EXPECT_EQ(sub->columns[sub->find("x")][0], 1e-310);
  auto big = readJsonTable(write("big.json", R"({"columns": {"x": [1e999], "f": [2]}})"));
  ASSERT_FALSE(big.hasValue());
}

// --- result files ------------------------------------------------------------------------

TEST_F(Hardening, FrontAndCheckpointFilesUseTheCheckedParser) {
  fs::create_directories(dir / "front_dir");
  auto d = readFrontJson(dir / "front_dir");
  ASSERT_FALSE(d.hasValue());
  EXPECT_EQ(d.error(), (dir / "front_dir").string() + ": is a directory");
  std::string deep = R"({"format": "lgp-front/1", "x": )" + std::string(100000, '[') +
                     std::string(100000, ']') + "}";
  auto f = readFrontJson(write("deep_front.json", deep));
  ASSERT_FALSE(f.hasValue());
  EXPECT_TRUE(contains(f.error(), "nested deeper than")) << f.error();
  auto c =
      readCheckpointFile(write("ck.json", R"({"format": "lgp-checkpoint/2", "a": 1, "a": 2})"));
  ASSERT_FALSE(c.hasValue());
  EXPECT_TRUE(contains(c.error(), "appears twice")) << c.error();
  const auto r = sh(lgp() + " front " + (dir / "deep_front.json").string());
  EXPECT_NE(r.code, 0);
  EXPECT_TRUE(contains(r.out, "nested deeper than")) << r.out;
}

// --- lgp run -----------------------------------------------------------------------------

TEST_F(Hardening, DeeplyNestedConfigIsAClearError) {
  for (const char* open : {"[", "{\"a\":"}) {
    std::string text = R"({"data": {"path": "t.csv", "inputs": ["x", "y"], "outputs": ["f"]},
                           "meta": )";
    std::string close = open[0] == '[' ? "]" : "}";
    for (int i = 0; i < 100000; ++i) text += open;
    text += "0";
    for (int i = 0; i < 100000; ++i) text += close;
    text += "}";
    write("deep.json", text);
    const auto r = sh("timeout 60 " + lgp() + " run " + (dir / "deep.json").string() + " -q");
    EXPECT_EQ(r.code, 2) << r.out.substr(0, 500);
    EXPECT_TRUE(contains(r.out, "nested deeper than")) << r.out.substr(0, 500);
  }
}

TEST_F(Hardening, HostileReferencesFailTheRunNotCrashIt) {
  const std::string deep = "nested deeper than";
  struct Case {
    std::string expr, why;
  };
  std::string abs_chain;
  for (int i = 0; i < 5000; ++i) abs_chain += "abs(";
  abs_chain += "x" + std::string(5000, ')');
  const std::vector<Case> cases = {
      {std::string(3000, '(') + "x" + std::string(3000, ')'), deep},
      {std::string(5000, '-') + "x", deep},
      {abs_chain, deep},
      {"x2147483648 + y", "input index 'x2147483648' out of range"},
      {"x4294967297", "input index 'x4294967297' out of range"},
  };
  for (const auto& c : cases) {
    for (bool seed : {false, true}) {
      auto cfg = base();
      cfg["references"] = {{{"name", "hostile"}, {"expr", c.expr}}};
      cfg["search"]["seed_references"] = seed;
      const auto r = run(cfg);
      EXPECT_EQ(r.code, 2) << c.expr.substr(0, 40) << ": " << r.out.substr(0, 300);
      EXPECT_TRUE(contains(r.out, "/references/0 (hostile): ")) << r.out.substr(0, 300);
      EXPECT_TRUE(contains(r.out, c.why)) << r.out.substr(0, 300);
    }
  }
  // 30k terms: refused at once by its length.
  std::string sum = "x";
  for (int k = 1; k < 30000; ++k) sum += " + x*" + std::to_string(k) + ".5";
  const auto r = runWithReference(sum);
  EXPECT_EQ(r.code, 2) << r.out.substr(0, 300);
  EXPECT_TRUE(contains(r.out, "more than the limit of 65536")) << r.out.substr(0, 300);
}

TEST_F(Hardening, SceneGridTooLargeIsRefused) {
  write("big_scene.json", R"({"outputs": ["A", "B"],
      "material": {"fresnel": {"model": "schlick", "f90": 1}},
      "grid": {"mu": {"count": 100000}, "r": {"count": 100000}}})");
  auto cfg = base();
  cfg["data"] = {{"scene", "big_scene.json"}, {"cache_dir", (dir / "cache").string()}};
  const auto r = run(cfg);
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_TRUE(contains(r.out, "/grid: 100000 x 100000 = 10000000000 cells, more than the limit"))
      << r.out;
  EXPECT_FALSE(contains(r.out, "bad_alloc")) << r.out;
}

// A mean_rel weight w/max(|y|, rel_floor) beyond float32 made every error infinite, and the
// run ended with exit 0 and an empty front: now refused before the search.
TEST_F(Hardening, MeanRelWeightsBeyondFloat32AreRefused) {
  write("t.csv", csvWith("0"));
  auto cfg = base();
  cfg["objectives"] = {{"error", "mean_rel"}, {"rel_floor", 1e-300}};
  const auto r = run(cfg);
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_TRUE(contains(r.out, "output 'f', row 3: the mean_rel weight")) << r.out;
  EXPECT_TRUE(contains(r.out, "raise /objectives/rel_floor")) << r.out;
}

// A run whose front is empty (here: resumed from a finished checkpoint whose archive was
// emptied and whose population computes 3e38 * 3e38, infinite in float32) fails with a reason
// and writes no front. (The checkpoint scores each program again: its errors must be the
// programs' own.)
TEST_F(Hardening, EmptyFrontIsAnErrorNotExitZero) {
  auto cfg = base();
  cfg["output"]["checkpoint"] = (dir / "ck.json").string();
  const auto first = run(cfg);
  ASSERT_EQ(first.code, 0) << first.out;
  fs::remove(dir / "front.json");
  nlohmann::json ck;
  {
    std::ifstream in(dir / "ck.json");
    ck = nlohmann::json::parse(in);
  }
  ck["archive"] = nlohmann::json::array();
  for (auto& isl : ck["islands"])
    for (auto& ind : isl["population"]) {
      ind["program"]["code"] = nlohmann::json::array({{"mul", "c0", "c0"}});
      ind["program"]["constants"][0] = 3e38;
      ind["program"]["outputs"] = {0};
      ind["obj"][0] = nullptr;  // error: not finite, as the program scores
    }
  std::ofstream(dir / "ck.json") << ck.dump();
  write("c.json", cfg.dump());
  const auto r = sh("timeout 60 " + lgp() + " run " + (dir / "c.json").string() + " -q --resume");
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_TRUE(contains(r.out, "the search ended with an empty front")) << r.out;
  EXPECT_TRUE(contains(r.out, "had a finite error")) << r.out;
  EXPECT_FALSE(fs::exists(dir / "front.json"));
}

TEST_F(Hardening, ANormalRunStillSucceeds) {
  const auto r = run(base());
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_TRUE(fs::exists(dir / "front.json"));
}

}  // namespace
}  // namespace lgp
