// The structured accurate end (search/structured.hpp): the families recover what they can
// express, are written in Horner form, never carry a pole onto the table's domain, and reach
// the archive at the start of a search.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>

#include "lgp/eval/interpreter.hpp"
#include "lgp/io/result.hpp"
#include "lgp/search/search.hpp"
#include "lgp/search/structured.hpp"
#include "test_tables.hpp"

namespace lgp {
namespace {

RunConfig structuredOnly(int degree) {
  RunConfig c;
  c.data.path = "in-memory";
  c.search.structured.max_degree = degree;
  c.search.structured.sqrt_inputs = false;
  return c;
}

std::vector<StructuredFit> fitsOf(const RunConfig& c, const Table& t) {
  const ProgramShape shape = c.shape(static_cast<int>(t.numInputs()), 1);
  return structuredFits(c, t, shape, tableDomain(t));
}

// The largest |program - y| over the table's rows (float32 interpreter).
double maxError(const Program& p, const Table& t) {
  Dataset ds(t, 256);
  Interpreter in(256);
  const auto v = in.evaluate(p, ds);
  double e = 0;
  for (size_t r = 0; r < t.rows(); ++r) e = std::max(e, std::fabs(v[0][r] - t.outputs[0][r]));
  return e;
}

const StructuredFit* family(const std::vector<StructuredFit>& fits, const std::string& name) {
  for (const auto& f : fits)
    if (f.family == name) return &f;
  return nullptr;
}

TEST(Structured, APolynomialIsRecoveredInHornerForm) {
  const Table t = test::gridTableOf(
      12, [](double x, double y) { return 0.3 + 0.5 * x - 0.2 * x * y + 0.7 * y * y * y; });
  const auto fits = fitsOf(structuredOnly(3), t);
  const StructuredFit* p3 = family(fits, "poly 3 (mu, r)");
  ASSERT_NE(p3, nullptr);
  EXPECT_EQ(p3->coefficients, 10);
  // One mad per coefficient but the leading one: nested Horner, no power evaluated twice.
  EXPECT_EQ(p3->program.code.size(), 9u);
  EXPECT_LT(maxError(p3->program, t), 1e-6);
  // A lower degree cannot: the fit is least squares, not interpolation.
  const StructuredFit* p2 = family(fits, "poly 2 (mu, r)");
  ASSERT_NE(p2, nullptr);
  EXPECT_GT(maxError(p2->program, t), 1e-3);
}

TEST(Structured, ARationalAndAnExponentialAreRecovered) {
  const Table rat =
      test::gridTableOf(12, [](double x, double y) { return (1 + 2 * x) / (1 + 0.5 * y); });
  const auto fits = fitsOf(structuredOnly(2), rat);
  const StructuredFit* r11 = family(fits, "rational 1/1 (mu, r)");
  ASSERT_NE(r11, nullptr);
  EXPECT_LT(maxError(r11->program, rat), 1e-5);
  const Table ex =
      test::gridTableOf(12, [](double x, double y) { return std::exp2(x - 2 * x * y); });
  const auto exp_fits = fitsOf(structuredOnly(2), ex);
  const StructuredFit* e2 = family(exp_fits, "exp2 poly 2 (mu, r)");
  ASSERT_NE(e2, nullptr);
  EXPECT_LT(maxError(e2->program, ex), 1e-5);
}

TEST(Structured, NoRationalKeepsAPoleOnTheDomain) {
  // 1 / (x - 0.53): finite at every grid point, a pole between two of them. Any rational the
  // fitter keeps must stay bounded on a dense sweep of the domain.
  const Table t = test::gridTableOf(10, [](double x, double) { return 1 / (x - 0.53); });
  const auto fits = fitsOf(structuredOnly(3), t);
  Table dense = test::gridTableOf(400, [](double, double) { return 0.0; });
  double table_max = 0;
  for (double y : t.outputs[0]) table_max = std::max(table_max, std::fabs(y));
  // (Without the check, rational 1/1 puts its pole at 0.53 and fits the grid exactly.)
  for (const auto& f : fits) {
    if (f.family.rfind("rational", 0) != 0) continue;
    Dataset ds(dense, 256);
    Interpreter in(256);
    const auto v = in.evaluate(f.program, ds);
    for (float y : v[0]) ASSERT_LE(std::fabs(y), 50 * table_max) << f.family;
  }
}

TEST(Structured, TheSqrtFeaturesAreOneOpcodeEach) {
  const Table t = test::gridTableOf(10, [](double x, double y) { return std::sqrt(x) + y; });
  RunConfig c = structuredOnly(1);
  c.search.structured.sqrt_inputs = true;
  const auto fits = fitsOf(c, t);
  const StructuredFit* f = family(fits, "poly 1 (sqrt mu, r)");
  ASSERT_NE(f, nullptr);
  EXPECT_LT(maxError(f->program, t), 1e-5);
  int roots = 0;
  for (const Instr& in : f->program.code) roots += in.op == Op::Sqrt;
  EXPECT_EQ(roots, 1);
}

TEST(Structured, ManyInputsStayWithinTheConstantBudgetAndFinishAtOnce) {
  // 30 inputs: degree 8 would be C(38, 8) = 4.9e7 monomials and the pole-check grid 6^30
  // points; neither may be listed. Degree 1 (31 coefficients) fits 48 slots, degree 2 does not.
  Table t;
  Rng rng(3);
  for (int i = 0; i < 30; ++i) t.input_names.push_back("x" + std::to_string(i));
  t.output_names = {"y"};
  t.inputs.assign(30, {});
  t.outputs.assign(1, {});
  for (int r = 0; r < 200; ++r) {
    double y = 0.5;
    for (int i = 0; i < 30; ++i) {
      const double x = rng.uniform();
      t.inputs[i].push_back(x);
      y += 0.01 * (i + 1) * x;
    }
    t.outputs[0].push_back(y);
  }
  const auto t0 = std::chrono::steady_clock::now();
  const auto fits = fitsOf(structuredOnly(8), t);
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 10.0);
  // poly 1 and exp2 poly 1 (y > 0), nothing of degree 2 or rational.
  ASSERT_EQ(fits.size(), 2u);
  const StructuredFit* p1 = nullptr;
  for (const auto& f : fits) {
    EXPECT_TRUE(f.family.rfind("poly 1 (x0, x1", 0) == 0 ||
                f.family.rfind("exp2 poly 1 (x0", 0) == 0)
        << f.family;
    if (f.family.rfind("poly 1", 0) == 0) p1 = &f;
  }
  ASSERT_NE(p1, nullptr);
  EXPECT_EQ(p1->coefficients, 31);
  EXPECT_LT(maxError(p1->program, t), 1e-5);
}

TEST(Structured, TheFitsReachTheArchiveAtTheStart) {
  const Table t = test::gridTableOf(
      12, [](double x, double y) { return 0.3 + 0.5 * x - 0.2 * x * y + 0.7 * y * y * y; });
  RunConfig c = structuredOnly(4);
  c.search.population = 40;
  c.search.threads = 1;
  Search s(c, t);
  s.initialize();
  double best = INFINITY;
  for (const auto& m : s.archiveMembers()) best = std::min(best, m.obj.error);
  EXPECT_LT(best, 1e-6);
  const auto& info = s.structuredInfo();
  ASSERT_TRUE(info.is_object());
  EXPECT_GT(info["fits"].get<int>(), 0);
  EXPECT_GT(info["archived"].get<int>(), 0);
  // Off: generation 0 is random programs only.
  c.search.structured.max_degree = 0;
  Search off(c, t);
  off.initialize();
  double best_off = INFINITY;
  for (const auto& m : off.archiveMembers()) best_off = std::min(best_off, m.obj.error);
  EXPECT_GT(best_off, 1e-4);
  EXPECT_TRUE(off.structuredInfo().is_null());
}

}  // namespace
}  // namespace lgp
