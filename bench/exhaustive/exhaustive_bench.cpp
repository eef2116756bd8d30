// Exhaustive enumeration (search.exhaustive) on one table: per operator count k, the distinct
// expressions enumerated, those fitted (one per function, with linear scaling one per function
// up to an affine map), the seconds until size k was done (wall, cumulative) and the best
// error with its formula. Prints the CPU model and the thread count.
//
// Usage: exhaustive_bench TABLE --inputs A,B --channel COL:W[,COL:W...] [--max-ops K]
//          [--seconds S] [--threads T] [--constants C] [--ops LIST] [--error METRIC]
//          [--no-linear-scaling]
//   TABLE      CSV or JSON table (`lgp data SCENE -o T` writes one)
//   --channel  the target: sum of weight * column, e.g. A:1,B:1 (the DFG at F0 = 1) or
//              A:0.04,B:1 (F0 = 0.04)
//   --ops      operators (comma list); default: every operator but sin, cos and select
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <sstream>
#include <string>
#include <vector>

#include "../bench_util.hpp"
#include "lgp/config/config.hpp"
#include "lgp/core/table.hpp"
#include "lgp/search/exhaustive.hpp"

namespace {

std::vector<std::string> split(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream in(s);
  for (std::string item; std::getline(in, item, ',');)
    if (!item.empty()) out.push_back(item);
  return out;
}

[[noreturn]] void die(const std::string& why) {
  std::fprintf(stderr, "exhaustive_bench: %s\n", why.c_str());
  std::exit(2);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) die("usage: exhaustive_bench TABLE --inputs A,B --channel COL:W,... [options]");
  std::vector<std::string> inputs, ops;
  std::vector<std::pair<std::string, double>> channel;
  int max_ops = 5, threads = 2, constants = 2;
  double seconds = 300;
  bool linear_scaling = true;
  std::string error = "rmse";
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--inputs") {
      inputs = split(lgp::bench::optionValue(argc, argv, i));
    } else if (a == "--channel") {
      for (const auto& term : split(lgp::bench::optionValue(argc, argv, i))) {
        const auto colon = term.find(':');
        if (colon == std::string::npos) die("--channel: expected COL:WEIGHT, got " + term);
        channel.emplace_back(term.substr(0, colon), std::atof(term.c_str() + colon + 1));
      }
    } else if (a == "--max-ops") {
      max_ops = std::atoi(lgp::bench::optionValue(argc, argv, i));
    } else if (a == "--seconds") {
      seconds = std::atof(lgp::bench::optionValue(argc, argv, i));
    } else if (a == "--threads") {
      threads = std::atoi(lgp::bench::optionValue(argc, argv, i));
    } else if (a == "--constants") {
      constants = std::atoi(lgp::bench::optionValue(argc, argv, i));
    } else if (a == "--ops") {
      ops = split(lgp::bench::optionValue(argc, argv, i));
    } else if (a == "--error") {
      error = lgp::bench::optionValue(argc, argv, i);
    } else if (a == "--no-linear-scaling") {
      linear_scaling = false;
    } else {
      die("unknown option " + a);
    }
  }
  if (channel.empty()) die("--channel is required");
  auto raw = lgp::readTableFile(argv[1]);
  if (!raw) die(raw.status().message());
  std::vector<std::string> outputs;
  for (const auto& [col, w] : channel) outputs.push_back(col);
  auto cols = lgp::selectColumns(*raw, inputs, outputs, "", argv[1]);
  if (!cols) die(cols.status().message());
  // One output: the channel's weighted sum.
  lgp::Table t = *cols;
  std::vector<double> y(t.rows(), 0.0);
  for (size_t k = 0; k < channel.size(); ++k)
    for (size_t r = 0; r < t.rows(); ++r) y[r] += channel[k].second * cols->outputs[k][r];
  t.outputs = {y};
  t.output_names = {"y"};

  // Through the config parser, so that the options get the run's checks and messages.
  nlohmann::json j = {
      {"data", {{"path", "in-memory"}}},
      {"objectives", {{"error", error}}},
      {"search",
       {{"threads", threads},
        {"linear_scaling", linear_scaling},
        {"exhaustive", {{"max_ops", max_ops}, {"seconds", seconds}, {"constants", constants}}}}}};
  if (!ops.empty()) j["search"]["exhaustive"]["ops"] = ops;
  auto cfg = lgp::parseRunConfig(j, ".");
  if (!cfg) die(cfg.error());

  std::printf("# exhaustive_bench  %s  CPU: %s  threads %d\n", lgp::bench::utcNow().c_str(),
              lgp::bench::cpuModel().c_str(), threads);
  std::printf("# table %s: %zu rows, inputs", argv[1], t.rows());
  for (const auto& n : t.input_names) std::printf(" %s", n.c_str());
  std::printf("; target");
  for (const auto& [col, w] : channel) std::printf(" %+g*%s", w, col.c_str());
  std::printf("; error %s, linear scaling %s, free constants <= %d\n", error.c_str(),
              linear_scaling ? "on" : "off", constants);
  const auto wall0 = std::chrono::steady_clock::now();
  const double cpu0 = std::clock() / static_cast<double>(CLOCKS_PER_SEC);
  auto r = lgp::exhaustiveSearch(*cfg, t);
  if (!r) die(r.error());
  const double wall =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  const double cpu = std::clock() / static_cast<double>(CLOCKS_PER_SEC) - cpu0;
  const auto cert = r->toJson(*cfg, t);
  std::printf("# operators (%zu):", cert["grammar"]["ops"].size());
  for (const auto& o : cert["grammar"]["ops"]) std::printf(" %s", o.get<std::string>().c_str());
  std::printf("\n%3s %12s %12s %10s %12s  %s\n", "k", "distinct", "fitted", "done_s", "best",
              "formula");
  for (const auto& b : cert["best"]) {
    const int k = b["max_ops"];
    const bool complete = b["complete"];
    std::printf("%3d %12llu %12llu %10.2f %12.4g  %s%s\n", k,
                static_cast<unsigned long long>(b["enumerated"].get<uint64_t>()),
                static_cast<unsigned long long>(b["screened"].get<uint64_t>()),
                b["seconds"].get<double>(), b["error"].is_null() ? NAN : b["error"].get<double>(),
                complete ? "" : "(incomplete) ", b["formula"].get<std::string>().c_str());
  }
  std::printf("# complete up to %d operators%s%s%s; wall %.2f s, CPU %.2f s (all threads)\n",
              r->complete_ops, r->stopped.empty() ? "" : " (stopped: ", r->stopped.c_str(),
              r->stopped.empty() ? "" : ")", wall, cpu);
  return 0;
}
