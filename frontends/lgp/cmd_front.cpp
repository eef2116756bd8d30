// `lgp front result.json` prints a front as a table (each member's simplified formula, its
// bits lost to cancellation); `--snap` snaps constants first against the run's table;
// `lgp front RUN --daemon URL` fetches a run's front from lgpd.
#include <cstdio>
#include <cxxopts.hpp>
#include <iostream>

#include "cli_args.hpp"
#include "commands.hpp"
#include "lgp/io/result.hpp"
#include "lgp/io/terminal_text.hpp"
#include "table_source.hpp"
#ifdef LGP_HAVE_EMIT
#include "lgp/emit/gpu_cost.hpp"
#endif
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
      "o,out", "with --daemon: also save the front JSON here; with --snap: save the snapped front",
      cxxopts::value<std::string>())(
      "snap",
      "snap every member's constants to simple values (0, integers, p/q, short decimals) where "
      "the error grows by less than --tolerance; needs the run's table")(
      "tolerance", "relative error growth --snap allows",
      cxxopts::value<double>()->default_value(std::to_string(lgp::kSnapTolerance)))(
      "data", "the run's table for --snap (default: the config's data, found next to the front)",
      cxxopts::value<std::string>())(
      "cancel-bits", "flag members that lose more than this many float32 bits to cancellation",
      cxxopts::value<double>())(
      "measure",
      "compile every member and reference to AMD ISA (RDNA2, RDNA3, GCN5) and show the measured "
      "instructions; with -o the front is saved with them")("h,help", "this help");
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
  const std::string path = args["front"].as<std::string>();
  auto front = lgp::readFrontJson(path);
  if (!front) {
    std::fprintf(stderr, "error: %s\n", lgp::terminalSafe(front.error()).c_str());
    return 2;
  }
  lgp::FrontTableOptions to;
  if (args.count("cancel-bits")) to.cancel_bits = args["cancel-bits"].as<double>();
  std::string snapped_note;
  if (args.count("snap")) {
    auto fail = [&](const std::string& m) {
      std::fprintf(stderr, "error: %s\n", lgp::terminalSafe(path + ": " + m).c_str());
      return 2;
    };
    lgp::SnapOptions so;
    so.tolerance = args["tolerance"].as<double>();
    if (!(so.tolerance >= 0)) return fail("--tolerance: must be >= 0");
    auto cfg =
        lgp::frontRunConfig(*front, path, args.count("data") ? args["data"].as<std::string>() : "");
    if (!cfg) return fail(cfg.error());
    auto table = lgp::cli::loadRunTable(*cfg);
    if (!table) return fail(table.error());
    int constants = 0, members = 0;
    for (size_t i = 0; i < (*front)["members"].size(); ++i) {
      auto m = lgp::snapFrontMember(*front, i, *cfg, *table, so);
      if (!m) return fail(m.error());
      const int n = (*m)["snap"]["constants"].get<int>();
      constants += n;
      members += n > 0;
      (*front)["members"][i] = std::move(*m);
    }
    char buf[160];
    std::snprintf(buf, sizeof buf,
                  "snapped: %d constants in %d of %zu members (error growth <= %g relative)\n",
                  constants, members, (*front)["members"].size(), so.tolerance);
    snapped_note = buf;
    if (args.count("out"))
      if (auto st = lgp::writeFrontJson(*front, args["out"].as<std::string>()); !st)
        return fail(st.message());
  }
  if (args.count("measure")) {
#ifdef LGP_HAVE_EMIT
    lgp::emit::addMeasuredCost(*front);
    const auto& info = (*front)["cost_measured_info"];
    if (info.contains("unavailable"))
      std::fprintf(stderr, "warning: --measure: %s\n",
                   lgp::terminalSafe(info["unavailable"].get<std::string>()).c_str());
    if (args.count("out") && !args.count("daemon"))
      if (auto st = lgp::writeFrontJson(*front, args["out"].as<std::string>()); !st) {
        std::fprintf(stderr, "error: %s\n", lgp::terminalSafe(st.message()).c_str());
        return 1;
      }
#else
    std::fprintf(stderr, "error: --measure: this build has no emit library\n");
    return 2;
#endif
  }
  if (args.count("json")) {
    std::cout << lgp::terminalJson((*front)["members"]) << "\n";
    return 0;
  }
  // Every text of the file is printed as text: the file may hold escape sequences.
  const auto& t = (*front)["table"];
  const auto field = [&](const char* key) {
    const auto it = front->find(key);
    return it != front->end() && it->is_string() ? lgp::terminalSafe(it->get<std::string>())
                                                 : std::string("?");
  };
  const auto rows = t.find("rows");
  std::printf("front: %zu members; table %s -> %s, %zu rows; cost model %s; error %s\n",
              (*front)["members"].size(), lgp::terminalSafe(t["inputs"].dump()).c_str(),
              lgp::terminalSafe(t["outputs"].dump()).c_str(),
              rows != t.end() && rows->is_number_unsigned() ? rows->get<size_t>() : size_t{0},
              field("cost_model").c_str(), field("error_metric").c_str());
  std::fputs(lgp::formatFrontTable(*front, to).c_str(), stdout);
  std::fputs(snapped_note.c_str(), stdout);
  return 0;
}

}  // namespace

LGP_REGISTER_COMMAND(kFrontCommand, "front", "print the Pareto front of a result file", frontMain);
