// lgpd: runs lgp searches overnight from JSON configs, with durable SQLite checkpoints, an
// HTTP JSON API and a Pareto-front inspection page (README.md in this folder).
//
//   lgpd --data-dir DIR [--listen 127.0.0.1:8737] [--config lgpd.json] [--jobs N]
//        [--checkpoint-interval S] [--port-file FILE] [--init]
//
// A data dir with no database gets a new one on its first start. An empty, unreadable or
// corrupt database, or a used data dir whose database is missing, stops lgpd with exit 1
// unless --init is given (the bad file is then kept aside and a new database created).
//
// SIGINT/SIGTERM: the server stops, every running job checkpoints and stays "running", and
// the next lgpd resumes it. After a kill -9 the next lgpd resumes from the last checkpoint.
//
// One lgpd per data dir: a second one on the same dir exits 1 naming the first one's PID
// (data_dir_lock.hpp).
#include <csignal>
#include <cstdio>
#include <fstream>
#include <thread>

#include <pthread.h>
#include <spdlog/spdlog.h>
#include <cxxopts.hpp>

#include "api.hpp"
#include "daemon_config.hpp"
#include "data_dir_lock.hpp"
#include "files.hpp"
#include "http_server.hpp"
#include "jobs.hpp"
#include "lgp/core/data_roots.hpp"
#include "omp_env.hpp"
#include "store.hpp"

namespace {

int run(int argc, char** argv) {
  cxxopts::Options opts("lgpd", "lgp search daemon: job queue, HTTP API and inspection page");
  // clang-format off
  opts.add_options()
    ("data-dir", "directory for the SQLite state (created if missing)", cxxopts::value<std::string>())
    ("listen", "host:port to bind (port 0 = any free port)", cxxopts::value<std::string>())
    ("config", "daemon config JSON (see README.md); flags override it", cxxopts::value<std::string>())
    ("jobs", "jobs running at once", cxxopts::value<int>())
    ("checkpoint-interval", "seconds between checkpoints of a running job", cxxopts::value<double>())
    ("progress-interval", "seconds between progress rows", cxxopts::value<double>())
    ("front-interval", "seconds between live front snapshots", cxxopts::value<double>())
    ("port-file", "write the bound port to this file once listening", cxxopts::value<std::string>())
    ("init", "create a new database where it is missing from a used data dir, empty or unreadable (the old file is kept aside)")
    ("log-level", "trace|debug|info|warn|error", cxxopts::value<std::string>()->default_value("info"))
    ("h,help", "this help");
  // clang-format on
  auto args = opts.parse(argc, argv);
  if (args.count("help")) {
    std::printf("%s\n", opts.help().c_str());
    return 0;
  }
  spdlog::set_level(spdlog::level::from_str(args["log-level"].as<std::string>()));

  lgpd::DaemonConfig cfg;
  if (args.count("config")) {
    // The same limits as a request body: depth, numbers, duplicate keys (the message names
    // the byte or the key).
    auto j = lgpd::readJsonDocument(args["config"].as<std::string>(), size_t{1} << 20);
    if (!j) {
      std::fprintf(stderr, "error: %s\n", j.error().c_str());
      return 2;
    }
    if (auto s = lgpd::applyDaemonConfigJson(*j, cfg); !s) {
      std::fprintf(stderr, "error: %s: %s\n", args["config"].as<std::string>().c_str(),
                   s.message().c_str());
      return 2;
    }
    std::filesystem::path dir =
        std::filesystem::path(args["config"].as<std::string>()).parent_path();
    lgpd::resolveConfigFilePaths(cfg, dir.empty() ? "." : dir);
  }
  if (args.count("data-dir")) cfg.data_dir = args["data-dir"].as<std::string>();
  if (args.count("listen")) cfg.listen = args["listen"].as<std::string>();
  if (args.count("jobs")) cfg.max_jobs = args["jobs"].as<int>();
  if (args.count("checkpoint-interval"))
    cfg.checkpoint_interval_s = args["checkpoint-interval"].as<double>();
  if (args.count("progress-interval"))
    cfg.progress_interval_s = args["progress-interval"].as<double>();
  if (args.count("front-interval")) cfg.front_interval_s = args["front-interval"].as<double>();
  if (auto s = cfg.validate(); !s) {
    std::fprintf(stderr, "error: %s\n", s.message().c_str());
    return 2;
  }
  auto addr = lgpd::parseListen(cfg.listen);
  if (!cfg.allowed_data_dirs.empty()) {
    // Every table and scene reader of this process checks the file it opened (not only its
    // path) against these; inline tables are lgpd's own files under tables/.
    auto roots = cfg.allowed_data_dirs;
    roots.push_back(cfg.data_dir / "tables");
    lgp::setDataRoots(roots);
  }

  // Signals are taken by one thread with sigwait; every other thread has them blocked.
  sigset_t sigs;
  sigemptyset(&sigs);
  sigaddset(&sigs, SIGINT);
  sigaddset(&sigs, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &sigs, nullptr);
  std::signal(SIGPIPE, SIG_IGN);

  // Before the database is opened or a run resumed: a second daemon on this dir stops here.
  auto dir_lock = lgpd::DataDirLock::acquire(cfg.data_dir);
  if (!dir_lock) {
    std::fprintf(stderr, "error: %s\n", dir_lock.error().c_str());
    return 1;
  }
  auto store = lgpd::Store::open(cfg.data_dir, args.count("init") > 0);
  if (!store) {
    std::fprintf(stderr, "error: %s\n", store.error().c_str());
    return 1;
  }
  spdlog::info("state in {}", (*store)->path().string());

  lgpd::JobManager jobs(**store, cfg);
  lgpd::HttpLimits limits;
  limits.workers = cfg.http_threads;
  limits.max_connections = cfg.max_connections;
  limits.max_connections_per_client = cfg.connectionsPerClient();
  limits.read_timeout_s = cfg.read_timeout_s;
  limits.request_timeout_s = cfg.request_timeout_s;
  limits.write_timeout_s = cfg.write_timeout_s;
  limits.keep_alive_timeout_s = cfg.keep_alive_timeout_s;
  limits.keep_alive_max_requests = cfg.keep_alive_max_requests;
  limits.max_request_bytes = cfg.max_body_bytes;
  lgpd::HttpServer server(limits, lgpd::makeApi(**store, jobs));
  auto bound = server.bind(addr->host, addr->port);
  if (!bound) {
    std::fprintf(stderr, "error: %s\n", bound.error().c_str());
    return 1;
  }
  const int port = *bound;
  // Jobs start before the server answers, so the first request sees the resumed runs.
  if (auto s = jobs.start(); !s) {
    std::fprintf(stderr, "error: %s\n", s.message().c_str());
    return 1;
  }
  if (auto s = server.serve(); !s) {
    std::fprintf(stderr, "error: %s\n", s.message().c_str());
    jobs.shutdown();
    return 1;
  }
  if (args.count("port-file")) {
    // Written via rename so a reader never sees a partial number.
    std::string path = args["port-file"].as<std::string>();
    {
      std::ofstream f(path + ".tmp");
      f << port << "\n";
    }
    std::rename((path + ".tmp").c_str(), path.c_str());
  }
  spdlog::info(
      "listening on http://{}:{} ({} job slot(s), checkpoint every {} s, {} HTTP workers, at "
      "most {} connections, {} per client{})",
      addr->host.find(':') != std::string::npos ? "[" + addr->host + "]" : addr->host, port,
      cfg.max_jobs, cfg.checkpoint_interval_s, cfg.http_threads, cfg.max_connections,
      cfg.connectionsPerClient(), cfg.token.empty() ? "" : ", bearer token required");

  int sig = 0;
  sigwait(&sigs, &sig);
  spdlog::info("signal {}: stopping", sig);
  server.stop();
  spdlog::info("checkpointing running jobs");
  jobs.shutdown();
  spdlog::info("stopped");
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  lgp::cli::ensurePassiveOpenMpWaits(argv);  // jobs run searches: same reason as in `lgp`
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  }
}
