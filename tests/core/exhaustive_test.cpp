// search.exhaustive: the enumeration's counts, its recovery of a small formula, its certificate
// and its config errors.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>

#include "lgp/config/config.hpp"
#include "lgp/io/result.hpp"
#include "lgp/search/exhaustive.hpp"
#include "test_tables.hpp"

namespace {

using namespace lgp;

template <class F>
Table table(int n, F f) {
  return test::gridTableOf(n, f, "x", "y", "f");
}

RunConfig config(std::vector<Op> ops, int max_ops) {
  RunConfig c;
  c.data.path = "t.csv";
  c.program.ops = ops;
  c.search.threads = 2;
  c.search.exhaustive.max_ops = max_ops;
  c.search.exhaustive.ops = std::move(ops);
  // Completion is under test, not speed: the default 60 s left the 4-operator size unfinished
  // in the sanitizer build (40x slower than Release). The time-budget test sets its own.
  c.search.exhaustive.seconds = 3600;
  return c;
}

TEST(Exhaustive, CountsOneOperatorExpressionsExactly) {
  // Leaves x, y and a free constant c. add and mul: unordered pairs, not both constants:
  // (c,x) (c,y) (x,x) (x,y) (y,y) = 5 each. sub: ordered pairs, not both constants, not
  // x - x or y - y: 9 - 1 - 2 = 6. neg: of x or y (neg c is a constant) = 2.
  const Table t = table(8, [](double x, double y) { return x + y; });
  auto r = exhaustiveSearch(config({Op::Add, Op::Mul, Op::Sub, Op::Neg}, 1), t);
  ASSERT_TRUE(r) << r.error();
  ASSERT_EQ(r->enumerated.size(), 2u);
  EXPECT_EQ(r->enumerated[1], 5u + 5u + 6u + 2u);
  EXPECT_EQ(r->complete_ops, 1);
  // x + y is among them: found exactly.
  EXPECT_LT(r->best_by_ops[1].obj.error, 1e-7);
}

TEST(Exhaustive, ATreeEqualToAnEarlierOneIsDropped) {
  // mul and square over x, y and c: mul(x, x) and mul(y, y) are square(x) and square(y), so
  // 5 + 2 - 2 distinct expressions (the names told them apart before: 7).
  const Table t = table(8, [](double x, double y) { return x * y; });
  auto r = exhaustiveSearch(config({Op::Mul, Op::Square}, 2), t);
  ASSERT_TRUE(r) << r.error();
  ASSERT_GE(r->enumerated.size(), 3u);
  EXPECT_EQ(r->enumerated[1], 5u);
  // Size 2 holds no tree equal to a size-1 one: mul(x, mul(x, c)) would be a new function,
  // square(square(x)) too, but mul(c, square(x)) and mul(x, mul(c, x)) are one.
  auto shallow = exhaustiveSearch(config({Op::Mul}, 2), t);
  ASSERT_TRUE(shallow) << shallow.error();
  // mul over x, y, c: size 1 = (c,x) (c,y) (x,x) (x,y) (y,y); size 2 = the products of three
  // leaves with at most 2 constants: x^3, x^2 y, x y^2, y^3, c x^2, c x y, c y^2, c c x, c c y
  // (c c x and c x are different parameter counts but one function family; they stay apart:
  // only equal values merge).
  EXPECT_EQ(shallow->enumerated[1], 5u);
  EXPECT_EQ(shallow->enumerated[2], 9u);
}

TEST(Exhaustive, WithLinearScalingOneTreePerAffineClassIsFitted) {
  // add, mul, neg over x, y, c. Size 1: add 5, mul 5, neg 2 = 12 distinct functions. Up to
  // a f + b they are x (x + c, c x, x + x, -x), y (likewise), x + y, x^2, x y, y^2: 6 fitted.
  const Table t = table(8, [](double x, double y) { return x * y; });
  RunConfig c = config({Op::Add, Op::Mul, Op::Neg}, 1);
  auto plain = exhaustiveSearch(c, t);
  ASSERT_TRUE(plain) << plain.error();
  EXPECT_EQ(plain->enumerated[1], 12u);
  EXPECT_EQ(plain->screened[1], 12u);
  c.search.linear_scaling = true;
  auto scaled = exhaustiveSearch(c, t);
  ASSERT_TRUE(scaled) << scaled.error();
  EXPECT_EQ(scaled->enumerated[1], 12u);
  EXPECT_EQ(scaled->screened[1], 6u);
  EXPECT_LT(scaled->best_by_ops[1].obj.error, 1e-6) << scaled->best_by_ops[1].formula;
}

TEST(Exhaustive, AKinkOutsideTheBoxAtTheProbeConstantsIsNotMerged) {
  // On x in [100, 101], min(x, c) at any probe value of c (|c| <= 16) is the constant c, yet
  // c = 100.5 puts its kink inside the box: it must be fitted, and it fits exactly.
  Table t = test::gridTableOf(
      16, [](double x, double) { return std::min(x, 100.5); }, "x", "y", "f");
  for (auto& v : t.inputs[0]) v = 100 + v;
  for (size_t r = 0; r < t.rows(); ++r) t.outputs[0][r] = std::min(t.inputs[0][r], 100.5);
  t.inputs.pop_back();
  t.input_names.pop_back();
  RunConfig c = config({Op::Min}, 1);
  c.search.exhaustive.constants = 1;
  auto r = exhaustiveSearch(c, t);
  ASSERT_TRUE(r) << r.error();
  EXPECT_EQ(r->enumerated[1], 1u);
  EXPECT_LT(r->best_by_ops[1].obj.error, 1e-3) << r->best_by_ops[1].formula;
}

TEST(Exhaustive, RecoversExp2OfAQuadraticAtFourOperatorsAndNotBefore) {
  const Table t = table(16, [](double x, double y) { return std::exp2(-7 * x - 4 * y * y); });
  auto r = exhaustiveSearch(config({Op::Add, Op::Mul, Op::Mad, Op::Square, Op::Exp2}, 4), t);
  ASSERT_TRUE(r) << r.error();
  ASSERT_EQ(r->complete_ops, 4);
  // exp2(mad(x, c, c * y^2)) needs square, mul, mad and exp2.
  EXPECT_LT(r->best_by_ops[4].obj.error, 1e-6) << r->best_by_ops[4].formula;
  EXPECT_GT(r->best_by_ops[3].obj.error, 1e-3) << r->best_by_ops[3].formula;
  // The best error never grows with the operator budget, and the front is sorted by cost.
  for (size_t k = 2; k < r->best_by_ops.size(); ++k)
    EXPECT_LE(r->best_by_ops[k].obj.error, r->best_by_ops[k - 1].obj.error);
  for (size_t i = 1; i < r->front.size(); ++i) {
    EXPECT_LE(r->front[i - 1].obj.cost, r->front[i].obj.cost);
    EXPECT_GT(r->front[i - 1].obj.error, r->front[i].obj.error);
  }
  const auto j = r->toJson(config({Op::Mul, Op::Mad, Op::Square, Op::Exp2}, 4), t);
  EXPECT_EQ(j["complete_ops"], 4);
  ASSERT_EQ(j["best"].size(), 4u);
  EXPECT_EQ(j["best"][3]["max_ops"], 4);
  EXPECT_TRUE(j["best"][3]["complete"].get<bool>());
  EXPECT_TRUE(r->stopped.empty());
  EXPECT_TRUE(j["stopped"].is_null());
}

// The enumeration holds every distinct expression of a size at once; with no bound it ended in
// a bare std::bad_alloc after 2.1 GB under `ulimit -v 3000000` (hardening round 3, F13). It
// stops at its memory bound with what it has, and says so.
TEST(Exhaustive, StopsAtItsMemoryBoundWithTheSizesItCompleted) {
  const Table t = table(8, [](double x, double y) { return x * y + 0.5 * x; });
  RunConfig c = config({Op::Add, Op::Sub, Op::Mul, Op::Div, Op::Mad, Op::Exp2, Op::Sqrt}, 8);
  c.search.exhaustive.seconds = 600;
  const size_t bound = size_t{24} << 20;
  auto r = exhaustiveSearch(c, t, bound);
  ASSERT_TRUE(r) << r.error();
  EXPECT_EQ(r->stopped, "memory");
  EXPECT_GE(r->complete_ops, 2);
  EXPECT_LT(r->complete_ops, 8);
  ASSERT_EQ(r->best_by_ops.size(), static_cast<size_t>(r->complete_ops) + 1);
  EXPECT_TRUE(std::isfinite(r->best_by_ops.back().obj.error));
  const auto j = r->toJson(c, t);
  EXPECT_EQ(j["stopped"], "memory");
  // The front table says why the larger sizes are missing.
  const nlohmann::json front = {{"table", {{"inputs", {"x", "y"}}, {"outputs", {"f"}}}},
                                {"members", nlohmann::json::array()},
                                {"exhaustive", j}};
  EXPECT_NE(formatFrontTable(front).find("stopped by the memory bound after " +
                                         std::to_string(r->complete_ops) + " ops"),
            std::string::npos)
      << formatFrontTable(front);
  // Without a bound of its own it takes half of what the process may still allocate.
  EXPECT_GT(exhaustiveMemoryBudget(), size_t{0});
}

TEST(Exhaustive, TheFrontTableStatesTheCountsPerSize) {
  const Table t = table(8, [](double x, double y) { return x * y; });
  RunConfig c = config({Op::Add, Op::Mul, Op::Neg}, 1);
  c.search.linear_scaling = true;
  auto r = exhaustiveSearch(c, t);
  ASSERT_TRUE(r) << r.error();
  const nlohmann::json front = {{"table", {{"inputs", {"x", "y"}}, {"outputs", {"f"}}}},
                                {"members", nlohmann::json::array()},
                                {"exhaustive", r->toJson(c, t)}};
  const std::string text = formatFrontTable(front);
  EXPECT_NE(text.find("<= 1 ops: error"), std::string::npos) << text;
  EXPECT_NE(text.find("[12 distinct, 6 fitted]"), std::string::npos) << text;
  // A front written before the fitted count was recorded prints the distinct count alone.
  nlohmann::json old = front;
  old["exhaustive"]["best"][0].erase("screened");
  EXPECT_NE(formatFrontTable(old).find("[12 distinct]"), std::string::npos);
}

TEST(Exhaustive, ATimeBudgetLeavesTheRestIncomplete) {
  const Table t = table(16, [](double x, double y) { return std::exp2(-7 * x - 4 * y * y); });
  RunConfig c = config({Op::Add, Op::Sub, Op::Mul, Op::Div, Op::Mad, Op::Exp2, Op::Log2}, 5);
  c.search.exhaustive.seconds = 0.5;
  const auto t0 = std::chrono::steady_clock::now();
  auto r = exhaustiveSearch(c, t);
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_TRUE(r) << r.error();
  // The budget stops the enumeration too, not only the fits (a generous bound: the point is
  // that level 5, about 10^10 combinations, is never walked).
  EXPECT_LT(secs, 30.0);
  EXPECT_LT(r->complete_ops, 5);
  const auto j = r->toJson(c, t);
  EXPECT_EQ(j["complete_ops"], r->complete_ops);
  EXPECT_EQ(j["stopped"], "seconds");
  const nlohmann::json front = {{"table", {{"inputs", {"x", "y"}}, {"outputs", {"f"}}}},
                                {"members", nlohmann::json::array()},
                                {"exhaustive", j}};
  EXPECT_NE(formatFrontTable(front).find("stopped by the time budget after " +
                                         std::to_string(r->complete_ops) + " ops"),
            std::string::npos)
      << formatFrontTable(front);
}

TEST(Exhaustive, ConfigErrorsNameTheField) {
  auto parse = [](const char* text) { return parseRunConfig(nlohmann::json::parse(text), "."); };
  auto bad = parse(R"({"data": {"path": "t.csv"}, "search": {"exhaustive": {"max_ops": 9}}})");
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().find("/search/exhaustive/max_ops"), std::string::npos) << bad.error();
  bad = parse(R"({"data": {"path": "t.csv"}, "search": {"exhaustive": {"ops": ["select"]}}})");
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().find("/search/exhaustive/ops/0"), std::string::npos) << bad.error();
  bad = parse(R"({"data": {"path": "t.csv"}, "search": {"exhaustive": {"maxops": 2}}})");
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().find("/search/exhaustive/maxops"), std::string::npos) << bad.error();
  auto good = parse(
      R"({"data": {"path": "t.csv"}, "search": {"exhaustive": {"max_ops": 3, "ops": ["add"]}}})");
  ASSERT_TRUE(good) << good.error();
  EXPECT_EQ(toJson(*good)["search"]["exhaustive"]["max_ops"], 3);

  Table two = table(4, [](double x, double) { return x; });
  two.output_names.push_back("g");
  two.outputs.push_back(two.outputs[0]);
  auto r = exhaustiveSearch(config({Op::Add}, 1), two);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().find("/search/exhaustive: one output only"), std::string::npos);
}

}  // namespace
