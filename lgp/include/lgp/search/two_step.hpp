// The two-step multi-output mode (fit "B" first, then "A"
// with B's chosen expression available as an input).
//
//   1. Search `first` alone (per-output error), spending `first_share` of every budget.
//   2. Pick one member of that front: the most accurate of cost <= first_max_cost, or, when
//      that is 0, the knee (the member closest to the utopia point after scaling log10(error)
//      and cost to [0, 1] over the front).
//   3. Evaluate the pick in float32 (what the shader computes) and add it to the table as the
//      input column "<first>_fit"; search the other outputs over the extended inputs.
//   4. Every member of the second front becomes one program computing all outputs: the
//      pick's opcodes followed by the member's, its "<first>_fit" operand rewired to the
//      pick's result. Those programs are scored on the original table with the run's error
//      (channels included) and form the result front; the shared sub-expression costs once.
// Step 2 fits its outputs' own targets: channels that mix outputs apply to the assembled
// programs, not inside step 2.
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "lgp/config/config.hpp"
#include "lgp/core/table.hpp"
#include "lgp/search/search.hpp"

namespace lgp {

class TwoStepSearch {
 public:
  TwoStepSearch(RunConfig cfg, Table table);
  ~TwoStepSearch();
  // Runs both steps and assembles the result (`result()`). on_progress gets each step's
  // progress; SearchProgress::stop_reason is prefixed with the step ("step 1: ...").
  void run(const std::function<void(int step, const SearchProgress&)>& on_progress = {});
  void requestStop();

  // The assembled search (all outputs): front(), progress(), config() and table() as usual.
  const Search& result() const { return *result_; }
  // The first-step pick and its input column name.
  const Program& pick() const { return pick_; }
  const std::string& pickColumn() const { return pick_column_; }
  // The table of step 2 (inputs + the pick's column; the other outputs).
  const Table& secondTable() const { return second_table_; }

 private:
  RunConfig cfg_;
  Table table_;
  std::unique_ptr<Search> step_;  // the step running now (for requestStop)
  std::unique_ptr<Search> result_;
  Program pick_;
  std::string pick_column_;
  Table second_table_;
  std::atomic<bool> stop_{false};
};

// Index of the member picked from a front (see step 2 above); -1 for an empty front.
int pickMember(const std::vector<FrontEntry>& front, double max_cost);

// One program computing every output: `first` (one output, over the original inputs) feeds
// input column `num_inputs` of `rest` (over num_inputs + 1 inputs). Output `first_index` of
// the result is first's output; the others are rest's, in order.
Program composeTwoStep(const Program& first, const Program& rest, int num_inputs, int first_index);

}  // namespace lgp
