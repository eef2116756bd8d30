// The evaluation budget counts what constant fitting costs: a Levenberg-Marquardt Jacobian pass
// over n constants is 1 + n program evaluations (values plus a derivative column per constant,
// the work of a finite-difference Jacobian), a residual pass is 1.
#include <gtest/gtest.h>

#include <cmath>

#include "lgp/search/levenberg_marquardt.hpp"
#include "test_tables.hpp"

namespace lgp {
namespace {

// c0 + c1 x + ... + c_{n-1} x^{n-1} by Horner's rule: linear in its n constants.
Program polynomial(int n) {
  Program p;
  p.constants.assign(n, 3.0f);
  p.code.push_back({Op::Mul, {inputOperand(0), constOperand(n - 1)}});
  for (int d = n - 2; d >= 0; --d) {
    const int prev = static_cast<int>(p.code.size()) - 1;
    p.code.push_back({Op::Add, {regOperand(prev), constOperand(d)}});
    if (d > 0)
      p.code.push_back(
          {Op::Mul, {regOperand(static_cast<int>(p.code.size()) - 1), inputOperand(0)}});
  }
  p.outputs = {static_cast<uint8_t>(p.code.size() - 1)};
  return p;
}

Table cubicTable() {
  return test::sampledTable(400, 5, [](double x) { return 0.5 - x + 0.25 * x * x * x; });
}

// One iteration on a problem linear in its constants: the starting residual pass, one Jacobian
// pass and one accepted trial step, so 1 + (1 + n) + 1 evaluations (it used to be 3 for any n).
TEST(LmEvaluations, AJacobianPassCountsOnePlusTheConstants) {
  const Table t = cubicTable();
  const Dataset ds(t, 256);
  ConstantFitter fitter(ds, ErrorConfig{});
  for (int n = 1; n <= 6; ++n) {
    Program p = polynomial(n);
    LevenbergMarquardtConfig lm;
    lm.max_iterations = 1;
    const ConstantFitResult res = fitter.fit(p, lm);
    ASSERT_EQ(res.iterations, 1) << n << " constants";
    EXPECT_TRUE(res.improved) << n << " constants";
    EXPECT_EQ(res.evaluations, 1 + (1 + n) + 1) << n << " constants";
  }
}

}  // namespace
}  // namespace lgp
