// `lgp status [RUN] [--daemon URL] [--json]`: the runs lgpd knows (one line each), or one run
// in detail. Exit code 1 when the daemon cannot be reached or the run is unknown.
#include <cmath>
#include <cstdio>
#include <string>

#include <cxxopts.hpp>
#include <nlohmann/json.hpp>

#include "cli_args.hpp"
#include "commands.hpp"
#include "daemon_client.hpp"
#include "lgp/io/terminal_text.hpp"

namespace lgp::cli {
namespace {

using nlohmann::json;

std::string num(const json& v, const char* fmt = "%.4g") {
  if (!v.is_number()) return "-";
  char buf[64];
  std::snprintf(buf, sizeof buf, fmt, v.get<double>());
  return buf;
}

// A field of the daemon's answer, null when absent (a hostile or broken daemon may send
// anything; const operator[] on a missing key is undefined behaviour).
const json& field(const json& r, const char* key) {
  static const json null;
  if (!r.is_object()) return null;
  const auto it = r.find(key);
  return it != r.end() ? *it : null;
}

// A string field, as text for the terminal ("" when absent or not a string).
std::string text(const json& r, const char* key) {
  const json& v = field(r, key);
  return v.is_string() ? terminalSafe(v.get<std::string>()) : "";
}

std::string generations(const json& r) {
  std::string s = std::to_string(r.value("generation", 0));
  const json& b = r.value("budget", json::object());
  if (b.contains("generations") && b["generations"].is_number_integer() &&
      b["generations"].get<int64_t>() > 0)
    s += "/" + std::to_string(b["generations"].get<int64_t>());
  return s;
}

int statusMain(int argc, char** argv) {
  cxxopts::Options opts("lgp status", "Show the runs of lgpd, or one run");
  // clang-format off
  opts.add_options()
    ("run", "run id", cxxopts::value<std::string>())
    ("daemon", "lgpd URL (default $LGP_DAEMON or http://127.0.0.1:8737)", cxxopts::value<std::string>()->default_value(""))
    ("json", "print the daemon's JSON")
    ("h,help", "this help");
  // clang-format on
  opts.parse_positional({"run"});
  opts.positional_help("[RUN]");
  auto parsed = parseArgs(opts, argc, argv, "", "");
  if (const int* code = std::get_if<int>(&parsed)) return *code;
  const cxxopts::ParseResult& args = std::get<cxxopts::ParseResult>(parsed);
  const std::string url = daemonUrl(args["daemon"].as<std::string>());
  const bool one = args.count("run") > 0;
  const std::string path =
      one ? "/api/v1/runs/" + args["run"].as<std::string>() : std::string("/api/v1/runs");
  auto got = daemonGetJson(url, path);
  if (!got) {
    std::fprintf(stderr, "error: %s\n", got.error().c_str());
    return 1;
  }
  json j = *got;
  if (args.count("json")) {
    std::printf("%s\n", terminalJson(j).c_str());
    return 0;
  }
  if (!one) {
    std::printf("%-16s  %-9s  %11s  %12s  %10s  %5s  %s\n", "RUN", "STATUS", "GENERATION",
                "EVALUATIONS", "BEST ERROR", "FRONT", "NAME");
    for (const auto& run : j.value("runs", json::array()))
      std::printf("%-16s  %-9s  %11s  %12llu  %10s  %5lld  %s\n", text(run, "id").c_str(),
                  text(run, "status").c_str(), generations(run).c_str(),
                  static_cast<unsigned long long>(run.value("evaluations", uint64_t{0})),
                  num(field(run, "best_error")).c_str(),
                  static_cast<long long>(run.value("front_size", 0)), text(run, "name").c_str());
    return 0;
  }
  const std::string name = text(j, "name");
  std::printf("run          %s%s\n", text(j, "id").c_str(),
              name.empty() ? "" : ("  (" + name + ")").c_str());
  std::printf("status       %s\n", text(j, "status").c_str());
  std::printf("generation   %s\n", generations(j).c_str());
  std::printf("evaluations  %llu (%s/s)\n",
              static_cast<unsigned long long>(j.value("evaluations", uint64_t{0})),
              num(field(j, "evals_per_s"), "%.3g").c_str());
  std::printf("elapsed      %s s\n", num(field(j, "elapsed_s"), "%.1f").c_str());
  std::printf("front        %lld members\n", static_cast<long long>(j.value("front_size", 0)));
  const json& best = j.value("best", json::object());
  for (const char* k : {"error", "cost", "discontinuity"}) {
    if (!best.contains(k)) continue;
    std::printf("best %-13s %s (member %s)\n", k, num(field(field(best, k), "value")).c_str(),
                num(field(field(best, k), "member"), "%.0f").c_str());
  }
  if (field(j, "checkpoint").is_object())
    std::printf("checkpoint   generation %s\n",
                num(field(field(j, "checkpoint"), "generation"), "%.0f").c_str());
  if (j.value("resumes", 0) > 0) std::printf("resumed      %d time(s)\n", j.value("resumes", 0));
  if (const std::string why = text(j, "stop_reason"); !why.empty())
    std::printf("stopped by   %s\n", why.c_str());
  if (j.contains("error"))
    std::printf("error        %s\n", terminalSafe(j["error"].dump()).c_str());
  return 0;
}

}  // namespace

LGP_REGISTER_COMMAND(kStatusCommand, "status", "show the runs of lgpd, or one run", statusMain);

}  // namespace lgp::cli
