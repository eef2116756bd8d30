// Runs a small search on an in-memory table through an installed lgp, and exports the best
// member as HLSL where lgp::emit is installed. Exit 0 only when the front fits the table.
#include <cmath>
#include <cstdio>

#include "lgp/config/config.hpp"
#include "lgp/core/table.hpp"
#include "lgp/search/search.hpp"
#ifdef CONSUMER_HAVE_EMIT
#include "lgp/emit/emit.hpp"
#endif

int main() {
  lgp::Table t;
  t.input_names = {"x", "y"};
  t.output_names = {"f"};
  t.inputs.assign(2, {});
  t.outputs.assign(1, {});
  for (int i = 0; i < 16; ++i)
    for (int j = 0; j < 16; ++j) {
      const double x = (i + 0.5) / 16, y = (j + 0.5) / 16;
      t.inputs[0].push_back(x);
      t.inputs[1].push_back(y);
      t.outputs[0].push_back(x * y + 0.5);
    }
  lgp::RunConfig cfg;
  cfg.search.population = 100;
  cfg.search.generations = 30;
  cfg.search.seed = 3;
  cfg.search.threads = 1;
  lgp::Search search(cfg, t);
  search.run();
  const auto front = search.front();
  if (front.empty()) {
    std::fprintf(stderr, "empty front\n");
    return 1;
  }
  double best = INFINITY;
  const lgp::FrontEntry* pick = nullptr;
  for (const auto& m : front)
    if (m.obj.error < best) best = m.obj.error, pick = &m;
  std::printf("front: %zu members; best rmse %.3g: %s\n", front.size(), best,
              pick->formula.c_str());
#ifdef CONSUMER_HAVE_EMIT
  lgp::emit::EmitInput in;
  in.program = pick->program;
  in.input_names = t.input_names;
  in.output_names = t.output_names;
  auto code = lgp::emit::emitProgram(in, lgp::emit::Language::Hlsl, {});
  if (!code) {
    std::fprintf(stderr, "emit: %s\n", code.error().c_str());
    return 1;
  }
  std::printf("HLSL: %zu bytes\n", code->code.size());
#endif
  return best < 0.05 ? 0 : 1;
}
