// Generation times of the ground-truth tables (issue: dfg 64x64 to 1e-6 absolute error in
// under 10 s on 2 cores; zh 32x32; and the 41x41 dfg on [0.02, 1]^2 of the error-estimate
// audit, whose low-roughness rows are the hard case). Usage: datasets_bench [threads...]
// (default: 1 2).
#include <omp.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "lgp/datasets/generate.hpp"

namespace ds = lgp::datasets;

namespace {
const char* kDfg = R"({
  "name": "dfg-64x64",
  "material": {"visibility": "smith-correlated", "fresnel": {"model": "schlick", "f90": 1},
               "roughness": "perceptual"},
  "light": {"type": "environment"},
  "outputs": ["A", "B"],
  "grid": {"mu": {"count": 64, "range": [0.015625, 1], "spacing": "edge"},
           "r": {"count": 64, "range": [0, 1], "spacing": "edge"}},
  "accuracy": {"abs_error": 1e-6, "integrator": "adaptive"}
})";
const char* kDfg41 = R"({
  "name": "dfg-41x41",
  "material": {"visibility": "smith-correlated", "fresnel": {"model": "schlick", "f90": 1},
               "roughness": "perceptual"},
  "light": {"type": "environment"},
  "outputs": ["A", "B"],
  "grid": {"mu": {"count": 41, "range": [0.02, 1], "spacing": "edge"},
           "r": {"count": 41, "range": [0.02, 1], "spacing": "edge"}},
  "accuracy": {"abs_error": 1e-6, "integrator": "adaptive"}
})";
const char* kZh = R"({
  "name": "zh-32x32",
  "material": {"diffuse": "disney"},
  "outputs": ["ZH0", "ZH1", "ZH2", "ZH1_over_ZH0", "ZH2_over_ZH0", "beta"],
  "grid": {"mu": {"count": 32, "range": [0, 1], "spacing": "edge"},
           "r": {"count": 32, "range": [0, 1], "spacing": "edge"}},
  "accuracy": {"abs_error": 1e-6, "integrator": "adaptive"}
})";

void run(const char* name, const char* text, int threads) {
  auto scene = ds::parseScene(nlohmann::json::parse(text), name);
  if (!scene) {
    std::fprintf(stderr, "%s\n", scene.error().c_str());
    std::exit(1);
  }
  ds::GenerateOptions o;
  o.threads = threads;
  const auto t0 = std::chrono::steady_clock::now();
  auto g = ds::generate(*scene, o);
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!g) {
    std::fprintf(stderr, "%s\n", g.error().c_str());
    std::exit(1);
  }
  std::printf("%-10s threads=%d  %7.3f s  rows=%zu  evals=%llu  max_est_error=%.2e  %s\n", name,
              threads, s, g->table.rows(), static_cast<unsigned long long>(g->counters.total()),
              g->max_error, g->converged ? "converged" : "NOT converged");
}
}  // namespace

int main(int argc, char** argv) {
  std::vector<int> threads;
  for (int i = 1; i < argc; ++i) threads.push_back(std::atoi(argv[i]));
  if (threads.empty()) threads = {1, 2};
  std::printf("datasets_bench (%s), omp max threads %d\n", ds::kGeneratorVersion,
              omp_get_max_threads());
  for (int t : threads) {
    run("dfg 64x64", kDfg, t);
    run("dfg 41x41", kDfg41, t);
    run("zh 32x32", kZh, t);
  }
  return 0;
}
