// `lgp score table --expr "..."`: metrics and cost of a formula on a table, with the same
// fields as a front member (so published formulas can be compared with a front). With --each,
// every --expr and every line of an --expr-file is a whole formula of its own, scored alone
// (bench/peer scores whole fronts this way).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cxxopts.hpp>
#include <fstream>
#include <iostream>
#include <sstream>

#include "cli_args.hpp"
#include "commands.hpp"
#include "lgp/core/program.hpp"
#include "lgp/emit/gpu_cost.hpp"
#include "lgp/emit/score.hpp"

namespace {

int fail(const std::string& msg) {
  std::fprintf(stderr, "error: %s\n", msg.c_str());
  return 2;
}

std::vector<std::string> splitList(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ','))
    if (!item.empty()) out.push_back(item);
  return out;
}

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.4g", v);
  return buf;
}

// Takes every `--expr X`, `--expr=X` and `-e X` out of argv (cxxopts would split a vector
// option's value at commas, which formulas are full of).
std::vector<std::string> takeExprs(int& argc, char** argv, std::string& error) {
  std::vector<std::string> exprs;
  int w = 1;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--expr" || a == "-e") {
      if (i + 1 >= argc) {
        error = a + ": missing formula";
        break;
      }
      exprs.push_back(argv[++i]);
    } else if (a.rfind("--expr=", 0) == 0) {
      exprs.push_back(a.substr(7));
    } else {
      argv[w++] = argv[i];
    }
  }
  argc = w;
  return exprs;
}

// An --expr-file of --each: many formulas (a front's worth), each within kMaxFormulaBytes.
constexpr size_t kMaxEachFileBytes = size_t{64} << 20;

// Adds "cost_measured" to a scored formula: the formula as `lgp emit --lang hlsl --fast` writes
// it, compiled for every AMD family. Returns "" or why the cost is not available; fails only
// on an internal error.
lgp::Expected<std::string> measureInto(nlohmann::json& j, const lgp::Table& table) {
  lgp::ProgramShape shape;
  shape.num_inputs = static_cast<int>(table.numInputs());
  shape.num_outputs = static_cast<int>(table.numOutputs());
  shape.max_length = 255;
  shape.num_constants = 255;
  shape.output_mode = lgp::OutputMode::Designated;
  auto p = lgp::programFromJson(j["program"], shape);
  if (!p) return lgp::Status::error("internal: " + p.error());
  const lgp::emit::MeasureOptions mo;
  auto m = lgp::emit::measureProgram(lgp::emit::emitInputForTable(*p, table), mo);
  if (!m) return "measured cost: not available (" + m.error() + ")";
  j["cost_measured"] = *m;
  return std::string();
}

// --each: every text is a whole formula. JSON: an array of results (a failed formula is
// {"index", "name", "text", "failed": why}); text: one line per formula.
int scoreEach(const std::vector<std::string>& texts, const std::string& name,
              const std::map<std::string, std::string>& aliases, const lgp::Table& table,
              const lgp::emit::ScoreOptions& so, bool measure, bool json) {
  nlohmann::json all = nlohmann::json::array();
  if (!json)
    std::printf("%5s %11s %11s %11s %7s  %s\n", "#", "rmse f32", "rmse f64", "max_abs f32", "rdna2",
                "formula");
  for (size_t i = 0; i < texts.size(); ++i) {
    const std::string label = name + " " + std::to_string(i + 1);
    auto r = lgp::emit::scoreFormula(label, {texts[i]}, aliases, table, so);
    std::string note;
    if (r && measure) {
      auto m = measureInto(*r, table);
      if (!m) return fail(m.error());
      note = *m;
    }
    nlohmann::json j = r ? std::move(*r) : nlohmann::json{{"name", label}, {"failed", r.error()}};
    j["index"] = i;
    if (!note.empty()) j["cost_measured_note"] = note;
    if (json) {
      if (!r) j["text"] = texts[i];
      all.push_back(std::move(j));
      continue;
    }
    if (!r) {
      std::printf("%5zu failed: %s\n", i + 1, r.error().c_str());
      continue;
    }
    auto f = [&](const char* path, const char* k) {
      const auto& v = j["outputs"][0][path][k];
      return v.is_number() ? num(v.get<double>()) : std::string("inf");
    };
    const std::string isa = j.contains("cost_measured")
                                ? num(j["cost_measured"]["rdna2"]["instructions"].get<double>())
                                : std::string("-");
    std::printf("%5zu %11s %11s %11s %7s  %s\n", i + 1, f("float32", "rmse").c_str(),
                f("double", "rmse").c_str(), f("float32", "max_abs").c_str(), isa.c_str(),
                j.value("formula", "").c_str());
  }
  if (json) std::cout << all.dump(2) << "\n";
  return 0;
}

cxxopts::Options scoreOptions(const char* argv0) {
  cxxopts::Options opts(argv0,
                        "Score a formula on a table: metrics (float32 interpreter and double "
                        "reference) and cost under every target model. Grammar: emit/README.md.");
  opts.positional_help("table.{csv,json}");
  opts.add_options()("table", "table file (CSV or lgp-table/1 JSON)",
                     cxxopts::value<std::string>())(
      "e,expr", "formula; repeat once per output, or assign every output in one")(
      "expr-file", "file holding the formula (newlines separate statements)",
      cxxopts::value<std::vector<std::string>>())(
      "name", "label for the output", cxxopts::value<std::string>()->default_value("formula"))(
      "inputs", "input columns, comma-separated (default: the file's)",
      cxxopts::value<std::string>()->default_value(""))(
      "outputs", "output columns, comma-separated (default: the file's)",
      cxxopts::value<std::string>()->default_value(""))(
      "weights", "per-row weight column", cxxopts::value<std::string>()->default_value(""))(
      "a,alias", "NAME=INPUT: a formula name for a table input, e.g. NoV=mu (repeatable)",
      cxxopts::value<std::vector<std::string>>())(
      "error", "error objective: rmse, max_abs, mae, mean_rel",
      cxxopts::value<std::string>()->default_value("rmse"))(
      "combine", "across outputs: mean or max",
      cxxopts::value<std::string>()->default_value("mean"))(
      "cost-model", "gpu-generic, nvidia, gcn, rdna, cpu",
      cxxopts::value<std::string>()->default_value("gpu-generic"))(
      "no-measure", "skip the measured GPU cost (compiling the formula to AMD ISA)")(
      "each",
      "score each formula alone: every --expr and every non-empty line of every --expr-file is "
      "a whole formula; --json prints an array, one entry per formula (a formula that fails "
      "gets \"failed\": why)")("json", "print the result as JSON (the fields of a front member)")(
      "h,help", "this help");
  opts.parse_positional({"table"});
  return opts;
}

// The formulas of every --expr-file after those of --expr: with --each one per non-empty
// line, else the whole file as one.
lgp::Status readExprFiles(const cxxopts::ParseResult& args, bool each,
                          std::vector<std::string>& texts) {
  if (!args.count("expr-file")) return lgp::Status::ok();
  for (const auto& f : args["expr-file"].as<std::vector<std::string>>()) {
    // With --each a file holds many formulas, each within kMaxFormulaBytes (scoreFormula
    // checks every one).
    auto text = lgp::readInputFile(f, each ? kMaxEachFileBytes : lgp::emit::kMaxFormulaBytes);
    if (!text) return lgp::Status::error("--expr-file: " + text.error());
    if (!each) {
      texts.push_back(std::move(*text));
      continue;
    }
    std::stringstream lines(*text);
    for (std::string line; std::getline(lines, line);)
      if (line.find_first_not_of(" \t\r") != std::string::npos) texts.push_back(line);
  }
  return lgp::Status::ok();
}

lgp::Expected<std::map<std::string, std::string>> aliasesOf(const cxxopts::ParseResult& args) {
  std::map<std::string, std::string> aliases;
  if (args.count("alias"))
    for (const auto& a : args["alias"].as<std::vector<std::string>>()) {
      const auto eq = a.find('=');
      if (eq == std::string::npos || eq == 0 || eq + 1 == a.size())
        return lgp::Status::error("--alias: expected NAME=INPUT (got '" + a + "')");
      aliases[a.substr(0, eq)] = a.substr(eq + 1);
    }
  return aliases;
}

lgp::Expected<lgp::emit::ScoreOptions> scoreOptionsOf(const cxxopts::ParseResult& args) {
  lgp::emit::ScoreOptions so;
  const auto metric = lgp::errorMetricFromString(args["error"].as<std::string>());
  if (!metric)
    return lgp::Status::error("--error: unknown metric '" + args["error"].as<std::string>() + "'");
  so.error.metric = *metric;
  const auto comb = lgp::outputCombineFromString(args["combine"].as<std::string>());
  if (!comb) return lgp::Status::error("--combine: expected mean or max");
  so.error.combine = *comb;
  const auto target = lgp::costTargetFromString(args["cost-model"].as<std::string>());
  if (!target)
    return lgp::Status::error("--cost-model: unknown target '" +
                              args["cost-model"].as<std::string>() + "'");
  so.cost = lgp::CostModel::preset(*target);
  return so;
}

// One scored formula as text: the table, the program, its metrics per output and path, its
// error and costs.
void printScore(nlohmann::json& j, const cxxopts::ParseResult& args, const lgp::Table& table,
                const std::string& tp, const std::string& measured_note) {
  std::printf("%s on %s (%zu rows; inputs", j["name"].get<std::string>().c_str(), tp.c_str(),
              table.rows());
  for (const auto& n : table.input_names) std::printf(" %s", n.c_str());
  std::printf("; outputs");
  for (const auto& n : table.output_names) std::printf(" %s", n.c_str());
  std::printf(")\n");
  std::printf("program: %d opcodes, %d piecewise, %zu constants\n", j["opcodes"].get<int>(),
              j["piecewise"].get<int>(), j["program"]["constants"].size());
  // The simplified formula (the front's printer), one statement per line.
  const std::string formula = j.value("formula", "");
  for (size_t b = 0; b < formula.size();) {
    const size_t e = std::min(formula.find("; ", b), formula.size());
    std::printf("  %s\n", formula.substr(b, e - b).c_str());
    b = e + 2;
  }
  if (j.contains("cancellation"))
    std::printf("cancellation: %.1f float32 bits lost%s\n",
                j["cancellation"]["bits_lost"].get<double>(),
                j["cancellation"]["flagged"].get<bool>() ? " (flagged: constants cancel)" : "");
  std::printf("%-10s %-8s %11s %11s %11s %11s %11s\n", "output", "path", "rmse", "max_abs", "mae",
              "mean_rel", "r2");
  for (const auto& o : j["outputs"])
    for (const char* path : {"float32", "double"}) {
      const auto& m = o[path];
      auto f = [&](const char* k) {
        return m[k].is_number() ? num(m[k].get<double>()) : std::string("inf");
      };
      std::printf("%-10s %-8s %11s %11s %11s %11s %11s\n", o["name"].get<std::string>().c_str(),
                  path, f("rmse").c_str(), f("max_abs").c_str(), f("mae").c_str(),
                  f("mean_rel").c_str(), f("r2").c_str());
    }
  std::printf("error (%s, %s over outputs, float32): %s\n", args["error"].as<std::string>().c_str(),
              args["combine"].as<std::string>().c_str(),
              j["error"].is_number() ? num(j["error"].get<double>()).c_str() : "inf");
  std::printf("cost (%s): %s   by target:", args["cost-model"].as<std::string>().c_str(),
              num(j["cost"].get<double>()).c_str());
  for (const auto& [k, v] : j["cost_by_target"].items())
    std::printf(" %s %s", k.c_str(), num(v.get<double>()).c_str());
  std::printf("\n");
  if (j.contains("cost_measured")) {
    std::printf("measured (instructions / latency / VGPRs over an I/O-only shader, hlsl --fast):");
    for (const auto& [fam, st] : j["cost_measured"].items())
      std::printf(" %s %s/%s/%s", fam.c_str(), num(st["instructions"].get<double>()).c_str(),
                  num(st["latency"].get<double>()).c_str(), num(st["vgprs"].get<double>()).c_str());
    std::printf("\n");
  } else if (!measured_note.empty()) {
    std::printf("%s\n", measured_note.c_str());
  }
  std::printf("discontinuity: %s\n", num(j["discontinuity"].get<double>()).c_str());
}

int scoreMain(int argc, char** argv) {
  std::string expr_error;
  std::vector<std::string> texts = takeExprs(argc, argv, expr_error);
  if (!expr_error.empty()) return fail(expr_error);
  cxxopts::Options opts = scoreOptions(argv[0]);
  auto parsed = lgp::cli::parseArgs(opts, argc, argv, "table",
                                    "no table given (lgp score table.csv --expr \"...\")");
  if (const int* code = std::get_if<int>(&parsed)) return *code;
  const cxxopts::ParseResult& args = std::get<cxxopts::ParseResult>(parsed);
  const bool each = args.count("each") > 0;
  if (auto st = readExprFiles(args, each, texts); !st) return fail(st.message());
  if (texts.empty()) return fail("give the formula with --expr or --expr-file");

  const std::string tp = args["table"].as<std::string>();
  auto raw = lgp::readTableFile(tp);
  if (!raw) return fail(raw.error());
  auto table = lgp::selectColumns(*raw, splitList(args["inputs"].as<std::string>()),
                                  splitList(args["outputs"].as<std::string>()),
                                  args["weights"].as<std::string>(), tp);
  if (!table) return fail(table.error());
  auto aliases = aliasesOf(args);
  if (!aliases) return fail(aliases.error());
  auto so = scoreOptionsOf(args);
  if (!so) return fail(so.error());

  const bool measure = !args.count("no-measure");
  if (each)
    return scoreEach(texts, args["name"].as<std::string>(), *aliases, *table, *so, measure,
                     args.count("json") > 0);
  auto r = lgp::emit::scoreFormula(args["name"].as<std::string>(), texts, *aliases, *table, *so);
  if (!r) return fail(r.error());
  auto& j = *r;
  std::string measured_note;
  if (measure) {
    auto m = measureInto(j, *table);
    if (!m) return fail(m.error());
    measured_note = *m;
  }
  if (args.count("json")) {
    std::cout << j.dump(2) << "\n";
    return 0;
  }
  printScore(j, args, *table, tp, measured_note);
  return 0;
}

}  // namespace

LGP_REGISTER_COMMAND(kScoreCommand, "score", "score a formula (e.g. a published fit) on a table",
                     scoreMain);
