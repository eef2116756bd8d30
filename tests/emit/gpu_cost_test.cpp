// Measured GPU cost on RADV's null device (emit/gpu_cost.hpp) and the calibrated cost model
// (lgp/eval/cost_model.hpp). Every test skips, saying why, where the backend is unavailable
// (no Vulkan/glslang at build time, or no Mesa RADV driver installed).
#include <gtest/gtest.h>

#include <cmath>

#include "../skip.hpp"
#include "lgp/core/formula.hpp"
#include "lgp/emit/compute_shader.hpp"
#include "lgp/emit/cost_calibration.hpp"
#include "lgp/emit/gpu_cost.hpp"
#include "lgp/emit/parser.hpp"

namespace lgp::emit {
namespace {

#define LGP_REQUIRE_ISA()                                                                      \
  do {                                                                                         \
    const auto st = isaBackendStatus();                                                        \
    if (!st.available) LGP_SKIP_UNLESS_REQUIRED() << "no ISA measurement here: " << st.detail; \
  } while (0)

const std::vector<std::string> kIn = {"mu", "r"};
const std::vector<Interval> kDomain = {{1.0 / 64, 1.0, false}, {0.0, 1.0, false}};

Program parse(const std::vector<std::string>& texts, const std::vector<std::string>& outs) {
  ParseOptions po;
  po.input_names = kIn;
  po.output_names = outs;
  auto f = parseFormula(texts, po);
  EXPECT_TRUE(f.hasValue()) << f.error();
  return f->program;
}

EmitInput input(const Program& p, const std::vector<std::string>& outs) {
  EmitInput in;
  in.program = p;
  in.input_names = kIn;
  in.output_names = outs;
  in.domain = kDomain;
  return in;
}

double instructions(const EmitInput& in, GpuFamily f, Language lang = Language::Hlsl) {
  MeasureOptions o;
  o.families = {f};
  o.lang = lang;
  auto m = measureProgram(in, o);
  EXPECT_TRUE(m.hasValue()) << m.error();
  return m ? (*m)[std::string(toString(f))]["instructions"].get<double>() : NAN;
}

TEST(GpuCost, NullDeviceIsRadvNullHardware) {
  LGP_REQUIRE_ISA();
  for (GpuFamily f : allGpuFamilies()) {
    const auto st = isaBackendStatus(f);
    ASSERT_TRUE(st.available) << st.detail;
    EXPECT_NE(st.detail.find("Null hardware (RADV"), std::string::npos) << st.detail;
  }
}

TEST(GpuCost, IdentityFormulaCostsNothing) {
  LGP_REQUIRE_ISA();
  // Outputs that are the inputs: the shader is its own I/O baseline.
  for (Language lang : {Language::Hlsl, Language::Glsl})
    for (GpuFamily f : allGpuFamilies()) {
      EXPECT_EQ(instructions(input(parse({"B = r"}, {"B"}), {"B"}), f, lang), 0)
          << toString(lang) << " " << toString(f);
      EXPECT_EQ(instructions(input(parse({"A = mu; B = r"}, {"A", "B"}), {"A", "B"}), f, lang), 0)
          << toString(lang) << " " << toString(f);
    }
}

TEST(GpuCost, OneMoreMultiplyCostsAtLeastOneInstruction) {
  LGP_REQUIRE_ISA();
  const std::vector<std::pair<std::string, std::string>> pairs = {
      {"B = exp2(-7*mu - 4*r*r)", "B = exp2(-7*mu - 4*r*r)*mu"},
      {"B = mu + r", "B = (mu + r)*r"},
      {"B = sqrt(mu)*0.3 + r", "B = (sqrt(mu)*0.3 + r)*(mu + r)"},
      {"B = max(mu, r) - 0.25", "B = (max(mu, r) - 0.25)*mu"}};
  for (const auto& [a, b] : pairs)
    for (GpuFamily f : allGpuFamilies()) {
      const double ca = instructions(input(parse({a}, {"B"}), {"B"}), f);
      const double cb = instructions(input(parse({b}, {"B"}), {"B"}), f);
      EXPECT_GE(cb, ca + 1) << a << " -> " << b << " on " << toString(f);
    }
}

// The measured cost is the cost of the formula, not of how the program spells it: a program
// and the program of its simplified, printed formula (the same DAG, relinearised) measure the
// same, and print the same.
TEST(GpuCost, ProgramAndItsSimplifiedFormulaCostTheSame) {
  LGP_REQUIRE_ISA();
  CorpusOptions co;
  co.programs = 40;
  co.seed = 11;
  co.max_inputs = 2;
  int compared = 0;
  for (const auto& s : randomCorpus(co)) {
    if (s.num_inputs != 2) continue;
    std::vector<std::string> outs;
    for (size_t o = 0; o < s.program.outputs.size(); ++o) outs.push_back("y" + std::to_string(o));
    const Dag d = formulaDag(s.program, 2, kDomain);
    auto lin = toProgram(d);
    ASSERT_TRUE(lin.hasValue()) << lin.error();
    const std::string text = printFormula(d, kIn, outs).text();
    ASSERT_EQ(printFormula(formulaDag(lin->program, 2, kDomain), kIn, outs).text(), text);
    EmitInput a = input(s.program, outs), b = input(lin->program, outs);
    for (GpuFamily f : allGpuFamilies())
      EXPECT_EQ(instructions(a, f), instructions(b, f)) << text << " on " << toString(f);
    ++compared;
  }
  EXPECT_GE(compared, 10);
}

TEST(GpuCost, MeasuredCostIsCachedAndDeterministic) {
  LGP_REQUIRE_ISA();
  const EmitInput in = input(parse({"B = exp2(-(7*mu + 4*r*r))"}, {"B"}), {"B"});
  MeasureOptions o;
  auto a = measureProgram(in, o);
  auto b = measureProgram(in, o);
  ASSERT_TRUE(a.hasValue()) << a.error();
  ASSERT_TRUE(b.hasValue()) << b.error();
  EXPECT_EQ(*a, *b);
  for (GpuFamily f : allGpuFamilies()) {
    const auto& s = (*a)[std::string(toString(f))];
    EXPECT_GT(s["instructions"].get<double>(), 0);
    EXPECT_GE(s["latency"].get<double>(), 0);
  }
}

TEST(GpuCost, BrokenShaderIsReportedNotFatal) {
  LGP_REQUIRE_ISA();
  auto r = shaderIsaStats(GpuFamily::Rdna2, Language::Glsl, "#version 450\nvoid main() { x; }\n");
  ASSERT_FALSE(r.hasValue());
  EXPECT_NE(r.error().find("compile"), std::string::npos) << r.error();
  // The worker survives a failed compile.
  EXPECT_TRUE(isaBackendStatus().available);
}

// The shipped rdna and gcn tables predict programs they were not fitted on within the error
// the calibration reported (costCalibration, from bench/cost's held-out set).
TEST(GpuCost, CalibratedModelPredictsHeldOutPrograms) {
  LGP_REQUIRE_ISA();
  CorpusOptions co;
  co.programs = 160;
  co.seed = 7;  // the shipped fit used seed 1
  auto corpus = randomCorpus(co);
  ASSERT_TRUE(measureCorpus(corpus, {GpuFamily::Rdna2, GpuFamily::Gcn5}, 2));
  for (auto [target, fam] : {std::pair{CostTarget::Rdna, GpuFamily::Rdna2},
                             std::pair{CostTarget::Gcn, GpuFamily::Gcn5}}) {
    const auto cal = costCalibration(target);
    ASSERT_TRUE(cal.has_value());
    const CostModel m = CostModel::preset(target);
    double se = 0;
    int n = 0, within = 0;
    for (const auto& s : corpus) {
      const double v = s.measured[static_cast<int>(fam)];
      if (!(v > 0)) continue;  // folded to nothing by the compiler (cost_calibration.hpp)
      const double e = m.price(s.features) - v;
      se += e * e;
      within += std::fabs(e) <= cal->worst_abs;
      ++n;
    }
    ASSERT_GT(n, 100);
    const double rmse = std::sqrt(se / n);
    EXPECT_LE(rmse, 1.25 * cal->rmse) << toString(target) << ": held-out RMS error " << rmse;
    EXPECT_GE(within, n - n / 50) << toString(target) << ": " << n - within << " of " << n
                                  << " programs beyond the reported worst error " << cal->worst_abs;
  }
}

}  // namespace
}  // namespace lgp::emit
