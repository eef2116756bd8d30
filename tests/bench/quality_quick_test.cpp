// `lgp_quality --quick` end to end: the report folder is complete and well formed, every
// figure in it is finite, and it is deterministic. The targets themselves are not checked
// here (a quick run is minutes of search); they belong to the committed full report.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

namespace fs = std::filesystem;

namespace {

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

fs::path runQuick(const std::string& name, const std::string& extra = "") {
  const fs::path dir =
      fs::temp_directory_path() / ("lgp_quality_" + std::to_string(getpid()) + "_" + name);
  fs::remove_all(dir);
  const std::string cmd = std::string(LGP_QUALITY_PATH) + " --quick --out " + dir.string() + " " +
                          extra + " > " + dir.string() + ".log 2>&1";
  const int rc = std::system(cmd.c_str());
  EXPECT_EQ(rc, 0) << slurp(dir.string() + ".log");
  return dir;
}

class QualityQuick : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { dir_ = new fs::path(runQuick("all")); }
  static void TearDownTestSuite() {
    fs::remove_all(*dir_);
    fs::remove(dir_->string() + ".log");
    delete dir_;
  }
  static fs::path* dir_;
};
fs::path* QualityQuick::dir_ = nullptr;

TEST_F(QualityQuick, ReportHasEverySectionForEveryTable) {
  const std::string md = slurp(*dir_ / "report.md");
  for (const char* t :
       {"Split-sum DFG", "Disney-diffuse ZH", "Sphere-light normalization", "Kulla-Conty E_avg"})
    EXPECT_NE(md.find("## " + std::string(t)), std::string::npos) << t;
  for (const char* s :
       {"### Targets", "### Accuracy against search time", "### Final front",
        "### Published formulas on the same table", "### Search levers", "### Recommended members"})
    EXPECT_NE(md.find(s), std::string::npos) << s;
  // The published DFG formulas are scored, published and refit.
  for (const char* r :
       {"Karis EnvBRDFApprox", "Iwanicki & Pesce", "Narkowicz 2014", "MaterialX rational",
        "Ray Tracing Gems ch.32", "Karis EnvBRDFApprox (refit)"})
    EXPECT_NE(md.find("| " + std::string(r) + " |"), std::string::npos) << r;
  EXPECT_EQ(md.find("invalid:"), std::string::npos);
  EXPECT_EQ(md.find("nan"), std::string::npos);
  EXPECT_EQ(md.find("inf |"), std::string::npos);
  // Every member's shaders ran in the driver, in float and half, and agree with lgp on which
  // rows are finite (a check where they do not is listed after "Worst:").
  const std::regex worst(
      R"(Worst: [0-9.e+-]+ ulps \(float\), [0-9.e+-]+ binary16 ulps \(half\)\.)");
  const std::string heading = "### In a Vulkan driver", not_run = heading + "\n\nNot run: ";
  size_t sections = 0, lines = 0;
  for (size_t p = md.find(heading); p != std::string::npos; p = md.find(heading, p + 1))
    sections += md.compare(p, not_run.size(), not_run) != 0;
  for (auto it = std::sregex_iterator(md.begin(), md.end(), worst); it != std::sregex_iterator();
       ++it)
    ++lines;
  EXPECT_EQ(md.find("not finite on the same rows"), std::string::npos);
  EXPECT_EQ(lines, sections);
}

TEST_F(QualityQuick, EveryLinkedFileExistsAndIsWellFormed) {
  const std::string md = slurp(*dir_ / "report.md");
  const std::regex link(R"(\]\(([A-Za-z0-9_.]+)\))");
  std::set<std::string> files;
  for (auto it = std::sregex_iterator(md.begin(), md.end(), link); it != std::sregex_iterator();
       ++it)
    files.insert((*it)[1]);
  int svgs = 0, hlsl = 0;
  for (const auto& f : files) {
    const fs::path p = *dir_ / f;
    ASSERT_TRUE(fs::exists(p)) << f;
    const std::string text = slurp(p);
    if (p.extension() == ".svg") {
      ++svgs;
      EXPECT_EQ(text.rfind("<svg", 0), 0u) << f;
      EXPECT_NE(text.find("</svg>"), std::string::npos) << f;
      EXPECT_EQ(text.find("NaN"), std::string::npos) << f;
      EXPECT_EQ(text.find("nan"), std::string::npos) << f;
    } else if (p.extension() == ".hlsl") {
      ++hlsl;
      EXPECT_NE(text.find("float"), std::string::npos) << f;
      EXPECT_NE(text.find("lgp_"), std::string::npos) << f;
    }
  }
  EXPECT_GE(svgs, 4 * 3);  // front, curve and at least one error map per table
  EXPECT_GE(hlsl, 4);
}

TEST_F(QualityQuick, SummaryFiguresAreFinite) {
  const auto s = nlohmann::json::parse(slurp(*dir_ / "summary.json"));
  for (const char* t : {"dfg", "zh", "normalization", "energy"}) {
    ASSERT_TRUE(s.contains(t)) << t;
    ASSERT_FALSE(s[t]["targets"].empty()) << t;
    for (const auto& g : s[t]["targets"]) {
      // A target with no member at or below its cost limit says so (member -1, not met, no
      // figures); otherwise the chosen member's cost is a number within the limit's unit.
      if (g["member"].get<int>() < 0) {
        EXPECT_TRUE(g["cost"].is_null()) << g.dump();
        EXPECT_FALSE(g["met"].get<bool>()) << g.dump();
        EXPECT_TRUE(g["measured"].empty()) << g.dump();
        continue;
      }
      ASSERT_TRUE(g["cost"].is_number()) << g.dump();
      ASSERT_TRUE(g["model_cost"].is_number()) << g.dump();
      for (const auto& m : g["measured"]) {
        EXPECT_TRUE(std::isfinite(m[0].get<double>())) << g.dump();
        EXPECT_TRUE(std::isfinite(m[1].get<double>())) << g.dump();
      }
    }
    EXPECT_FALSE(s[t]["recommended"].empty()) << t;
  }
  const auto timing = nlohmann::json::parse(slurp(*dir_ / "timing.json"));
  EXPECT_TRUE(timing.contains("dfg"));
}

TEST_F(QualityQuick, ReportIsDeterministic) {
  const fs::path again = runQuick("again", "--tables energy,normalization --no-ablation");
  const fs::path first = runQuick("first", "--tables energy,normalization --no-ablation");
  EXPECT_EQ(slurp(again / "report.md"), slurp(first / "report.md"));
  EXPECT_EQ(slurp(again / "energy_front.svg"), slurp(first / "energy_front.svg"));
  for (const auto& d : {again, first}) {
    fs::remove_all(d);
    fs::remove(d.string() + ".log");
  }
}

// A run stopped by --stop-after and resumed from its --state, as often as it takes, writes the
// report of an uninterrupted run; the state refuses another seed and a file that is not one.
TEST(QualityCli, StoppedAndResumedRunWritesTheUninterruptedReport) {
  const fs::path whole = runQuick("whole", "--tables energy --no-ablation");
  const fs::path dir =
      fs::temp_directory_path() / ("lgp_quality_" + std::to_string(getpid()) + "_resumed");
  const fs::path state = dir.string() + "_state";
  fs::remove_all(dir);
  fs::remove_all(state);
  const std::string base = std::string(LGP_QUALITY_PATH) +
                           " --quick --tables energy --no-ablation --out " + dir.string() +
                           " --state " + state.string();
  const std::string log = dir.string() + ".log";
  int stops = 0, rc = 0;
  for (int i = 0; i < 200; ++i) {
    rc = std::system((base + " --stop-after 0.05 --save-every 0.01 > " + log + " 2>&1").c_str());
    if (!WIFEXITED(rc) || WEXITSTATUS(rc) != 3) break;
    ++stops;
  }
  ASSERT_TRUE(WIFEXITED(rc) && WEXITSTATUS(rc) == 0) << slurp(log);
  EXPECT_GE(stops, 2) << "the run was never stopped: the test checks nothing";
  EXPECT_EQ(slurp(whole / "report.md"), slurp(dir / "report.md"));
  // Finished: running it again searches nothing and writes the same report.
  ASSERT_EQ(std::system((base + " > " + log + " 2>&1").c_str()), 0) << slurp(log);
  EXPECT_NE(slurp(log).find("finished: no search"), std::string::npos) << slurp(log);
  EXPECT_EQ(slurp(whole / "report.md"), slurp(dir / "report.md"));
  // Another seed is another run.
  EXPECT_NE(std::system((base + " --seed 2 > " + log + " 2>&1").c_str()), 0);
  EXPECT_NE(slurp(log).find("seed 1 there, 2 here"), std::string::npos) << slurp(log);
  std::ofstream(state / "energy.state.json") << "{\"format\": \"something else\"}";
  EXPECT_NE(std::system((base + " > " + log + " 2>&1").c_str()), 0);
  EXPECT_NE(slurp(log).find("energy.state.json: /format"), std::string::npos) << slurp(log);
  for (const auto& d : {whole, dir}) {
    fs::remove_all(d);
    fs::remove(d.string() + ".log");
  }
  fs::remove_all(state);
}

TEST(QualityCli, BadSpecIsAClearError) {
  const fs::path spec =
      fs::temp_directory_path() / ("lgp_bad_spec_" + std::to_string(getpid()) + ".json");
  std::ofstream(spec) << R"({"tables": [{"name": "x", "config": "c.json"}]})";
  const std::string log = spec.string() + ".log";
  const int rc = std::system((std::string(LGP_QUALITY_PATH) + " --spec " + spec.string() +
                              " --out /tmp/none > " + log + " 2>&1")
                                 .c_str());
  EXPECT_NE(rc, 0);
  EXPECT_NE(slurp(log).find("/tables/0/evals_per_minute"), std::string::npos) << slurp(log);
  fs::remove(spec);
  fs::remove(log);
}

}  // namespace
