// `lgp front result.json` prints a front as a table; `lgp front RUN --daemon URL` fetches a
// run's front from lgpd.
#include <cstdio>
#include <cxxopts.hpp>
#include <iostream>

#include "cli_args.hpp"
#include "commands.hpp"
#include "lgp/io/result.hpp"
#ifdef LGP_HAVE_DAEMON_CLIENT
#include "daemon_client.hpp"
#endif

namespace {

int frontMain(int argc, char** argv) {
  cxxopts::Options opts(argv[0],
                        "Print the Pareto front of a run (front JSON written by `lgp run`).");
  opts.positional_help("front.json | RUN --daemon URL");
  opts.add_options()("front", "front JSON file, or a run id with --daemon",
                     cxxopts::value<std::string>())("json",
                                                    "print the members as JSON instead of a table")(
      "daemon", "lgpd URL; the positional argument is then a run id",
      cxxopts::value<std::string>())(
      "o,out", "with --daemon: also save the front JSON here", cxxopts::value<std::string>())(
      "h,help", "this help");
  opts.parse_positional({"front"});
  auto parsed = lgp::cli::parseArgs(opts, argc, argv, "front", "no front file given");
  if (const int* code = std::get_if<int>(&parsed)) return *code;
  const cxxopts::ParseResult& args = std::get<cxxopts::ParseResult>(parsed);
  if (args.count("daemon")) {
#ifdef LGP_HAVE_DAEMON_CLIENT
    return lgp::cli::daemonFront(
        lgp::cli::daemonUrl(args["daemon"].as<std::string>()), args["front"].as<std::string>(),
        args.count("out") ? args["out"].as<std::string>() : "", args.count("json") > 0);
#else
    std::fprintf(stderr,
                 "error: --daemon: this build has no daemon client (LGP_WITH_DAEMON=OFF)\n");
    return 2;
#endif
  }
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
