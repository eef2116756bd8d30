// lgp_gpu_time: every member of a front (and its scored references), as `lgp emit` exports it,
// timed on a real GPU through Vulkan, next to the instruction count measured for it on AMD ISA
// (the front's cost_measured) and the cost models' figures. It answers whether the unit the
// fronts are judged in (RDNA2 instructions from ACO) ranks formulas as another vendor's GPU
// times them. See README.md for the protocol.
//
// lgp_gpu_time --front F.json [--front G.json ..] --out DIR [--lang hlsl|glsl] [--invocations N]
// [--iters N]
//              [--rounds N] [--warmup N] [--device NAME] [--allow-cpu] [--no-references]
#include <glslang/Public/ShaderLang.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <numeric>
#include <string>
#include <vector>

#include <cxxopts.hpp>
#include <nlohmann/json.hpp>

#include "../bench_util.hpp"
#include "lgp/core/expr.hpp"
#include "lgp/emit/emit.hpp"
#include "lgp/eval/objectives.hpp"
#include "spirv_compile.hpp"
#include "timing_kernel.hpp"
#include "vk_timer.hpp"

namespace {

using nlohmann::json;
using namespace lgp;

[[noreturn]] void die(const std::string& msg) {
  std::fprintf(stderr, "lgp_gpu_time: %s\n", msg.c_str());
  std::exit(1);
}

double median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// One formula to time: a member or a reference of the front.
struct Entry {
  std::string label;  // "m12" or the reference's name
  bool reference = false;
  double error = std::nan("");
  double cost = std::nan(""), nvidia = std::nan(""), rdna2 = std::nan("");
  size_t formula_kernel = 0, baseline_kernel = 0;
  // What the host needs to recompute the formula kernel's sums (checkSums).
  Dag dag;
  std::vector<TargetTransform> transforms;
  std::vector<Interval> domain;
  size_t num_inputs = 0;
};

// The formula kernel's sum for invocation i, recomputed on the host: the same input walk and
// the emitted DAG evaluated as the float32 interpreter does, inverse transforms applied, summed
// in float in the kernel's order. `scale` gets the sum of the terms' magnitudes.
float hostSum(const Entry& e, uint32_t i, uint32_t iters, double& scale) {
  std::vector<double> x(e.num_inputs);
  float acc = 0;
  scale = 0;
  for (uint32_t k = 0; k < iters; ++k) {
    for (size_t j = 0; j < x.size(); ++j) x[j] = bench::walkInput(e.domain, j, i, k);
    const std::vector<double> v = evaluateRow(e.dag, x.data(), Precision::Float);
    for (size_t o = 0; o < v.size(); ++o) {
      const float term = static_cast<float>(
          invertTransform(o < e.transforms.size() ? e.transforms[o] : TargetTransform::None,
                          static_cast<double>(static_cast<float>(v[o]))));
      acc += term;
      scale += std::fabs(static_cast<double>(term));
    }
  }
  return acc;
}

double numberAt(const json& j, const json::json_pointer& p) {
  return j.contains(p) && j.at(p).is_number() ? j.at(p).get<double>() : std::nan("");
}

std::vector<double> ranks(const std::vector<double>& v) {
  if (std::any_of(v.begin(), v.end(), [](double a) { return !std::isfinite(a); }))
    return std::vector<double>(v.size(), std::nan(""));  // no ranks: the correlation is NaN
  std::vector<size_t> idx(v.size());
  std::iota(idx.begin(), idx.end(), 0);
  std::sort(idx.begin(), idx.end(), [&](size_t a, size_t b) { return v[a] < v[b]; });
  std::vector<double> r(v.size());
  for (size_t i = 0; i < idx.size();) {
    size_t j = i;
    while (j + 1 < idx.size() && v[idx[j + 1]] == v[idx[i]]) ++j;
    for (size_t k = i; k <= j; ++k) r[idx[k]] = 0.5 * double(i + j);  // ties: mean rank
    i = j + 1;
  }
  return r;
}

double pearson(const std::vector<double>& x, const std::vector<double>& y) {
  const size_t n = x.size();
  if (n < 3 || y.size() != n) return std::nan("");
  for (size_t i = 0; i < n; ++i)
    if (!std::isfinite(x[i]) || !std::isfinite(y[i])) return std::nan("");
  const double mx = std::accumulate(x.begin(), x.end(), 0.0) / double(n);
  const double my = std::accumulate(y.begin(), y.end(), 0.0) / double(n);
  double sxy = 0, sxx = 0, syy = 0;
  for (size_t i = 0; i < n; ++i) {
    sxy += (x[i] - mx) * (y[i] - my);
    sxx += (x[i] - mx) * (x[i] - mx);
    syy += (y[i] - my) * (y[i] - my);
  }
  return sxx > 0 && syy > 0 ? sxy / std::sqrt(sxx * syy) : std::nan("");
}

// A statistic that identifies the code ("Hash", "Driver pipeline hash"): no quantity to
// subtract or correlate.
bool isHash(std::string name) {
  for (char& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return name.find("hash") != std::string::npos;
}

std::string fmt(double v, const char* f = "%.3g") {
  if (!std::isfinite(v)) return "-";
  char b[48];
  std::snprintf(b, sizeof b, f, v);
  return b;
}

}  // namespace

int main(int argc, char** argv) {
  cxxopts::Options opts("lgp_gpu_time", "Times a front's emitted formulas on a Vulkan GPU");
  opts.add_options()("front", "front JSON (lgp-front/1); repeat for several",
                     cxxopts::value<std::vector<std::string>>())(
      "out", "folder for results.json and report.md", cxxopts::value<std::string>())(
      "lang", "hlsl (as the measured cost compiles it) or glsl",
      cxxopts::value<std::string>()->default_value("hlsl"))(
      "invocations", "threads per dispatch (a multiple of 128)",
      cxxopts::value<uint32_t>()->default_value("1048576"))(
      "iters", "evaluations per thread", cxxopts::value<uint32_t>()->default_value("1024"))(
      "rounds", "timed dispatches per kernel", cxxopts::value<int>()->default_value("11"))(
      "warmup", "untimed rounds first", cxxopts::value<int>()->default_value("2"))(
      "device", "substring of the Vulkan device's name (default: the first GPU)",
      cxxopts::value<std::string>()->default_value(""))(
      "allow-cpu", "accept a CPU Vulkan device (lavapipe: runs, timings mean nothing)")(
      "no-references", "time the members only")(
      "check", "invocations per formula whose sums are recomputed on the host and compared",
      cxxopts::value<uint32_t>()->default_value("4"))(
      "stats-only",
      "build the kernels and report the driver's statistics of each, run nothing (a "
      "compile-only device such as RADV's null device)")("h,help", "this help");
  cxxopts::ParseResult args;
  try {
    args = opts.parse(argc, argv);
  } catch (const std::exception& e) {
    die(e.what());
  }
  if (args.count("help")) {
    std::printf("%s\n", opts.help().c_str());
    return 0;
  }
  if (!args.count("front")) die("--front: required");
  if (!args.count("out")) die("--out: required");
  const auto front_paths = args["front"].as<std::vector<std::string>>();
  const auto lang = emit::languageFromString(args["lang"].as<std::string>());
  if (!lang || !emit::languageInfo(*lang).shader) die("--lang: expected a shader language (hlsl or glsl)");
  const uint32_t invocations = args["invocations"].as<uint32_t>();
  const uint32_t iters = args["iters"].as<uint32_t>();
  const bool stats_only = args.count("stats-only") > 0;
  const int rounds = stats_only ? 0 : args["rounds"].as<int>();
  const int warmup = stats_only ? 0 : args["warmup"].as<int>();
  if (invocations == 0 || invocations % bench::kTimingWorkgroup)
    die("--invocations: must be a positive multiple of 128");
  if (iters == 0) die("--iters: must be positive");
  if ((rounds < 1 && !stats_only) || warmup < 0) die("--rounds: must be >= 1, --warmup >= 0");

  // Emit and compile every formula and its I/O-only twin; identical kernels (most twins) are
  // compiled and timed once.
  glslang::InitializeProcess();
  std::vector<std::vector<Entry>> entries(front_paths.size());
  std::vector<std::vector<uint32_t>> kernels;
  std::map<std::string, size_t> kernel_of;
  for (size_t fi = 0; fi < front_paths.size(); ++fi) {
    const std::string& front_path = front_paths[fi];
    std::ifstream in(front_path);
    if (!in) die("--front: cannot read " + front_path);
    const json front = json::parse(in, nullptr, false);
    if (front.is_discarded() || !front.contains("members") || !front["members"].is_array())
      die("--front: " + front_path + " is not a front JSON (no members array)");
    auto add = [&](const json& e, const std::string& path, Entry entry) {
      const std::string where = front_path + path;
      auto input = emit::emitInputFromFrontEntry(front, e, path);
      if (!input) die(where + ": " + input.error());
      emit::EmitOptions eo;
      eo.fast = true;  // as the measured cost compiles it (emit/gpu_cost.hpp)
      eo.header = false;
      auto emitted = emit::emitProgram(*input, *lang, eo);
      if (!emitted) die(where + ": " + emitted.error());
      size_t index[2] = {0, 0};
      int slot = 0;
      for (auto body : {emit::KernelBody::Formula, emit::KernelBody::IoBaseline}) {
        auto src = bench::timingKernel(*emitted, *lang, input->domain, body);
        if (!src) die(where + ": " + src.error());
        auto [it, fresh] = kernel_of.emplace(*src, kernels.size());
        if (fresh) {
          try {
            kernels.push_back(spirv::compileCompute(std::string(emit::toString(*lang)), *src));
          } catch (const spirv::CompileError& err) {
            die(where + ": " + err.what() + "\n" + *src);
          }
        }
        index[slot++] = it->second;
      }
      entry.formula_kernel = index[0];
      entry.baseline_kernel = index[1];
      entry.error = numberAt(e, json::json_pointer("/error"));
      entry.cost = numberAt(e, json::json_pointer("/cost"));
      entry.nvidia = numberAt(e, json::json_pointer("/cost_by_target/nvidia"));
      entry.rdna2 = numberAt(e, json::json_pointer("/cost_measured/rdna2/instructions"));
      entry.dag = emitted->dag;
      entry.transforms = input->transforms;
      entry.domain = input->domain;
      entry.num_inputs = static_cast<size_t>(emitted->num_inputs);
      entries[fi].push_back(entry);
    };
    for (size_t i = 0; i < front["members"].size(); ++i)
      add(front["members"][i], "/members/" + std::to_string(i), {"m" + std::to_string(i)});
    if (!args.count("no-references") && front.contains("references"))
      for (size_t i = 0; i < front["references"].size(); ++i) {
        const json& r = front["references"][i];
        Entry e{r.value("name", "reference " + std::to_string(i))};
        e.reference = true;
        add(r, "/references/" + std::to_string(i), e);
      }
  }
  glslang::FinalizeProcess();

  bench::TimerOptions to;
  to.device = args["device"].as<std::string>();
  to.allow_cpu = args.count("allow-cpu") > 0;
  auto timer = bench::VkTimer::open(to);
  if (!timer) die(timer.error());
  const bench::DeviceInfo& dev = (*timer)->info();
  std::printf("lgp_gpu_time: %s (%s), %s; host CPU %s\n", dev.name.c_str(), dev.type.c_str(),
              dev.driver.c_str(), bench::cpuModel().c_str());
  size_t formulas = 0;
  for (const auto& e : entries) formulas += e.size();
  std::printf(
      "lgp_gpu_time: %zu formulas, %zu kernels, %u x %u evaluations per dispatch, "
      "%d rounds (+%d warm-up)\n",
      formulas, kernels.size(), invocations, iters, rounds, warmup);
  std::fflush(stdout);
  const uint32_t keep = stats_only ? 0 : std::min(args["check"].as<uint32_t>(), invocations);
  auto run = (*timer)->time(kernels, invocations, iters, rounds, warmup, keep);
  if (!run) die(run.error());

  // Each formula kernel computes its formula: its sums for the first `keep` invocations,
  // recomputed on the host, agree to within kCheckTolerance of the sum of the terms'
  // magnitudes (GPU transcendentals and fused multiply-adds differ in the last bits, and a
  // formula that cancels amplifies that; a wrong input, output or loop differs by far more).
  constexpr double kCheckTolerance = 1e-3;
  size_t check_failures = 0;

  // Per formula: the median over rounds of (formula - its baseline), each pair timed in the
  // same round, in picoseconds per evaluation.
  const double evals = double(invocations) * double(iters);
  struct Series {
    std::vector<double> rdna2, nvidia, cost, ps;
    std::map<std::string, std::vector<double>> driver;  // per driver statistic, with ps_of
    std::map<std::string, std::vector<double>> ps_of, rdna2_of;
  };
  auto correlation = [](const Series& v) {
    double sxy = 0, sxx = 0;  // least squares through the origin: ps per RDNA2 instruction
    for (size_t i = 0; i < v.ps.size(); ++i) {
      sxy += v.rdna2[i] * v.ps[i];
      sxx += v.rdna2[i] * v.rdna2[i];
    }
    return json{{"members", v.ps.size()},
                {"ps_per_rdna2_instruction", sxx > 0 ? sxy / sxx : std::nan("")},
                {"pearson_rdna2", pearson(v.rdna2, v.ps)},
                {"spearman_rdna2", pearson(ranks(v.rdna2), ranks(v.ps))},
                {"pearson_model_nvidia", pearson(v.nvidia, v.ps)},
                {"spearman_model_nvidia", pearson(ranks(v.nvidia), ranks(v.ps))},
                {"pearson_model_cost", pearson(v.cost, v.ps)},
                {"spearman_model_cost", pearson(ranks(v.cost), ranks(v.ps))},
                {"driver_statistics", [&] {
                   json d = json::object();
                   for (const auto& [name, x] : v.driver) {
                     const auto& y = v.ps_of.at(name);
                     const auto& z = v.rdna2_of.at(name);
                     d[name] = {{"members", x.size()},
                                {"pearson", pearson(x, y)},
                                {"spearman", pearson(ranks(x), ranks(y))},
                                {"pearson_rdna2", pearson(x, z)},
                                {"spearman_rdna2", pearson(ranks(x), ranks(z))}};
                   }
                   return d;
                 }()}};
  };
  Series pooled;
  json fronts = json::array();
  for (size_t fi = 0; fi < front_paths.size(); ++fi) {
    json rows = json::array();
    Series one;
    for (const Entry& e : entries[fi]) {
      const auto& f = run->ns[e.formula_kernel];
      const auto& b = run->ns[e.baseline_kernel];
      std::vector<double> d(f.size());
      for (size_t r = 0; r < f.size(); ++r) d[r] = (f[r] - b[r]) * 1e3 / evals;
      const double ps = median(d);
      const auto [lo, hi] = std::minmax_element(d.begin(), d.end());
      const double ps_min = d.empty() ? std::nan("") : *lo, ps_max = d.empty() ? std::nan("") : *hi;
      double deviation = 0;  // the largest |gpu - host| / scale over the checked invocations
      const auto& head = run->head[e.formula_kernel];
      for (uint32_t i = 0; i < head.size(); ++i) {
        double scale = 0;
        const double want = hostSum(e, i, iters, scale);
        const double gap = std::fabs(double(head[i]) - want) / std::max(scale, 1e-30);
        deviation = std::max(deviation, std::isfinite(gap) ? gap : HUGE_VAL);
      }
      const bool checked = deviation <= kCheckTolerance;
      if (!checked) {
        ++check_failures;
        std::fprintf(stderr,
                     "lgp_gpu_time: %s %s: the kernel's sums differ from the host's by "
                     "%.3g of their magnitude\n",
                     front_paths[fi].c_str(), e.label.c_str(), deviation);
      }
      // The driver's statistics of the formula kernel over its baseline's (where reported).
      json driver = json::object();
      const json& fs = run->stats[e.formula_kernel];
      const json& bs = run->stats[e.baseline_kernel];
      for (auto it = fs.begin(); it != fs.end(); ++it)
        if (it->is_number() && bs.contains(it.key()) && bs[it.key()].is_number() &&
            !isHash(it.key()))
          driver[it.key()] = it->get<double>() - bs[it.key()].get<double>();
      rows.push_back({{"label", e.label},
                      {"driver_stats", driver},
                      {"check_deviation", deviation},
                      {"check_ok", checked},
                      {"reference", e.reference},
                      {"error", e.error},
                      {"cost", e.cost},
                      {"cost_nvidia", e.nvidia},
                      {"rdna2_instructions", e.rdna2},
                      {"ps_per_eval", ps},
                      {"ps_per_eval_min", ps_min},
                      {"ps_per_eval_max", ps_max},
                      {"formula_ns", f},
                      {"baseline_ns", b},
                      {"finite", run->finite[e.formula_kernel] && run->finite[e.baseline_kernel]}});
      if (!e.reference && std::isfinite(e.rdna2) && std::isfinite(e.nvidia) &&
          std::isfinite(e.cost) && (stats_only || std::isfinite(ps)))
        for (Series* v : {&one, &pooled}) {
          for (auto it = driver.begin(); it != driver.end(); ++it) {
            v->driver[it.key()].push_back(it->get<double>());
            v->ps_of[it.key()].push_back(ps);
            v->rdna2_of[it.key()].push_back(e.rdna2);
          }
          v->rdna2.push_back(e.rdna2);
          v->nvidia.push_back(e.nvidia);
          v->cost.push_back(e.cost);
          v->ps.push_back(ps);
        }
    }
    fronts.push_back(
        {{"front", front_paths[fi]}, {"correlation", correlation(one)}, {"formulas", rows}});
  }
  json result = {{"device",
                  {{"name", dev.name},
                   {"type", dev.type},
                   {"driver", dev.driver},
                   {"api", dev.api},
                   {"all", dev.all},
                   {"pipeline_statistics", dev.pipeline_statistics}}},
                 {"host_cpu", bench::cpuModel()},
                 {"date", bench::utcNow()},
                 {"lang", std::string(emit::toString(*lang))},
                 {"invocations", invocations},
                 {"iters", iters},
                 {"rounds", rounds},
                 {"stats_only", stats_only},
                 {"warmup", warmup},
                 {"kernels", kernels.size()},
                 {"checked_invocations", keep},
                 {"check_tolerance", kCheckTolerance},
                 {"check_failures", check_failures},
                 {"pooled", correlation(pooled)},
                 {"fronts", fronts}};

  // The report: how well each cost unit ranks the timings, per front and pooled, then every
  // formula of the first front.
  std::string md = "# GPU time of emitted formulas\n\n";
  md += std::string(emit::toString(*lang)) + " as `lgp emit --fast` writes it, on **" + dev.name +
        "** (" + dev.driver + ", Vulkan " + dev.api + "); host CPU " + bench::cpuModel() + "; " +
        bench::utcNow() + ".\n\n";
  if (stats_only) {
    md += "Statistics only (`--stats-only`): each of the " + std::to_string(kernels.size()) +
          " distinct kernels was compiled by the driver and nothing ran; the timing columns are "
          "empty.\n\n";
  } else {
    md += "Each dispatch: " + std::to_string(invocations) + " invocations x " +
          std::to_string(iters) + " evaluations; " + std::to_string(rounds) +
          " timed rounds after " + std::to_string(warmup) + " warm-up rounds, each of the " +
          std::to_string(kernels.size()) +
          " distinct kernels once per round. ps/eval: median over rounds of (formula kernel - "
          "its I/O-only kernel, same round) per evaluation. Correlations over the members "
          "(references left out). Each formula kernel's sums for its first " +
          std::to_string(keep) + " invocations were recomputed on the host: " +
          (check_failures ? std::to_string(check_failures) + " differ" : std::string("all agree")) +
          ".\n\n";
  }
  md +=
      "| front | members | ps per RDNA2 instr | RDNA2: Pearson | Spearman | nvidia model: "
      "Pearson | Spearman | run's model: Pearson | Spearman |\n";
  md += "|---|---|---|---|---|---|---|---|---|\n";
  auto corrRow = [&](const std::string& name, const json& c) {
    md += "| " + name + " | " + std::to_string(c["members"].get<size_t>()) + " | " +
          fmt(c["ps_per_rdna2_instruction"].get<double>(), "%.2f") + " | " +
          fmt(c["pearson_rdna2"].get<double>()) + " | " + fmt(c["spearman_rdna2"].get<double>()) +
          " | " + fmt(c["pearson_model_nvidia"].get<double>()) + " | " +
          fmt(c["spearman_model_nvidia"].get<double>()) + " | " +
          fmt(c["pearson_model_cost"].get<double>()) + " | " +
          fmt(c["spearman_model_cost"].get<double>()) + " |\n";
  };
  for (const json& f : fronts)
    corrRow("`" + bench::mdEscape(f["front"].get<std::string>()) + "`", f["correlation"]);
  if (fronts.size() > 1) corrRow("all, pooled", result["pooled"]);
  const json& ds = result["pooled"]["driver_statistics"];
  if (!ds.empty()) {
    md +=
        "\nThe driver's own statistics of each kernel (VK_KHR_pipeline_executable_properties), "
        "formula minus baseline, against the timings and against the measured RDNA2 "
        "instructions, all fronts pooled:\n\n"
        "| driver statistic | members | time: Pearson r | Spearman rho | RDNA2: Pearson r | "
        "Spearman rho |\n|---|---|---|---|---|---|\n";
    for (auto it = ds.begin(); it != ds.end(); ++it)
      md += "| " + bench::mdEscape(it.key()) + " | " +
            std::to_string((*it)["members"].get<size_t>()) + " | " +
            fmt((*it)["pearson"].get<double>()) + " | " + fmt((*it)["spearman"].get<double>()) +
            " | " + fmt((*it)["pearson_rdna2"].get<double>()) + " | " +
            fmt((*it)["spearman_rdna2"].get<double>()) + " |\n";
  }
  md += "\n## Every formula of `" + bench::mdEscape(front_paths[0]) + "`\n\n";
  md += "| formula | error | model cost | nvidia model | RDNA2 instr | ps/eval | [min, max] |\n";
  md += "|---|---|---|---|---|---|---|\n";
  for (const json& r : fronts[0]["formulas"]) {
    md += "| " + bench::mdEscape(r["label"].get<std::string>()) +
          (r["finite"].get<bool>() ? "" : " (non-finite)") + " | " +
          fmt(r["error"].get<double>(), "%.4g") + " | " + fmt(r["cost"].get<double>()) + " | " +
          fmt(r["cost_nvidia"].get<double>()) + " | " +
          fmt(r["rdna2_instructions"].get<double>(), "%.0f") + " | " +
          fmt(r["ps_per_eval"].get<double>(), "%.2f") + " | " +
          fmt(r["ps_per_eval_min"].get<double>(), "%.2f") + ", " +
          fmt(r["ps_per_eval_max"].get<double>(), "%.2f") + " |\n";
  }

  const std::filesystem::path out = args["out"].as<std::string>();
  std::error_code ec;
  std::filesystem::create_directories(out, ec);
  if (ec) die("--out: cannot create " + out.string() + ": " + ec.message());
  std::ofstream(out / "results.json") << result.dump(1) << '\n';
  std::ofstream(out / "report.md") << md;
  std::printf("%s", md.c_str());
  if (check_failures) {
    std::fprintf(stderr, "lgp_gpu_time: %zu formula kernels do not compute their formula\n",
                 check_failures);
    return 4;
  }
  return 0;
}
