// `lgp front result.json`: print a front as a table.
#include <cstdio>
#include <cxxopts.hpp>
#include <iostream>

#include "cli_args.hpp"
#include "commands.hpp"
#include "lgp/io/result.hpp"

namespace {

int frontMain(int argc, char** argv) {
  cxxopts::Options opts(argv[0],
                        "Print the Pareto front of a run (front JSON written by `lgp run`).");
  opts.positional_help("front.json");
  opts.add_options()("front", "front JSON file", cxxopts::value<std::string>())(
      "json", "print the members as JSON instead of a table")("h,help", "this help");
  opts.parse_positional({"front"});
  auto parsed = lgp::cli::parseArgs(opts, argc, argv, "front", "no front file given");
  if (const int* code = std::get_if<int>(&parsed)) return *code;
  const cxxopts::ParseResult& args = std::get<cxxopts::ParseResult>(parsed);
  auto front = lgp::readFrontJson(args["front"].as<std::string>());
  if (!front) {
    std::fprintf(stderr, "error: %s\n", front.error().c_str());
    return 2;
  }
  if (args.count("json")) {
    std::cout << (*front)["members"].dump(2) << "\n";
    return 0;
  }
  const auto& t = (*front)["table"];
  std::printf("front: %zu members; table %s -> %s, %zu rows; cost model %s; error %s\n",
              (*front)["members"].size(), t["inputs"].dump().c_str(), t["outputs"].dump().c_str(),
              t.value("rows", size_t{0}), front->value("cost_model", "?").c_str(),
              front->value("error_metric", "?").c_str());
  std::fputs(lgp::formatFrontTable(*front).c_str(), stdout);
  return 0;
}

}  // namespace

LGP_REGISTER_COMMAND(kFrontCommand, "front", "print the Pareto front of a result file", frontMain);
