// `lgp submit cfg.json [--daemon URL] [--name NAME] [--inline] [--wait]`: sends a run config
// (the same JSON `lgp run` takes) to lgpd and prints the new run's id on stdout.
//
// Relative data paths in the config are resolved against the config file's directory before
// sending, so the daemon reads the same files `lgp run cfg.json` would. --inline embeds the
// table itself (data.table), for a daemon that cannot see the file.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <thread>

#include <cxxopts.hpp>
#include <nlohmann/json.hpp>

#include "cli_args.hpp"
#include "commands.hpp"
#include "daemon_client.hpp"
#include "lgp/config/config.hpp"
#include "lgp/config/json_reader.hpp"
#include "lgp/core/table.hpp"
#include "lgp/io/terminal_text.hpp"

namespace lgp::cli {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// lgp-table/1 JSON holding every column of a file, keeping its declared roles.
Expected<json> inlineTable(const fs::path& path) {
  auto raw = readTableFile(path);
  if (!raw) return raw.status();
  json cols = json::object();
  for (size_t i = 0; i < raw->names.size(); ++i) cols[raw->names[i]] = raw->columns[i];
  json t = {{"format", "lgp-table/1"}, {"columns", cols}};
  if (!raw->default_inputs.empty()) t["inputs"] = raw->default_inputs;
  if (!raw->default_outputs.empty()) t["outputs"] = raw->default_outputs;
  if (!raw->weights.empty()) t["weights"] = raw->weights;
  if (!raw->meta.empty()) t["meta"] = raw->meta;
  return t;
}

int submitMain(int argc, char** argv) {
  cxxopts::Options opts("lgp submit", "Submit a run config to lgpd; prints the run id");
  // clang-format off
  opts.add_options()
    ("config", "run config JSON", cxxopts::value<std::string>())
    ("daemon", "lgpd URL (default $LGP_DAEMON or http://127.0.0.1:8737)", cxxopts::value<std::string>()->default_value(""))
    ("name", "label shown in the run list", cxxopts::value<std::string>()->default_value(""))
    ("inline", "embed the data file in the submission")
    ("wait", "wait until the run ends, printing progress to stderr")
    ("h,help", "this help");
  // clang-format on
  opts.parse_positional({"config"});
  opts.positional_help("cfg.json");
  auto parsed = parseArgs(opts, argc, argv, "config", "no config given");
  if (const int* code = std::get_if<int>(&parsed)) return *code;
  const cxxopts::ParseResult& args = std::get<cxxopts::ParseResult>(parsed);
  const fs::path cfg_path = args["config"].as<std::string>();
  auto text = lgp::readInputFile(cfg_path, lgp::kMaxConfigBytes);
  if (!text) {
    std::fprintf(stderr, "error: %s\n", text.error().c_str());
    return 2;
  }
  auto parsed_cfg = lgp::parseJson(*text);
  if (!parsed_cfg) {
    std::fprintf(stderr, "error: %s: %s\n", cfg_path.c_str(), parsed_cfg.error().c_str());
    return 2;
  }
  json cfg = std::move(*parsed_cfg);
  if (!cfg.is_object()) {
    std::fprintf(stderr, "error: %s: not a JSON object\n", cfg_path.c_str());
    return 2;
  }
  const fs::path base = fs::absolute(cfg_path).parent_path();
  if (cfg.contains("data") && cfg["data"].is_object()) {
    json& data = cfg["data"];
    for (const char* key : {"path", "scene", "cache_dir"}) {
      if (!data.contains(key) || !data[key].is_string()) continue;
      fs::path p = data[key].get<std::string>();
      if (!p.empty() && p.is_relative()) data[key] = (base / p).lexically_normal().string();
    }
    if (args.count("inline")) {
      if (!data.contains("path") || !data["path"].is_string()) {
        std::fprintf(stderr, "error: --inline needs data.path (a CSV or JSON table)\n");
        return 2;
      }
      auto t = inlineTable(data["path"].get<std::string>());
      if (!t) {
        std::fprintf(stderr, "error: %s\n", t.error().c_str());
        return 2;
      }
      data.erase("path");
      data["table"] = std::move(*t);
    }
  }
  if (!args["name"].as<std::string>().empty()) cfg["name"] = args["name"].as<std::string>();

  const std::string url = daemonUrl(args["daemon"].as<std::string>());
  auto r = daemonRequest(url, "POST", "/api/v1/runs", cfg.dump());
  if (!r) {
    std::fprintf(stderr, "error: %s\n", r.error().c_str());
    return 1;
  }
  if (r->status != 201) {
    std::fprintf(stderr, "error: %s rejected the config: %s (HTTP %d)\n", url.c_str(),
                 r->errorMessage().c_str(), r->status);
    return 1;
  }
  const json reply = r->json();
  const std::string id = reply.is_object() && reply.contains("id") && reply["id"].is_string()
                             ? terminalSafe(reply["id"].get<std::string>())
                             : "";
  if (id.empty() || id.find_first_not_of("0123456789abcdef") != std::string::npos) {
    std::fprintf(stderr, "error: %s answered 201 without a run id\n", url.c_str());
    return 1;
  }
  std::printf("%s\n", id.c_str());
  std::fflush(stdout);
  std::fprintf(stderr, "queued run %s on %s\n", id.c_str(), url.c_str());
  if (!args.count("wait")) return 0;

  std::string last;
  for (;;) {
    std::this_thread::sleep_for(std::chrono::seconds(1));
    auto s = daemonRequest(url, "GET", "/api/v1/runs/" + id);
    if (!s) {
      std::fprintf(stderr, "error: %s\n", s.error().c_str());
      return 1;
    }
    if (s->status != 200) {
      std::fprintf(stderr, "error: %s\n", s->errorMessage().c_str());
      return 1;
    }
    json j = s->json();
    if (!j.is_object()) {
      std::fprintf(stderr, "error: %s: the run's status is not a JSON object\n", url.c_str());
      return 1;
    }
    const std::string status = j.contains("status") && j["status"].is_string()
                                   ? terminalSafe(j["status"].get<std::string>())
                                   : "";
    char line[256];
    std::snprintf(line, sizeof line, "%s: gen %d, %llu evals, %.1f s, front %lld", status.c_str(),
                  j.value("generation", 0),
                  static_cast<unsigned long long>(j.value("evaluations", uint64_t{0})),
                  j.value("elapsed_s", 0.0), static_cast<long long>(j.value("front_size", 0)));
    if (line != last) std::fprintf(stderr, "%s\n", line);
    last = line;
    if (status == "finished") return 0;
    if (status == "failed" || status == "cancelled") {
      if (j.contains("error"))
        std::fprintf(stderr, "error: %s\n", terminalSafe(j["error"].dump()).c_str());
      return 1;
    }
  }
}

}  // namespace

LGP_REGISTER_COMMAND(kSubmitCommand, "submit", "send a run config to lgpd (the daemon)",
                     submitMain);

}  // namespace lgp::cli
