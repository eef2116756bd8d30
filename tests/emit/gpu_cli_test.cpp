// Measured cost and Vulkan runs through the `lgp` CLI: lgp run records cost_measured, lgp front
// shows it, lgp score prints it, lgp emit states it in the header and --verify vulkan runs the
// member. Skips, saying why, where the GPU backends are unavailable.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "../shell.hpp"
#include "../skip.hpp"
#include "lgp/emit/gpu_cost.hpp"
#include "lgp/emit/vulkan_run.hpp"

namespace {

namespace fs = std::filesystem;
using lgp_test::sh;

class GpuCli : public ::testing::Test {
 protected:
  fs::path dir = fs::temp_directory_path() / ("lgp_gpu_cli_" + std::to_string(getpid()));
  void SetUp() override {
    const auto st = lgp::emit::isaBackendStatus();
    if (!st.available) LGP_SKIP_UNLESS_REQUIRED() << "no ISA measurement here: " << st.detail;
    fs::create_directories(dir);
    std::ofstream csv(dir / "t.csv");
    csv << "mu,r,B\n";
    for (int i = 0; i < 12; ++i)
      for (int j = 0; j < 12; ++j) {
        const double mu = (i + 0.5) / 12, r = (j + 0.5) / 12;
        csv << mu << "," << r << "," << std::exp2(-(7 * mu + 4 * r * r)) << "\n";
      }
    nlohmann::json cfg = {
        {"data", {{"path", (dir / "t.csv").string()}, {"inputs", {"mu", "r"}}, {"outputs", {"B"}}}},
        {"search", {{"population", 80}, {"generations", 30}, {"seed", 3}, {"threads", 2}}},
        {"references", {{{"name", "exact"}, {"expr", "B = exp2(-(7*mu + 4*r*r))"}}}},
        {"output", {{"front_json", (dir / "front.json").string()}, {"front_csv", ""}}}};
    std::ofstream(dir / "c.json") << cfg.dump();
  }
  void TearDown() override { fs::remove_all(dir); }
  std::string lgp() const { return std::string(LGP_CLI_PATH); }
};

TEST_F(GpuCli, RunFrontScoreAndEmitShowMeasuredCost) {
  auto r = sh(lgp() + " run " + (dir / "c.json").string());
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("measured GPU cost of"), std::string::npos) << r.out;
  std::ifstream in(dir / "front.json");
  const auto front = nlohmann::json::parse(in);
  ASSERT_TRUE(front.contains("cost_measured_info")) << front.dump(1).substr(0, 400);
  EXPECT_EQ(front["cost_measured_info"]["families"],
            nlohmann::json::array({"rdna2", "rdna3", "gcn5"}));
  for (const char* list : {"members", "references"})
    for (const auto& m : front[list]) {
      ASSERT_TRUE(m.contains("cost_measured")) << list;
      for (const char* f : {"rdna2", "rdna3", "gcn5"})
        EXPECT_GE(m["cost_measured"][f]["instructions"].get<double>(), 0) << list << " " << f;
    }
  // The exact reference costs instructions on every family.
  EXPECT_GT(front["references"][0]["cost_measured"]["rdna2"]["instructions"].get<double>(), 3);

  r = sh(lgp() + " front " + (dir / "front.json").string());
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("rdna2/rdna3/gcn5"), std::string::npos) << r.out;

  r = sh(lgp() + " score " + (dir / "t.csv").string() +
         " --inputs mu,r --outputs B --expr 'B = exp2(-(7*mu + 4*r*r))'");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("measured (instructions"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("rdna2 "), std::string::npos) << r.out;

  r = sh(lgp() + " emit " + (dir / "front.json").string() + " --lang glsl");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("// Measured (ACO instructions"), std::string::npos) << r.out;
  r = sh(lgp() + " emit " + (dir / "front.json").string() + " --lang glsl --no-measure");
  EXPECT_EQ(r.out.find("// Measured"), std::string::npos) << r.out;

  // Code printed without its helpers is measured with them: the same measured line.
  bool checked = false;
  for (size_t i = 0; i < front["members"].size() && !checked; ++i) {
    const std::string emit = lgp() + " emit " + (dir / "front.json").string() + " -m " +
                             std::to_string(i) + " --lang hlsl";
    const auto full = sh(emit);
    ASSERT_EQ(full.code, 0) << full.out;
    if (full.out.find("lgp protected-operator helpers") == std::string::npos) continue;
    const auto bare = sh(emit + " --no-helpers");
    ASSERT_EQ(bare.code, 0) << bare.out;
    EXPECT_EQ(bare.out.find("lgp protected-operator helpers"), std::string::npos) << bare.out;
    const auto measured = [](const std::string& s) {
      const size_t a = s.find("// Measured");
      return a == std::string::npos ? std::string() : s.substr(a, s.find('\n', a) - a);
    };
    EXPECT_NE(measured(full.out).find("// Measured (ACO instructions"), std::string::npos);
    EXPECT_EQ(measured(bare.out), measured(full.out)) << bare.out;
    checked = true;
  }
  EXPECT_TRUE(checked) << "no member of the front calls a protected helper";
}

TEST_F(GpuCli, EmitVerifyVulkanRunsTheMember) {
  const auto st = lgp::emit::vulkanRunStatus();
  if (!st.available) LGP_SKIP_UNLESS_REQUIRED() << "no Vulkan driver to run shaders: " << st.detail;
  ASSERT_EQ(sh(lgp() + " run " + (dir / "c.json").string() + " -q").code, 0);
  auto r = sh(lgp() + " emit " + (dir / "front.json").string() + " --verify vulkan -o " +
              (dir / "m.hlsl").string());
  ASSERT_EQ(r.code, 0) << r.out;
  for (const char* v : {"glsl float", "glsl half", "hlsl float", "hlsl half"})
    EXPECT_NE(r.out.find(v), std::string::npos) << v << "\n" << r.out;
  EXPECT_TRUE(fs::exists(dir / "m.hlsl"));
  // A bound of 0 ulp, which GPU exp2 and half arithmetic do not meet, fails the check.
  r = sh(lgp() + " emit " + (dir / "front.json").string() + " --verify vulkan --verify-ulp 0 -o " +
         (dir / "m.hlsl").string());
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("OVER THE BOUND"), std::string::npos) << r.out;
  r = sh(lgp() + " emit " + (dir / "front.json").string() + " --verify metal");
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("--verify"), std::string::npos) << r.out;
}

}  // namespace
