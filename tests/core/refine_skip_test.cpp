// Offspring refinement spends no Nelder-Mead evaluations where Levenberg-Marquardt has
// converged on the error the search measures: clones of a program whose constants are at the
// optimum cost their score and one short LM run, not a 60-evaluation simplex polish.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "clone_generation.hpp"
#include "lgp/search/search.hpp"

namespace lgp {
namespace {

// Evaluations of one generation of clones (no crossover, no mutation), every one refined.
uint64_t cloneGeneration(ErrorMetric metric, LmObjective lm = LmObjective::Configured) {
  RunConfig c = test::cloneConfig();
  c.objectives.metric = metric;
  c.search.refine.offspring_evaluations = 60;
  c.search.refine.lm_metric = lm;
  Search s(c, test::lineTable());
  test::stepClones(s);
  return s.progress().evaluations;
}

TEST(RefineSkip, ConvergedLmSkipsNelderMeadOnRmse) {
  const uint64_t per_offspring = cloneGeneration(ErrorMetric::Rmse) / 40;
  // Score 1, LM: the starting residual pass, a Jacobian pass over 2 constants (3) and a trial
  // step, so 6; the Nelder-Mead polish it used to get made that 67.
  std::printf("rmse: %llu evaluations per clone\n", static_cast<unsigned long long>(per_offspring));
  EXPECT_LE(per_offspring, 12u);
}

// LM on the configured error converges on it for every metric: the polish is skipped there too
// (score, the starting error, LM's passes and one round's check: about 10). Plain least
// squares does not fit max_abs, so with lm_metric least_squares the polish still runs.
TEST(RefineSkip, ConvergedLmSkipsNelderMeadOnEveryMetric) {
  for (ErrorMetric m : {ErrorMetric::MaxAbs, ErrorMetric::Mae, ErrorMetric::MeanRel}) {
    const uint64_t per_offspring = cloneGeneration(m) / 40;
    std::printf("%s: %llu evaluations per clone\n", std::string(toString(m)).c_str(),
                static_cast<unsigned long long>(per_offspring));
    EXPECT_LE(per_offspring, 16u) << toString(m);
  }
  const uint64_t least_squares = cloneGeneration(ErrorMetric::MaxAbs, LmObjective::LeastSquares);
  std::printf("max_abs, least squares: %llu evaluations per clone\n",
              static_cast<unsigned long long>(least_squares / 40));
  EXPECT_GT(least_squares / 40, 20u);
}

}  // namespace
}  // namespace lgp
