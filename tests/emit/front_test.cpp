// Emitting from a real front.json (a short seeded search on the DFG table), member
// selection, the half-precision re-measurement, and the run config's references.
#include <gtest/gtest.h>

#include "emit_test_util.hpp"
#include "lgp/emit/emit.hpp"
#include "lgp/emit/score.hpp"
#include "lgp/io/result.hpp"
#include "lgp/search/search.hpp"

namespace lgp::emit {
namespace {

nlohmann::json runConfigJson() {
  return {{"data", {{"path", (test::dataDir() / "dfg_16x16.json").string()}}},
          {"search", {{"population", 48}, {"generations", 8}, {"seed", 3}, {"threads", 1}}},
          {"references",
           {{{"name", "Karis EnvBRDFApprox"},
             {"expr",
              {"qx = 1 - r; a004 = min(qx*qx, exp2(-9.28*NoV))*qx + (-0.0275*r + 0.0425); "
               "A = -1.04*a004 + (-0.572*r + 1.04)",
               "B = 1.04*a004 + (0.022*r - 0.04)"}}},
            {{"name", "Iwanicki"},
             {"expr",
              "m = rough*rough; B = exp2(-(7*NoV + 4*m)); "
              "A = 1 - B - m*max(B, min(rough, 0.739 + 0.323*NoV) - 0.434)"},
             {"aliases", {{"rough", "r"}}}},
            {{"name", "broken"}, {"expr", "A = r +"}}}}};
}

const nlohmann::json& front() {
  static const nlohmann::json f = [] {
    const Table t = test::loadDfg();
    auto cfg = parseRunConfig(runConfigJson(), test::dataDir());
    EXPECT_TRUE(cfg.hasValue()) << cfg.error();
    Search s(*cfg, t);
    s.run();
    return frontToJson(s, s.front());
  }();
  return f;
}

TEST(EmitFront, EveryMemberEmitsInEveryLanguage) {
  const auto& f = front();
  ASSERT_GE(f["members"].size(), 2u);
  for (size_t m = 0; m < f["members"].size(); ++m)
    for (Language l : {Language::Hlsl, Language::Glsl, Language::Cpp}) {
      auto code = emitFromFront(f, m, l, EmitOptions{});
      ASSERT_TRUE(code.hasValue()) << code.error();
      EXPECT_NE(code->find("// Fitted on: "), std::string::npos);
      EXPECT_NE(code->find("NoV in [0.03125, 0.96875], r in [0, 1]"), std::string::npos) << *code;
      EXPECT_NE(code->find("// Error (search, float32): A rmse "), std::string::npos) << *code;
      EXPECT_NE(code->find("// Cost: gpu-generic "), std::string::npos);
      EXPECT_NE(code->find("// Piecewise ops: "), std::string::npos);
      const std::string sig = l == Language::Cpp    ? "inline lgp_fit_result lgp_fit("
                              : l == Language::Hlsl ? "float2 lgp_fit(float NoV, float r)"
                                                    : "vec2 lgp_fit(float NoV, float r)";
      EXPECT_NE(code->find(sig), std::string::npos) << *code;
    }
}

TEST(EmitFront, EmittedCostNeverExceedsTheSearchCost) {
  const auto& f = front();
  for (size_t m = 0; m < f["members"].size(); ++m) {
    auto in = emitInputFromFront(f, m);
    ASSERT_TRUE(in.hasValue()) << in.error();
    auto e = emitProgram(*in, Language::Hlsl, EmitOptions{});
    ASSERT_TRUE(e.hasValue()) << e.error();
    for (int t = 0; t < kNumCostTargets; ++t)
      EXPECT_LE(
          e->cost[t],
          f["members"][m]["cost_by_target"][std::string(kCostTargetNames[t])].get<double>() + 1e-9);
  }
}

TEST(EmitFront, MemberSelection) {
  const auto& f = front();
  const auto& ms = f["members"];
  MemberSelector s;
  auto best = selectMember(f, s);
  ASSERT_TRUE(best.hasValue());
  for (const auto& m : ms) EXPECT_LE(ms[*best]["error"].get<double>(), m["error"].get<double>());
  s.max_cost = ms[0]["cost"].get<double>();  // the cheapest member's cost
  auto cheap = selectMember(f, s);
  ASSERT_TRUE(cheap.hasValue());
  EXPECT_LE(ms[*cheap]["cost"].get<double>(), ms[0]["cost"].get<double>());
  s = MemberSelector{};
  s.max_error = ms[*best]["error"].get<double>();
  auto acc = selectMember(f, s);
  ASSERT_TRUE(acc.hasValue());
  EXPECT_LE(ms[*acc]["error"].get<double>(), s.max_error.value());
  s.max_error = 0;
  auto none = selectMember(f, s);
  ASSERT_FALSE(none.hasValue());
  EXPECT_NE(none.error().find("--max-error: no member has error <= 0"), std::string::npos);
  s = MemberSelector{};
  s.index = 999;
  EXPECT_FALSE(selectMember(f, s).hasValue());
  s.max_cost = 3;
  EXPECT_NE(selectMember(f, s).error().find("give one of"), std::string::npos);
  s = MemberSelector{};
  s.max_cost = 1e9;
  s.cost_target = "nvidia";
  EXPECT_TRUE(selectMember(f, s).hasValue());
}

TEST(EmitFront, HalfErrorIsReMeasuredOnTheTable) {
  const auto& f = front();
  const Table t = test::loadDfg();
  EmitOptions o;
  o.precision = Precision::Half;
  o.table = &t;
  o.table_label = "dfg.csv";
  auto in = emitInputFromFront(f, f["members"].size() - 1);
  ASSERT_TRUE(in.hasValue());
  auto e = emitProgram(*in, Language::Hlsl, o);
  ASSERT_TRUE(e.hasValue()) << e.error();
  EXPECT_NE(e->code.find("// Error (this code, half arithmetic, on dfg.csv, " +
                         std::to_string(t.rows()) + " rows): A rmse "),
            std::string::npos)
      << e->code;
  EXPECT_NE(e->code.find("half2 lgp_fit(half NoV, half r)"), std::string::npos);
  o.table = nullptr;
  e = emitProgram(*in, Language::Hlsl, o);
  EXPECT_NE(e->code.find("not measured (no table given)"), std::string::npos);
}

TEST(EmitFront, BadFrontsAreErrorsNamingTheField) {
  nlohmann::json f = front();
  EXPECT_NE(emitFromFront(f, 999, Language::Hlsl, {}).error().find("out of range"),
            std::string::npos);
  f["members"][0]["outputs"][0]["transform"] = "cube";
  EXPECT_NE(emitFromFront(f, 0, Language::Hlsl, {}).error().find("/members/0/outputs/0/transform"),
            std::string::npos);
  f.erase("table");
  EXPECT_NE(emitFromFront(f, 0, Language::Hlsl, {}).error().find("/table"), std::string::npos);
}

TEST(EmitFront, ReferencesAreScoredLikeMembers) {
  const Table t = test::loadDfg();
  auto cfg = parseRunConfig(runConfigJson(), test::dataDir());
  ASSERT_TRUE(cfg.hasValue()) << cfg.error();
  const auto refs = scoreReferences(*cfg, t);
  ASSERT_EQ(refs.size(), 3u);
  for (int i = 0; i < 2; ++i) {
    EXPECT_TRUE(refs[i]["error"].is_number()) << refs[i].dump();
    EXPECT_TRUE(refs[i]["cost"].is_number());
    EXPECT_TRUE(refs[i]["cost_by_target"]["nvidia"].is_number());
    EXPECT_TRUE(refs[i]["outputs"][1]["float32"]["rmse"].is_number());
    EXPECT_TRUE(refs[i]["program"].contains("code"));
  }
  EXPECT_EQ(refs[0]["name"], "Karis EnvBRDFApprox");
  EXPECT_TRUE(refs[2].contains("invalid"));
  EXPECT_NE(refs[2]["invalid"].get<std::string>().find("unexpected end of formula"),
            std::string::npos);
  const Status s = checkReferences(*cfg, t);
  ASSERT_FALSE(s.isOk());
  EXPECT_NE(s.message().find("/references/2 (broken)"), std::string::npos) << s.message();
  auto bad = parseReferences(nlohmann::json::array({{{"name", "x"}, {"exp", "r"}}}));
  ASSERT_FALSE(bad.hasValue());
  EXPECT_NE(bad.error().find("/references/0/exp: unknown key"), std::string::npos);
}

}  // namespace
}  // namespace lgp::emit
