// `lgp emit front.json --lang LANG`: export one front member as shader or C++ code
// (lgp::emit::allLanguages).
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <cxxopts.hpp>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>

#include "cli_args.hpp"
#include "commands.hpp"
#include "lgp/emit/emit.hpp"
#include "lgp/emit/gpu_cost.hpp"
#include "lgp/emit/vulkan_run.hpp"
#include "lgp/io/result.hpp"
#include "lgp/io/terminal_text.hpp"
#include "table_source.hpp"

namespace {

// Messages quote names from the front file: shown as text, never as escape sequences.
int fail(const std::string& msg) {
  std::fprintf(stderr, "error: %s\n", lgp::terminalSafe(msg).c_str());
  return 2;
}

std::string num(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.3g", v);
  return std::isfinite(v) ? b : "inf";
}

// The inputs of `t` with values outside the domain `in` records, as "r in [0.5, 1]" (empty:
// none).
std::string outsideDomain(const lgp::emit::EmitInput& in, const lgp::Table& t) {
  std::string out;
  for (size_t i = 0; i < in.domain.size() && i < t.numInputs(); ++i) {
    const auto [lo, hi] = std::minmax_element(t.inputs[i].begin(), t.inputs[i].end());
    if (lo == t.inputs[i].end() || (*lo >= in.domain[i].lo && *hi <= in.domain[i].hi)) continue;
    out += (out.empty() ? "" : ", ") + in.input_names[i] + " in [" + num(in.domain[i].lo) + ", " +
           num(in.domain[i].hi) + "]";
  }
  return out;
}

// `--verify vulkan`: every language and precision on lavapipe; the report goes to stderr so that
// stdout stays the code.
int verifyVulkan(const lgp::emit::EmitInput& in, const lgp::Table& t, size_t member, double bound,
                 const lgp::emit::EmitOptions& eo) {
  lgp::emit::VerifyOptions vo;
  vo.fast = eo.fast;
  vo.pow_rewrites = eo.pow_rewrites;
  vo.domain_rewrites = eo.domain_rewrites;
  auto checks = lgp::emit::verifyOnVulkan(in, t, vo);
  if (!checks) return fail("--verify vulkan: " + checks.error());
  const auto st = lgp::emit::vulkanRunStatus();
  std::fprintf(stderr, "lgp emit: member %zu run on %s over %zu rows\n", member, st.detail.c_str(),
               t.rows());
  bool ok = true;
  for (const auto& c : *checks) {
    const std::string head =
        std::string(lgp::emit::toString(c.lang)) + " " + std::string(lgp::toString(c.precision));
    if (c.skipped) {
      std::fprintf(stderr, "  %-11s skipped: %s\n", head.c_str(), c.why.c_str());
      continue;
    }
    for (const auto& o : c.outputs) {
      const bool pass = o.nonfinite == 0 && o.max_scaled_ulp <= bound;
      ok = ok && pass;
      std::fprintf(
          stderr,
          "  %-11s %-6s vs %s: max |diff| %s (%s ulp; %s ulp of max|y|)%s; vs truth rmse "
          "%s max %s (lgp %s %s)%s\n",
          head.c_str(), o.name.c_str(), c.reference.c_str(), num(o.max_abs_diff).c_str(),
          num(o.max_ulp).c_str(), num(o.max_scaled_ulp).c_str(),
          o.nonfinite ? (", " + std::to_string(o.nonfinite) + " rows not finite").c_str() : "",
          num(o.driver.rmse).c_str(), num(o.driver.max_abs).c_str(), num(o.reference.rmse).c_str(),
          num(o.reference.max_abs).c_str(), pass ? "" : "  OVER THE BOUND");
    }
  }
  if (!ok) {
    std::fprintf(stderr, "lgp emit: --verify vulkan: disagreement over %g ulp of max|y|\n", bound);
    if (eo.domain_rewrites && !outsideDomain(in, t).empty())
      std::fprintf(stderr,
                   "lgp emit: the code assumes the front's domain (%s); the table has rows "
                   "outside it: emit with --no-domain-rewrites for code that holds there\n",
                   lgp::terminalSafe(outsideDomain(in, t)).c_str());
    return 1;
  }
  return 0;
}

cxxopts::Options emitOptions(const char* argv0) {
  cxxopts::Options opts(argv0,
                        "Export a front member as an HLSL, GLSL or C++ function that computes "
                        "what the search scored (see emit/README.md).");
  opts.positional_help("front.json");
  opts.add_options()("front", "front JSON written by `lgp run`", cxxopts::value<std::string>())(
      "l,lang", lgp::emit::languageChoices(),
      cxxopts::value<std::string>()->default_value(std::string(lgp::emit::allLanguages()[0].name)))(
      "m,member", "member index", cxxopts::value<size_t>())(
      "max-error", "the cheapest member with error <= E", cxxopts::value<double>())(
      "max-cost", "the most accurate member with cost <= C", cxxopts::value<double>())(
      "cost-target",
      "cost used by --max-cost: gpu-generic, nvidia, gcn, rdna, cpu (default: "
      "the run's cost model)",
      cxxopts::value<std::string>())("n,name", "function name",
                                     cxxopts::value<std::string>()->default_value("lgp_fit"))(
      "p,precision", "float; half (HLSL, GLSL); double (C++)",
      cxxopts::value<std::string>()->default_value("float"))(
      "fast", "raw operators where the protected branch is proven unreachable on the domain")(
      "no-pow-rewrites", "keep pow(x, 2) etc. as protected pow")(
      "no-domain-rewrites",
      "keep piecewise ops whose branch never switches on the domain (abs, saturate, min, max, "
      "select)")("snap",
                 "snap the member's constants to simple values first (needs the run's table)")(
      "tolerance", "relative error growth --snap allows",
      cxxopts::value<double>()->default_value(std::to_string(lgp::kSnapTolerance)))(
      "data", "the run's table for --snap (default: the config's data, found next to the front)",
      cxxopts::value<std::string>())(
      "cancel-bits", "warn when the member loses more than this many float32 bits to cancellation",
      cxxopts::value<double>()->default_value(std::to_string(lgp::kCancellationFlagBits)))(
      "exact-math", "C++ float: the interpreter's own exp2/log2/sin/cos (bit-identical)")(
      "table", "table (CSV/JSON) to re-measure the error of the emitted code on, e.g. in half",
      cxxopts::value<std::string>())("no-header", "omit the header comment")(
      "no-helpers", "omit the lgp_* helper definitions")(
      "verify",
      "vulkan: run the member's GLSL and HLSL, in float and half, as compute shaders on "
      "lavapipe over every row of the table (--table, else the run's) and compare with lgp; "
      "exit 1 beyond --verify-ulp",
      cxxopts::value<std::string>())(
      "verify-ulp",
      "bound for --verify: ulps of the output's largest |value| (float32; binary16 for GLSL half)",
      cxxopts::value<double>()->default_value("16"))(
      "no-measure", "omit the measured AMD instruction counts from the header (HLSL, GLSL)")(
      "o,out", "write to this file instead of stdout", cxxopts::value<std::string>())("h,help",
                                                                                      "this help");
  opts.parse_positional({"front"});
  return opts;
}

// The emitter's options from the command line (--lang is checked by the caller).
lgp::Expected<lgp::emit::EmitOptions> emitOptionsOf(const cxxopts::ParseResult& args,
                                                    lgp::emit::Language lang) {
  lgp::emit::EmitOptions eo;
  eo.function_name = args["name"].as<std::string>();
  const auto prec = lgp::emit::precisionFromString(args["precision"].as<std::string>());
  if (!prec)
    return lgp::Status::error("--precision: expected float, half or double (got '" +
                              args["precision"].as<std::string>() + "')");
  eo.precision = *prec;
  eo.fast = args.count("fast") > 0;
  eo.pow_rewrites = args.count("no-pow-rewrites") == 0;
  eo.domain_rewrites = args.count("no-domain-rewrites") == 0;
  eo.exact_math = args.count("exact-math") > 0;
  eo.header = args.count("no-header") == 0;
  eo.helpers = args.count("no-helpers") == 0;
  if (auto s = eo.validate(lang); !s) return lgp::Status::error("--" + s.message());
  return eo;
}

// The member --member, --max-error or --max-cost picks.
lgp::Expected<size_t> pickMember(const cxxopts::ParseResult& args, const nlohmann::json& front) {
  lgp::emit::MemberSelector sel;
  if (args.count("member")) sel.index = args["member"].as<size_t>();
  if (args.count("max-error")) sel.max_error = args["max-error"].as<double>();
  if (args.count("max-cost")) sel.max_cost = args["max-cost"].as<double>();
  if (args.count("cost-target")) {
    sel.cost_target = args["cost-target"].as<std::string>();
    if (!lgp::costTargetFromString(sel.cost_target))
      return lgp::Status::error("--cost-target: unknown target '" + sel.cost_target + "'");
  }
  return lgp::emit::selectMember(front, sel);
}

// The run's config, found from the front (its data next to the front, or --data).
lgp::Expected<lgp::RunConfig> runConfig(const cxxopts::ParseResult& args,
                                        const nlohmann::json& front, const std::string& path) {
  return lgp::frontRunConfig(front, path, args.count("data") ? args["data"].as<std::string>() : "");
}

// --snap: the member's constants snapped to simple values on the run's table, in the front.
lgp::Status snapMember(const cxxopts::ParseResult& args, nlohmann::json& front,
                       const std::string& path, size_t member) {
  lgp::SnapOptions so;
  so.tolerance = args["tolerance"].as<double>();
  if (!(so.tolerance >= 0)) return lgp::Status::error("--tolerance: must be >= 0");
  auto cfg = runConfig(args, front, path);
  if (!cfg) return lgp::Status::error(path + ": " + cfg.error());
  auto t = lgp::cli::loadRunTable(*cfg);
  if (!t) return t.status();
  auto sm = lgp::snapFrontMember(front, member, *cfg, *t, so);
  if (!sm) return lgp::Status::error(path + ": " + sm.error());
  front["members"][member] = *sm;  // emitted from the snapped program and metrics
  const nlohmann::json& m = front["members"][member];
  std::fprintf(stderr, "lgp emit: snapped %d constants (error %s -> %s)\n",
               m["snap"]["constants"].get<int>(), m["snap"]["error_before"].dump().c_str(),
               m["error"].dump().c_str());
  return lgp::Status::ok();
}

void warnCancellation(const nlohmann::json& m, size_t member, double max_bits) {
  if (!m.contains("cancellation") || !m["cancellation"].is_object()) return;
  const double bits = m["cancellation"].value("bits_lost", 0.0);
  if (bits > max_bits)
    std::fprintf(stderr,
                 "warning: member %zu loses %.1f of float32's 24 bits to cancellation (constants "
                 "that cancel); its result is fragile on a GPU, with or without FMA contraction\n",
                 member, bits);
}

// The table the code is measured (--table) or verified (--verify) on: --table, else for
// --verify the run's own.
lgp::Expected<std::optional<lgp::Table>> checkTable(const cxxopts::ParseResult& args,
                                                    const nlohmann::json& front,
                                                    const std::string& path,
                                                    const lgp::emit::EmitInput& in) {
  std::optional<lgp::Table> table;
  if (args.count("verify") && !args.count("table")) {
    // The run's own table, as --snap finds it.
    auto cfg = runConfig(args, front, path);
    if (!cfg) return lgp::Status::error(path + ": " + cfg.error() + " (or give --table)");
    auto t = lgp::cli::loadRunTable(*cfg);
    if (!t) return t.status();
    table = std::move(*t);
  }
  if (args.count("table")) {
    const std::string tp = args["table"].as<std::string>();
    auto raw = lgp::readTableFile(tp);
    if (!raw) return raw.status();
    auto t = lgp::selectColumns(*raw, in.input_names, in.output_names, "", tp);
    if (!t) return t.status();
    table = std::move(*t);
  }
  return table;
}

// The code to --out, else to stdout.
lgp::Status writeCode(const cxxopts::ParseResult& args, const std::string& code) {
  if (args.count("out"))
    // Through a temporary file, a device or pipe in place (writeTextAtomic): a failed write
    // is an error and never leaves a truncated file.
    return lgp::writeTextAtomic(code, args["out"].as<std::string>());
  std::cout << code << std::flush;
  if (!std::cout || std::fflush(stdout) != 0)
    return lgp::Status::error("standard output: write failed (" +
                              std::string(std::strerror(errno)) + ")");
  return lgp::Status::ok();
}

int emitMain(int argc, char** argv) {
  cxxopts::Options opts = emitOptions(argv[0]);
  auto parsed = lgp::cli::parseArgs(opts, argc, argv, "front",
                                    "no front file given (lgp emit front.json --lang hlsl)");
  if (const int* code = std::get_if<int>(&parsed)) return *code;
  const cxxopts::ParseResult& args = std::get<cxxopts::ParseResult>(parsed);
  const std::string path = args["front"].as<std::string>();
  auto front = lgp::readFrontJson(path);
  if (!front) return fail(front.error());

  const auto lang = lgp::emit::languageFromString(args["lang"].as<std::string>());
  if (!lang)
    return fail("--lang: expected " + lgp::emit::languageChoices() + " (got '" +
                args["lang"].as<std::string>() + "')");
  auto eo = emitOptionsOf(args, *lang);
  if (!eo) return fail(eo.error());
  auto member = pickMember(args, *front);
  if (!member) return fail(member.error());
  if (args.count("snap"))
    if (auto st = snapMember(args, *front, path, *member); !st) return fail(st.message());
  warnCancellation((*front)["members"][*member], *member, args["cancel-bits"].as<double>());

  auto in = lgp::emit::emitInputFromFront(*front, *member);
  if (!in) return fail(path + ": " + in.error());
  if (args.count("verify") && args["verify"].as<std::string>() != "vulkan")
    return fail("--verify: the only driver is 'vulkan' (got '" + args["verify"].as<std::string>() +
                "')");
  auto table = checkTable(args, *front, path, *in);
  if (!table) return fail(table.error());
  if (args.count("table")) {
    eo->table = &**table;
    eo->table_label = std::filesystem::path(args["table"].as<std::string>()).filename().string();
  }
  eo->source = path + " member " + std::to_string(*member);
  // The code as emitted, compiled to AMD ISA: the header states what it costs.
  auto e = args.count("no-measure") ? lgp::emit::emitProgram(*in, *lang, *eo)
                                    : lgp::emit::emitMeasured(*in, *lang, *eo);
  if (!e) return fail(e.error());
  if (const std::string w = lgp::emit::halfRangeWarning(*e); !w.empty())
    std::fprintf(stderr, "warning: member %zu: %s\n", *member, w.c_str());
  if (auto st = writeCode(args, e->code); !st) return fail(st.message());
  if (args.count("verify"))
    return verifyVulkan(*in, **table, *member, args["verify-ulp"].as<double>(), *eo);
  return 0;
}

}  // namespace

LGP_REGISTER_COMMAND(kEmitCommand, "emit", "export a front member as HLSL, GLSL or C++", emitMain);
