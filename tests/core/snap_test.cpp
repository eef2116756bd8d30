// Constant snapping (lgp/core/snap.hpp): exp2(-7 mu - 4 r^2) data snaps a fitted member to the
// integers, the search's post-run pass puts the snapped twin on the front, and snapping never
// raises the error past its tolerance.
#include <gtest/gtest.h>

#include <random>

#include "lgp/core/formula.hpp"
#include "lgp/core/snap.hpp"
#include "lgp/io/result.hpp"
#include "lgp/search/search.hpp"
#include "test_tables.hpp"

namespace lgp {
namespace {

constexpr auto X = inputOperand;
constexpr auto C = constOperand;
constexpr auto R = regOperand;

// examples/quickstart.csv: B = exp2(-7 mu - 4 r^2) on a 32 x 32 grid of (0, 1)^2.
Table quickstart() {
  auto raw = readTableFile(std::filesystem::path(LGP_SOURCE_DIR) / "examples" / "quickstart.csv");
  EXPECT_TRUE(raw.hasValue()) << raw.error();
  auto t = selectColumns(*raw, {"mu", "r"}, {"B"}, "", "quickstart.csv");
  EXPECT_TRUE(t.hasValue()) << t.error();
  return *t;
}

// exp2(mad(c0, mu, mad(c1, r^2, c2))), the shape the quickstart search recovers.
Program fitted(float c0, float c1, float c2) {
  Program p;
  p.code = {Instr{Op::Square, {X(1)}}, Instr{Op::Mad, {C(1), R(0), C(2)}},
            Instr{Op::Mad, {C(0), X(0), R(1)}}, Instr{Op::Exp2, {R(2)}}};
  p.constants = {c0, c1, c2};
  p.outputs = {3};
  return p;
}

TEST(Snap, QuickstartDataIsExp2OfMinus7MuMinus4RSquared) {
  const Table t = quickstart();
  ASSERT_EQ(t.rows(), 1024u);
  for (size_t r = 0; r < t.rows(); ++r) {
    const double mu = t.inputs[0][r], rr = t.inputs[1][r];
    ASSERT_NEAR(t.outputs[0][r], std::exp2(-7 * mu - 4 * rr * rr), 1e-12);
  }
}

TEST(Snap, CandidatesStartSimple) {
  EXPECT_EQ(snapCandidates(1.0195341e-08f)[0], 0.0f);
  const auto c = snapCandidates(-6.9999f);
  ASSERT_GE(c.size(), 2u);
  EXPECT_EQ(c[1], -7.0f);
  const auto third = snapCandidates(0.33333f);
  EXPECT_NE(std::find(third.begin(), third.end(), 1.0f / 3.0f), third.end());
  const auto dec = snapCandidates(0.73912f);
  EXPECT_NE(std::find(dec.begin(), dec.end(), 0.74f), dec.end());
}

TEST(Snap, FittedQuickstartMemberSnapsToTheIntegers) {
  const Table t = quickstart();
  const Dataset ds(t, 256);
  Scorer s(ds, ErrorConfig{}, 256);
  const Program p = fitted(-6.9999f, -4.0001f, 1.0195341e-08f);
  const auto r = snapConstants(p, [&](const Program& q) { return s.error(q); });
  EXPECT_EQ(r.snapped, 3);
  EXPECT_EQ(r.program.constants, (std::vector<float>{-7.0f, -4.0f, 0.0f}));
  EXPECT_LE(r.error_after, r.error_before * (1 + kSnapTolerance));
  EXPECT_EQ(programFormula(r.program, t.input_names, t.output_names, tableDomain(t)),
            "B = exp2(-7*mu - 4*r^2)");
  // Exact up to rounding (the quickstart run's member: error 4.7e-9), its 1e-8 constant is
  // rounding noise: the relative tolerance alone keeps it, the float32 floor snaps it to 0.
  const Program exact = fitted(-7.0f, -4.0f, 1.050774e-08f);
  const auto rel = snapConstants(exact, [&](const Program& q) { return s.error(q); });
  EXPECT_NE(rel.program.constants[2], 0.0f);
  SnapOptions floor;
  floor.abs_floor = float32ErrorFloor(ErrorConfig{}, t);
  EXPECT_GT(floor.abs_floor, 1e-9);
  const auto abs = snapConstants(
      exact, [&](const Program& q) { return s.error(q); }, floor);
  EXPECT_EQ(abs.program.constants[2], 0.0f);
  EXPECT_LE(abs.error_after, abs.error_before + floor.abs_floor);
  // An exact member stays as it is.
  const auto again = snapConstants(r.program, [&](const Program& q) { return s.error(q); });
  EXPECT_EQ(again.snapped, 0);
  EXPECT_EQ(again.program, r.program);
}

// A run seeded with the fitted member (no refinement, so its constants stay off by 1e-4): the
// post-run pass offers the snapped twin, which is more accurate at the same cost and replaces
// it on the front.
TEST(Snap, PostRunPassPutsTheSnappedTwinOnTheFront) {
  RunConfig c;
  c.data.path = "in-memory";
  c.search.population = 40;
  c.search.generations = 1;
  c.search.threads = 1;
  c.search.refine.offspring_share = 0;
  c.search.refine.archive_period = 0;
  c.program.max_length = 8;
  c.program.num_constants = 4;
  // Off: its exp2 fit over (mu, r^2) is the exact formula, which would leave nothing to snap.
  c.search.structured.max_degree = 0;
  Search s(c, quickstart());
  ASSERT_TRUE(s.addSeeds({{"fitted", fitted(-6.9999f, -4.0001f, 1.0195341e-08f)}}).empty());
  s.run();
  auto has = [](const nlohmann::json& members, const std::string& f) {
    for (const auto& m : members)
      if (m["formula"] == f) return true;
    return false;
  };
  const auto with = frontToJson(s, s.front())["members"];
  EXPECT_TRUE(has(with, "B = exp2(-7*mu - 4*r^2)")) << with.dump(1);
  s.setSnapTwins(false);
  const auto without = frontToJson(s, s.front())["members"];
  EXPECT_FALSE(has(without, "B = exp2(-7*mu - 4*r^2)"));
  EXPECT_TRUE(has(without, "B = exp2(1.0195341e-08 - 4.0001*r^2 - 6.9999*mu)")) << without.dump(1);
}

// For random programs and constants, under several tolerances: the snapped error is within the
// tolerance of the original, and is the error of the program returned.
TEST(Snap, NeverRaisesTheErrorPastItsTolerance) {
  const Table t = test::gridTable(10);
  const Dataset ds(t, 256);
  Scorer s(ds, ErrorConfig{}, 256);
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> cd(-3, 3);
  int snapped = 0, checked = 0;
  for (int i = 0; i < 200; ++i) {
    Program p;
    const Op ops[] = {Op::Add, Op::Mul, Op::Mad, Op::Exp2, Op::Sub, Op::Div, Op::Min, Op::Square};
    const int len = 2 + i % 6;
    for (int k = 0; k < len; ++k) {
      Instr in;
      in.op = ops[(i * 7 + k * 3) % 8];
      for (int a = 0; a < arity(in.op); ++a) {
        const int kind = static_cast<int>(rng() % 3);
        in.args[a] = kind == 0 || k == 0 ? (rng() % 2 ? X(rng() % 2) : C(rng() % 3))
                     : kind == 1         ? C(rng() % 3)
                                         : R(rng() % k);
      }
      p.code.push_back(in);
    }
    p.constants = {cd(rng), cd(rng), cd(rng)};
    if (i % 3 == 0) p.constants[0] = std::nearbyint(p.constants[0]) + 1e-4f;  // nearly simple
    p.outputs = {static_cast<uint8_t>(len - 1)};
    for (double tol : {0.0, 1e-3, 1e-2, 0.1}) {
      SnapOptions o;
      o.tolerance = tol;
      o.abs_floor = tol * 1e-3;  // an absolute allowance too
      const auto r = snapConstants(
          p, [&](const Program& q) { return s.error(q); }, o);
      if (!std::isfinite(r.error_before)) continue;
      ++checked;
      snapped += r.snapped > 0;
      ASSERT_LE(r.error_after, r.error_before + std::max(tol * r.error_before, o.abs_floor))
          << "program " << i << " tol " << tol;
      ASSERT_EQ(s.error(r.program), r.error_after) << "program " << i;
    }
  }
  EXPECT_GT(checked, 400);
  EXPECT_GT(snapped, 50);  // the property is not vacuous
}

}  // namespace
}  // namespace lgp
