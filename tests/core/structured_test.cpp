// The structured accurate end (search/structured.hpp): the families recover what they can
// express, are written in Horner form, never carry a pole onto the table's domain, and reach
// the archive at the start of a search.
#include <gtest/gtest.h>

#include <omp.h>

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

// The root mean square of program - y over the table's rows.
double rmsError(const Program& p, const Table& t) {
  Dataset ds(t, 256);
  Interpreter in(256);
  const auto v = in.evaluate(p, ds);
  double e = 0;
  for (size_t r = 0; r < t.rows(); ++r) e += std::pow(v[0][r] - t.outputs[0][r], 2);
  return std::sqrt(e / static_cast<double>(t.rows()));
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

// Every rational of `fits` stays within 50 times the table's largest |y| on `sweep`.
void expectBounded(const std::vector<StructuredFit>& fits, const Table& t, const Table& sweep) {
  double table_max = 0;
  for (double y : t.outputs[0]) table_max = std::max(table_max, std::fabs(y));
  int rationals = 0;
  for (const auto& f : fits) {
    if (f.family.rfind("rational", 0) != 0) continue;
    ++rationals;
    Dataset ds(sweep, 256);
    Interpreter in(256);
    const auto v = in.evaluate(f.program, ds);
    for (float y : v[0]) ASSERT_LE(std::fabs(y), 50 * table_max) << f.family;
  }
  EXPECT_GT(rationals, 0);
}

TEST(Structured, NoRationalKeepsAPoleOnTheDomain) {
  // 1 / (x - 0.53): finite at every grid point, a pole between two of them. Any rational the
  // fitter keeps must stay bounded on a dense sweep of the domain.
  const Table t = test::gridTableOf(10, [](double x, double) { return 1 / (x - 0.53); });
  // 400 x 400 points over the table's domain, [0.05, 0.95] on each axis.
  Table dense = test::gridTableOf(400, [](double, double) { return 0.0; });
  for (auto& col : dense.inputs)
    for (double& v : col) v = 0.05 + 0.9 * (v - 0.00125) / 0.9975;
  // (Without the check, rational 1/1 puts its pole at 0.53 and fits the grid exactly.)
  expectBounded(fitsOf(structuredOnly(3), t), t, dense);
  // x + 0.01 / (x - 0.53), exactly rational 2/1: its spike is so narrow that no sampled point
  // of the domain box (64 per axis) sees more than 2, within the table's range widened by its
  // span. Only the Bernstein proof over the whole domain refuses the pole.
  const Table narrow =
      test::gridTableOf(10, [](double x, double) { return x + 0.01 / (x - 0.53); });
  Table sweep = test::gridTableOf(100, [](double, double) { return 0.0; });
  for (double& v : sweep.inputs[0]) v = 0.52 + 0.02 * v;  // x within 1e-4 of 0.53, and closer
  expectBounded(fitsOf(structuredOnly(3), narrow), narrow, sweep);
}

TEST(Structured, MaterialXsDfgFamilyIsRecovered) {
  // B of MaterialX's GGX albedo fit: a ratio of polynomials of degree 2 in each of x = n.v
  // and y = r^2, which no total-degree family over (mu, r) or their roots expresses within
  // 48 slots.
  const auto fit = [](double x, double r) {
    const double y = r * r;
    const double num =
        (0.9345 + x * (-2.323 + 1.424 * x)) +
        y * ((2.229 + x * (-3.748 + 1.436 * x)) + y * (-0.7684 + x * (0.2913 + 0.6286 * x)));
    const double den = (1 + x * (0.2281 + 13.08 * x)) + y * ((15.94 + x * (-55.83 + 54.9 * x)) +
                                                             y * (41.26 + x * (300.2 - 285.1 * x)));
    return num / den;
  };
  const Table t = test::gridTableOf(32, fit);
  RunConfig c = structuredOnly(2);
  c.search.structured.square_inputs = true;
  const auto fits = fitsOf(c, t);
  const StructuredFit* f = family(fits, "rational tensor 2/2 (mu, r^2)");
  ASSERT_NE(f, nullptr);
  EXPECT_EQ(f->coefficients, 18);
  EXPECT_LT(maxError(f->program, t), 1e-4);
  // Off: no tensor family, no squared feature.
  c.search.structured.tensor = false;
  c.search.structured.square_inputs = false;
  for (const auto& g : fitsOf(c, t)) {
    EXPECT_EQ(g.family.find("tensor"), std::string::npos) << g.family;
    EXPECT_EQ(g.family.find("^2"), std::string::npos) << g.family;
  }
}

TEST(Structured, ThePolishBeatsTheLinearisedFitAndTheFitsDoNotDependOnThreads) {
  // A smooth target no low-degree rational matches exactly: Levenberg-Marquardt on P/Q - y
  // must not end worse than the linearised fit alone (polish 0), and one thread or four give
  // the same programs.
  const Table t = test::gridTableOf(24, [](double x, double y) {
    return std::exp(-3 * x * y) / (1 + x) + 0.2 * std::sqrt(y + 0.05);
  });
  RunConfig c = structuredOnly(3);
  const ProgramShape shape = c.shape(2, 1);
  const int threads_before = omp_get_max_threads();
  const auto one = structuredFits(c, t, shape, tableDomain(t), 1);
  const auto four = structuredFits(c, t, shape, tableDomain(t), 4);
  // Each fitting task pins Eigen to one thread; the caller's setting is left as it was.
  EXPECT_EQ(omp_get_max_threads(), threads_before);
  ASSERT_EQ(one.size(), four.size());
  for (size_t i = 0; i < one.size(); ++i) {
    EXPECT_EQ(one[i].family, four[i].family);
    EXPECT_TRUE(one[i].program == four[i].program) << one[i].family;
  }
  c.search.structured.polish = 0;
  const auto raw = structuredFits(c, t, shape, tableDomain(t), 1);
  int compared = 0;
  for (const auto& r : raw) {
    if (r.family.rfind("rational", 0) != 0) continue;
    const StructuredFit* p = family(one, r.family);
    ASSERT_NE(p, nullptr) << r.family;  // the polish keeps every family the linearised fit had
    EXPECT_LE(rmsError(p->program, t), rmsError(r.program, t) * (1 + 1e-3)) << r.family;
    ++compared;
  }
  EXPECT_GT(compared, 0);
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
