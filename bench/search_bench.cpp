// End-to-end search throughput benchmark (prints figures; never a test).
//
// Runs lgp::Search on a generated 32x32 table, target y = exp2(-(7 mu + 4 r^2)) on the
// cell-centred grid mu, r = (i + 0.5) / 32, with a fixed seed, population 500 and a fixed
// number of generations, on 1 thread and on all threads. Prints evaluated programs per second
// (Nelder-Mead evaluations included, as the search counts them) and the wall time per
// generation, each the median of --reps identical runs (the search is deterministic, so every
// repetition does the same work; the front must not depend on the thread count), by wall
// clock and by the master thread's CPU time (see threadCpuSeconds). It then times the
// non-dominated sorting alone (see rankingBench).
//
// Usage: search_bench [--generations N] [--population N] [--reps N] [--threads N] [--seed N]
//                     [--no-ranking] [--quick]
#include <benchmark/benchmark.h>
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <limits>
#include <numeric>
#include <string>
#include <vector>

#include "bench_util.hpp"
#include "lgp/config/config.hpp"
#include "lgp/core/table.hpp"
#include "lgp/search/pareto.hpp"
#include "lgp/search/search.hpp"

namespace {

struct Options {
  int generations = 100;
  int population = 500;
  int reps = 3;
  int threads = 0;  // 0 = omp_get_max_threads()
  uint64_t seed = 1;
  bool ranking = true;  // also time non-dominated sorting alone
};
Options g_opt;

lgp::Table makeTable() {
  constexpr int kSide = 32;
  lgp::Table t;
  t.input_names = {"mu", "r"};
  t.output_names = {"y"};
  t.inputs.assign(2, {});
  t.outputs.assign(1, {});
  for (int j = 0; j < kSide; ++j)
    for (int i = 0; i < kSide; ++i) {
      const double mu = (i + 0.5) / kSide, r = (j + 0.5) / kSide;
      t.inputs[0].push_back(mu);
      t.inputs[1].push_back(r);
      t.outputs[0].push_back(std::exp2(-(7.0 * mu + 4.0 * r * r)));
    }
  return t;
}

lgp::RunConfig makeConfig(int threads) {
  lgp::RunConfig cfg;
  cfg.data.path = "in-memory";  // unused: the table is passed directly
  cfg.search.population = g_opt.population;
  cfg.search.generations = g_opt.generations;
  cfg.search.seed = g_opt.seed;
  cfg.search.threads = threads;
  cfg.output.progress_interval_s = 1e9;
  cfg.output.front_json.clear();
  cfg.output.front_csv.clear();
  return cfg;
}

// CPU time of the calling thread. The thread that calls Search::run() is OpenMP's master: it
// runs every serial part of a generation and its share of each parallel loop, and waits
// (spinning, by libgomp's default) at the end of each loop, so on an idle machine its CPU time
// equals the wall time. Unlike wall time it leaves out the time this thread was descheduled,
// so with 1 thread on a loaded, shared machine it estimates the unloaded run time. With N
// threads it counts spinning while a descheduled partner finishes (pessimistic) but not
// sleeping waits under OMP_WAIT_POLICY=passive (optimistic).
struct RunResult {
  double init_s = 0, run_s = 0;      // wall: generation 0 (random population); generations 1..G
  double init_cpu = 0, run_cpu = 0;  // the same, master-thread CPU time
  uint64_t init_evals = 0, evals = 0;
  double best_error = 0;
  size_t front = 0;
};

RunResult runOnce(const lgp::Table& table, int threads) {
  lgp::Search search(makeConfig(threads), table);
  RunResult r;
  const auto t0 = std::chrono::steady_clock::now();
  const double c0 = lgp::bench::threadCpuSeconds();
  search.initialize();
  const auto t1 = std::chrono::steady_clock::now();
  const double c1 = lgp::bench::threadCpuSeconds();
  r.init_evals = search.progress().evaluations;
  search.run();
  const auto t2 = std::chrono::steady_clock::now();
  const double c2 = lgp::bench::threadCpuSeconds();
  const auto p = search.progress();
  benchmark::DoNotOptimize(p.best_error);
  r.init_s = std::chrono::duration<double>(t1 - t0).count();
  r.run_s = std::chrono::duration<double>(t2 - t1).count();
  r.init_cpu = c1 - c0;
  r.run_cpu = c2 - c1;
  r.evals = p.evaluations;
  r.best_error = p.best_error;
  r.front = p.front_size;
  if (p.generation != g_opt.generations)
    std::printf("warning: stopped at generation %d (%s)\n", p.generation, p.stop_reason.c_str());
  return r;
}

struct Summary {
  double evals_per_s = 0, gen_ms = 0, init_ms = 0;  // wall clock
  double evals_per_cpu_s = 0, gen_cpu_ms = 0;       // master-thread CPU time
  RunResult last;
};

Summary measure(const lgp::Table& table, int threads) {
  std::vector<double> eps, gen, init, eps_cpu, gen_cpu;
  Summary s;
  for (int k = 0; k < g_opt.reps; ++k) {
    const RunResult r = runOnce(table, threads);
    eps.push_back(static_cast<double>(r.evals) / (r.init_s + r.run_s));
    gen.push_back(r.run_s / g_opt.generations * 1e3);
    init.push_back(r.init_s * 1e3);
    eps_cpu.push_back(static_cast<double>(r.evals) / (r.init_cpu + r.run_cpu));
    gen_cpu.push_back(r.run_cpu / g_opt.generations * 1e3);
    std::printf(
        "  threads=%d rep %d: wall %.3f s (%.3e evals/s, %.2f ms/gen), master CPU %.3f s "
        "(%.3e evals/s, %.2f ms/gen), %llu evals, best error %.6g, archive %zu\n",
        threads, k + 1, r.init_s + r.run_s, eps.back(), gen.back(), r.init_cpu + r.run_cpu,
        eps_cpu.back(), gen_cpu.back(), static_cast<unsigned long long>(r.evals), r.best_error,
        r.front);
    s.last = r;
  }
  auto median = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  };
  s.evals_per_s = median(eps);
  s.gen_ms = median(gen);
  s.init_ms = median(init);
  s.evals_per_cpu_s = median(eps_cpu);
  s.gen_cpu_ms = median(gen_cpu);
  return s;
}

// ---------------------------------------------------------------------------------------------
// Non-dominated sorting (lgp::nondominatedRanks) measured alone on the distinct
// objective vectors of a real pool (population at generation G-1 plus that at G), as
// rankPopulation passes them. It is serial, so it bounds the multi-thread speed-up.
std::vector<lgp::Objectives> populationObjectives(const nlohmann::json& checkpoint) {
  std::vector<lgp::Objectives> out;
  for (const auto& ind : checkpoint.at("population")) {
    const auto& o = ind.at("obj");
    lgp::Objectives v;
    v.error = o[0].is_number() ? o[0].get<double>() : std::numeric_limits<double>::infinity();
    v.cost = o[1].get<double>();
    v.discontinuity = o[2].get<double>();
    out.push_back(v);
  }
  return out;
}

void rankingBench(const lgp::Table& table) {
  lgp::Search search(makeConfig(1), table);
  search.initialize();
  for (int g = 1; g < g_opt.generations; ++g) search.step();
  auto pool = populationObjectives(search.checkpoint());
  search.step();
  const auto last = populationObjectives(search.checkpoint());
  pool.insert(pool.end(), last.begin(), last.end());
  std::vector<double> t;
  std::vector<int> ranks;
  for (int rep = 0; rep < 7; ++rep) {
    const double c0 = lgp::bench::threadCpuSeconds();
    for (int k = 0; k < 20; ++k) benchmark::DoNotOptimize(ranks = lgp::nondominatedRanks(pool));
    t.push_back((lgp::bench::threadCpuSeconds() - c0) / 20);
  }
  std::sort(t.begin(), t.end());
  std::printf("\n== non-dominated sorting alone (%zu individuals, %d fronts; thread CPU time) ==\n",
              pool.size(), *std::max_element(ranks.begin(), ranks.end()) + 1);
  std::printf("  lgp::nondominatedRanks: %8.3f ms per call\n", t[t.size() / 2] * 1e3);
}

void parseArgs(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&] { return lgp::bench::optionValue(argc, argv, i); };
    if (a == "--generations")
      g_opt.generations = std::atoi(next());
    else if (a == "--population")
      g_opt.population = std::atoi(next());
    else if (a == "--reps")
      g_opt.reps = std::atoi(next());
    else if (a == "--threads")
      g_opt.threads = std::atoi(next());
    else if (a == "--seed")
      g_opt.seed = std::strtoull(next(), nullptr, 10);
    else if (a == "--no-ranking")
      g_opt.ranking = false;
    else if (a == "--quick") {
      g_opt.generations = 10;
      g_opt.reps = 1;
    } else {
      std::fprintf(stderr,
                   "usage: search_bench [--generations N] [--population N] [--reps N] "
                   "[--threads N] [--seed N] [--no-ranking] [--quick]\n");
      std::exit(2);
    }
  }
  g_opt.reps = std::max(1, g_opt.reps);
  g_opt.generations = std::max(1, g_opt.generations);
  g_opt.population = std::max(4, g_opt.population);
}

}  // namespace

int main(int argc, char** argv) {
  parseArgs(argc, argv);
  const int threads = g_opt.threads > 0 ? g_opt.threads : omp_get_max_threads();
  const lgp::Table table = makeTable();
  std::printf(
      "search_bench: 32x32 table y = exp2(-(7 mu + 4 r^2)), population %d, "
      "%d generations, seed %llu, reps %d (median)\n",
      g_opt.population, g_opt.generations, static_cast<unsigned long long>(g_opt.seed), g_opt.reps);
  if (FILE* f = std::fopen("/proc/loadavg", "r")) {
    char buf[128] = {};
    if (std::fgets(buf, sizeof buf, f)) std::printf("load average at start: %s", buf);
    std::fclose(f);
  }
  const char* wait = std::getenv("OMP_WAIT_POLICY");
  std::printf(
      "OMP_WAIT_POLICY=%s (libgomp spins at barriers by default; on a loaded machine a\n"
      "  spinning thread can wait out a descheduled partner's time slice)\n",
      wait ? wait : "(unset)");

  const Summary s1 = measure(table, 1);
  const Summary sn = threads > 1 ? measure(table, threads) : s1;

  std::printf("\n== summary (medians) ==\n");
  std::printf("  %-8s %13s %10s %15s %13s %10s %10s %12s\n", "threads", "evals/s", "ms/gen",
              "evals/s (cpu)", "ms/gen (cpu)", "gen-0 ms", "evals", "best error");
  for (const auto& [t, s] : {std::pair{1, s1}, std::pair{threads, sn}}) {
    std::printf("  %-8d %13.3e %10.2f %15.3e %13.2f %10.2f %10llu %12.6g\n", t, s.evals_per_s,
                s.gen_ms, s.evals_per_cpu_s, s.gen_cpu_ms, s.init_ms,
                static_cast<unsigned long long>(s.last.evals), s.last.best_error);
  }
  std::printf(
      "  (cpu) = by master-thread CPU time. 1 thread: estimates the unloaded run. N threads on a\n"
      "  loaded machine: pessimistic with spinning waits (the default), optimistic with\n"
      "  OMP_WAIT_POLICY=passive (sleeping waits are not counted)\n");
  std::printf("  speed-up %d threads / 1 thread: %.2fx wall, %.2fx cpu\n", threads,
              sn.evals_per_s / s1.evals_per_s, sn.evals_per_cpu_s / s1.evals_per_cpu_s);
  const bool same = s1.last.evals == sn.last.evals && s1.last.best_error == sn.last.best_error &&
                    s1.last.front == sn.last.front;
  std::printf("  same result on 1 and %d threads (evals, best error, archive size): %s\n", threads,
              same ? "yes" : "NO");
  if (g_opt.ranking) rankingBench(table);
  return 0;
}
