#include "lgp/search/two_step.hpp"

#include <algorithm>
#include <cmath>

#include "lgp/eval/interpreter.hpp"

namespace lgp {

namespace {
// A budget share, never rounding a set budget down to "unlimited" (0).
template <class T>
T share(T budget, double f) {
  if (budget == 0) return 0;
  return std::max<T>(1, static_cast<T>(static_cast<double>(budget) * f));
}

Table withOutputs(const Table& t, const std::vector<size_t>& outs) {
  Table r;
  r.input_names = t.input_names;
  r.inputs = t.inputs;
  r.weights = t.weights;
  r.meta = t.meta;
  for (size_t o : outs) {
    r.output_names.push_back(t.output_names[o]);
    r.outputs.push_back(t.outputs[o]);
  }
  return r;
}
}  // namespace

int pickMember(const std::vector<FrontEntry>& front, double max_cost) {
  int best = -1;
  if (max_cost > 0) {
    for (int i = 0; i < static_cast<int>(front.size()); ++i)
      if (front[i].obj.finite() && front[i].obj.cost <= max_cost &&
          (best < 0 || front[i].obj.error < front[best].obj.error))
        best = i;
    if (best >= 0) return best;  // else: nothing that cheap, fall back to the knee
  }
  double lo_e = INFINITY, hi_e = -INFINITY, lo_c = INFINITY, hi_c = -INFINITY;
  for (const auto& m : front) {
    if (!m.obj.finite()) continue;
    const double le = std::log10(std::max(m.obj.error, 1e-300));
    lo_e = std::min(lo_e, le);
    hi_e = std::max(hi_e, le);
    lo_c = std::min(lo_c, m.obj.cost);
    hi_c = std::max(hi_c, m.obj.cost);
  }
  double best_d = INFINITY;
  for (int i = 0; i < static_cast<int>(front.size()); ++i) {
    const auto& m = front[i];
    if (!m.obj.finite()) continue;
    const double le = std::log10(std::max(m.obj.error, 1e-300));
    const double e = hi_e > lo_e ? (le - lo_e) / (hi_e - lo_e) : 0;
    const double c = hi_c > lo_c ? (m.obj.cost - lo_c) / (hi_c - lo_c) : 0;
    const double d = e * e + c * c;
    if (d < best_d) {
      best_d = d;
      best = i;
    }
  }
  return best;
}

Program composeTwoStep(const Program& first, const Program& rest, int num_inputs, int first_index) {
  Program p;
  p.code = first.code;
  p.constants = first.constants;
  const int len1 = static_cast<int>(first.code.size());
  const int nc1 = static_cast<int>(first.constants.size());
  const uint8_t fed = first.outputs.at(0);
  for (Instr in : rest.code) {
    for (int a = 0; a < arity(in.op); ++a) {
      Operand& o = in.args[a];
      if (o.kind == OperandKind::Var && o.index == num_inputs)
        o = regOperand(fed);
      else if (o.kind == OperandKind::Reg)
        o.index = static_cast<uint8_t>(o.index + len1);
      else if (o.kind == OperandKind::Const)
        o.index = static_cast<uint8_t>(o.index + nc1);
    }
    p.code.push_back(in);
  }
  p.constants.insert(p.constants.end(), rest.constants.begin(), rest.constants.end());
  const int k = static_cast<int>(rest.outputs.size()) + 1;
  for (int o = 0, r = 0; o < k; ++o)
    p.outputs.push_back(o == first_index ? fed : static_cast<uint8_t>(len1 + rest.outputs[r++]));
  return p;
}

TwoStepSearch::TwoStepSearch(RunConfig cfg, Table table)
    : cfg_(std::move(cfg)), table_(std::move(table)) {}

TwoStepSearch::~TwoStepSearch() = default;

void TwoStepSearch::requestStop() {
  stop_.store(true);
  // The step pointer is only replaced between steps, by the thread running run().
  if (step_) step_->requestStop();
}

void TwoStepSearch::run(const std::function<void(int, const SearchProgress&)>& on_progress) {
  const auto& mo = cfg_.search.multi_output;
  const size_t n_in = table_.numInputs();
  size_t first = 0;
  std::vector<size_t> others;
  for (size_t o = 0; o < table_.numOutputs(); ++o) {
    if (table_.output_names[o] == mo.first)
      first = o;
    else
      others.push_back(o);
  }
  auto stepConfig = [&](double f, const std::vector<std::string>& outputs) {
    RunConfig c = cfg_;
    c.search.multi_output = MultiOutputConfig{};
    c.objectives.channels.clear();
    c.references = nlohmann::json::array();
    c.data.outputs = outputs;
    c.search.generations = share(cfg_.search.generations, f);
    c.search.max_evaluations = share(cfg_.search.max_evaluations, f);
    c.search.wall_time_s = cfg_.search.wall_time_s > 0 ? cfg_.search.wall_time_s * f : 0;
    return c;
  };

  // Step 1.
  RunConfig c1 = stepConfig(mo.first_share, {mo.first});
  step_ = std::make_unique<Search>(c1, withOutputs(table_, {first}));
  if (stop_.load()) step_->requestStop();
  step_->run([&](const SearchProgress& p) {
    if (on_progress) on_progress(1, p);
  });
  const auto p1 = step_->progress();
  const auto f1 = step_->front();
  const int pick = pickMember(f1, mo.first_max_cost);
  Program pick_prog;
  if (pick >= 0) {
    pick_prog = f1[pick].program;
  } else {  // no finite member at all: feed a constant 0 (step 2 then fits alone)
    pick_prog.code.push_back(Instr{Op::Mul, {inputOperand(0), constOperand(0)}});
    pick_prog.constants = {0.0f};
    pick_prog.outputs = {0};
  }
  pick_ = pick_prog;
  pick_column_ = mo.first + "_fit";

  // Step 2: the pick's float32 values become an input column.
  const Table t1 = withOutputs(table_, {first});
  // The block interpreter, so the column holds exactly what the search's programs see.
  const int bs = cfg_.eval.block_size;
  const auto picked = Interpreter(bs).evaluate(pick_prog, Dataset(t1, bs))[0];
  const std::vector<double> vals(picked.begin(), picked.end());
  second_table_ = withOutputs(table_, others);
  second_table_.input_names.push_back(pick_column_);
  second_table_.inputs.push_back(vals);
  std::vector<std::string> other_names;
  for (size_t o : others) other_names.push_back(table_.output_names[o]);
  RunConfig c2 = stepConfig(1.0 - mo.first_share, other_names);
  c2.data.inputs = second_table_.input_names;
  step_ = std::make_unique<Search>(c2, second_table_);
  if (stop_.load()) step_->requestStop();
  step_->run([&](const SearchProgress& p) {
    if (on_progress) on_progress(2, p);
  });
  const auto p2 = step_->progress();
  const auto f2 = step_->front();

  // Assemble: every second-step member with the pick in front of it.
  std::vector<Program> programs;
  for (const auto& m : f2)
    programs.push_back(
        composeTwoStep(pick_prog, m.program, static_cast<int>(n_in), static_cast<int>(first)));
  RunConfig cr = cfg_;
  cr.search.linear_scaling = false;  // the steps' scaling is already in their programs
  cr.program.max_length = 255;
  cr.program.num_constants = 255;
  cr.program.output_mode = OutputMode::Designated;
  result_ = std::make_unique<Search>(cr, table_);
  result_->adopt(programs, p1.generation + p2.generation, p1.evaluations + p2.evaluations,
                 p1.elapsed_s + p2.elapsed_s,
                 "step 1: " + p1.stop_reason + ", step 2: " + p2.stop_reason);
  step_.reset();
}

}  // namespace lgp
