// `lgp emit front.json --lang hlsl|glsl|cpp`: export one front member as shader or C++ code.
#include <cstdio>
#include <cxxopts.hpp>
#include <fstream>
#include <iostream>

#include "cli_args.hpp"
#include "commands.hpp"
#include "lgp/emit/emit.hpp"
#include "lgp/io/result.hpp"

namespace {

int fail(const std::string& msg) {
  std::fprintf(stderr, "error: %s\n", msg.c_str());
  return 2;
}

int emitMain(int argc, char** argv) {
  cxxopts::Options opts(argv[0],
                        "Export a front member as an HLSL, GLSL or C++ function that computes "
                        "what the search scored (see emit/README.md).");
  opts.positional_help("front.json");
  opts.add_options()("front", "front JSON written by `lgp run`", cxxopts::value<std::string>())(
      "l,lang", "hlsl, glsl or cpp", cxxopts::value<std::string>()->default_value("hlsl"))(
      "m,member", "member index", cxxopts::value<size_t>())(
      "max-error", "the cheapest member with error <= E", cxxopts::value<double>())(
      "max-cost", "the most accurate member with cost <= C", cxxopts::value<double>())(
      "cost-target",
      "cost used by --max-cost: gpu-generic, nvidia, gcn, rdna, cpu (default: "
      "the run's cost model)",
      cxxopts::value<std::string>())("n,name", "function name",
                                     cxxopts::value<std::string>()->default_value("lgp_fit"))(
      "p,precision", "float; half (HLSL); double (C++)",
      cxxopts::value<std::string>()->default_value("float"))(
      "fast", "raw operators where the protected branch is proven unreachable on the domain")(
      "no-pow-rewrites", "keep pow(x, 2) etc. as protected pow")(
      "exact-math", "C++ float: the interpreter's own exp2/log2/sin/cos (bit-identical)")(
      "table", "table (CSV/JSON) to re-measure the error of the emitted code on, e.g. in half",
      cxxopts::value<std::string>())("no-header", "omit the header comment")(
      "no-helpers", "omit the lgp_* helper definitions")(
      "o,out", "write to this file instead of stdout", cxxopts::value<std::string>())("h,help",
                                                                                      "this help");
  opts.parse_positional({"front"});
  auto parsed = lgp::cli::parseArgs(opts, argc, argv, "front",
                                    "no front file given (lgp emit front.json --lang hlsl)");
  if (const int* code = std::get_if<int>(&parsed)) return *code;
  const cxxopts::ParseResult& args = std::get<cxxopts::ParseResult>(parsed);
  const std::string path = args["front"].as<std::string>();
  auto front = lgp::readFrontJson(path);
  if (!front) return fail(front.error());

  const auto lang = lgp::emit::languageFromString(args["lang"].as<std::string>());
  if (!lang)
    return fail("--lang: expected hlsl, glsl or cpp (got '" + args["lang"].as<std::string>() +
                "')");
  lgp::emit::EmitOptions eo;
  eo.function_name = args["name"].as<std::string>();
  const auto prec = lgp::emit::precisionFromString(args["precision"].as<std::string>());
  if (!prec)
    return fail("--precision: expected float, half or double (got '" +
                args["precision"].as<std::string>() + "')");
  eo.precision = *prec;
  eo.fast = args.count("fast") > 0;
  eo.pow_rewrites = args.count("no-pow-rewrites") == 0;
  eo.exact_math = args.count("exact-math") > 0;
  eo.header = args.count("no-header") == 0;
  eo.helpers = args.count("no-helpers") == 0;
  if (auto s = eo.validate(*lang); !s) return fail("--" + s.message());

  lgp::emit::MemberSelector sel;
  if (args.count("member")) sel.index = args["member"].as<size_t>();
  if (args.count("max-error")) sel.max_error = args["max-error"].as<double>();
  if (args.count("max-cost")) sel.max_cost = args["max-cost"].as<double>();
  if (args.count("cost-target")) {
    sel.cost_target = args["cost-target"].as<std::string>();
    if (!lgp::costTargetFromString(sel.cost_target))
      return fail("--cost-target: unknown target '" + sel.cost_target + "'");
  }
  auto member = lgp::emit::selectMember(*front, sel);
  if (!member) return fail(member.error());

  auto in = lgp::emit::emitInputFromFront(*front, *member);
  if (!in) return fail(path + ": " + in.error());
  std::optional<lgp::Table> table;
  if (args.count("table")) {
    const std::string tp = args["table"].as<std::string>();
    auto raw = lgp::readTableFile(tp);
    if (!raw) return fail(raw.error());
    auto t = lgp::selectColumns(*raw, in->input_names, in->output_names, "", tp);
    if (!t) return fail(t.error());
    table = std::move(*t);
    eo.table = &*table;
  }
  eo.source = path + " member " + std::to_string(*member);
  auto e = lgp::emit::emitProgram(*in, *lang, eo);
  if (!e) return fail(e.error());
  if (args.count("out")) {
    const std::string out = args["out"].as<std::string>();
    std::ofstream f(out);
    if (!(f << e->code)) return fail(out + ": cannot write");
  } else {
    std::cout << e->code;
  }
  return 0;
}

}  // namespace

LGP_REGISTER_COMMAND(kEmitCommand, "emit", "export a front member as HLSL, GLSL or C++", emitMain);
