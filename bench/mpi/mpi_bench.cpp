// lgp_mpi_bench: one search on 1 rank x T threads against R ranks x 1 thread (asynchronous
// and synchronous migration), at equal wall time, interleaved per seed; the front quality at
// the quality report's cost levels, throughput, and the share of each run spent inside MPI
// calls. Then a ping-pong over the same launcher measures latency and bandwidth, and a model
// built from those figures and the measured generation times predicts the communication share
// at 8 to 64 ranks. Writes report.md and results.json.
//
//   lgp_mpi_bench [--config bench/quality/configs/dfg.json] [--budget 60] [--seeds 3]
//                 [--ranks 2] [--out bench/results/mpi] [--lgp PATH] [--mpirun PATH]
//   mpirun -np 2 lgp_mpi_bench --pingpong OUT.json     (run by the driver itself)
#include <mpi.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "../bench_util.hpp"

namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

// --- ping-pong (under mpirun) --------------------------------------------------------------

int pingpong(const std::string& out) {
  MPI_Init(nullptr, nullptr);
  int rank = 0, size = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  json rows = json::array();
  for (int bytes : {8, 1024, 16384, 262144, 1048576}) {
    std::vector<char> buf(static_cast<size_t>(bytes));
    const int reps = bytes >= 262144 ? 200 : 2000;
    MPI_Barrier(MPI_COMM_WORLD);
    const double t0 = MPI_Wtime();
    for (int i = 0; i < reps && size > 1; ++i) {
      if (rank == 0) {
        MPI_Send(buf.data(), bytes, MPI_BYTE, 1, 0, MPI_COMM_WORLD);
        MPI_Recv(buf.data(), bytes, MPI_BYTE, 1, 0, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
      } else if (rank == 1) {
        MPI_Recv(buf.data(), bytes, MPI_BYTE, 0, 0, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        MPI_Send(buf.data(), bytes, MPI_BYTE, 0, 0, MPI_COMM_WORLD);
      }
    }
    const double one_way = (MPI_Wtime() - t0) / (2.0 * reps);
    rows.push_back({{"bytes", bytes}, {"one_way_s", one_way}});
  }
  // An 8-byte allreduce, as the synchronous mode does every generation.
  uint64_t in = 1, sum = 0;
  MPI_Barrier(MPI_COMM_WORLD);
  const double t0 = MPI_Wtime();
  for (int i = 0; i < 2000; ++i) MPI_Allreduce(&in, &sum, 1, MPI_UINT64_T, MPI_SUM, MPI_COMM_WORLD);
  const double allreduce = (MPI_Wtime() - t0) / 2000;
  // Decoding one progress report of a full archive (256 objective vectors), as rank 0 does
  // for every rank each report period.
  json front = json::array();
  for (int i = 0; i < 256; ++i) front.push_back({1.0 / (i + 1), i * 0.5, 0.0});
  const auto report = json::to_msgpack(json{{"generation", 1}, {"front", front}});
  const double t1 = MPI_Wtime();
  size_t sink = 0;
  for (int i = 0; i < 200; ++i) sink += json::from_msgpack(report)["front"].size();
  const double decode = (MPI_Wtime() - t1) / 200;
  if (rank == 0)
    std::ofstream(out) << json{{"sizes", rows},
                               {"allreduce_8b_s", allreduce},
                               {"report_bytes", report.size()},
                               {"report_decode_s", decode},
                               {"check", sink}}
                              .dump(2)
                       << "\n";
  MPI_Finalize();
  return 0;
}

// --- the driver ------------------------------------------------------------------------------

struct Options {
  std::string config = "bench/quality/configs/dfg.json";
  double budget = 60;
  int seeds = 3;
  int ranks = 2;
  std::string out = "bench/results/mpi";
  std::string lgp, mpirun = "mpirun";
  std::string self;
};

struct Run {
  std::string mode;
  int seed = 0;
  int code = -1;
  double wall_s = 0, cpu_s = 0;
  json front;
};

// Runs argv (no shell) with output to `log`; wall and CPU time of the whole process tree.
Run launch(const std::vector<std::string>& args, const fs::path& log) {
  Run r;
  rusage before{}, after{};
  getrusage(RUSAGE_CHILDREN, &before);
  const auto t0 = Clock::now();
  std::fflush(nullptr);  // else the child's stdio would write the parent's buffers again
  const pid_t pid = fork();
  if (pid == 0) {
    std::vector<char*> argv;
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    if (std::freopen(log.c_str(), "w", stderr) == nullptr) _exit(126);
    if (std::freopen(log.c_str(), "a", stdout) == nullptr) _exit(126);
    execvp(argv[0], argv.data());
    _exit(127);
  }
  int st = 0;
  waitpid(pid, &st, 0);
  r.wall_s = std::chrono::duration<double>(Clock::now() - t0).count();
  getrusage(RUSAGE_CHILDREN, &after);
  auto secs = [](const timeval& t) { return static_cast<double>(t.tv_sec) + 1e-6 * t.tv_usec; };
  r.cpu_s =
      secs(after.ru_utime) - secs(before.ru_utime) + secs(after.ru_stime) - secs(before.ru_stime);
  r.code = WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
  return r;
}

double bestAtCost(const json& front, double level) {
  double best = INFINITY;
  for (const auto& m : front["members"])
    if (m["cost"].get<double>() <= level && m["error"].is_number())
      best = std::min(best, m["error"].get<double>());
  return best;
}

double median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

std::string fmt(double v, const char* f = "%.4g") {
  if (!std::isfinite(v)) return "-";
  char b[64];
  std::snprintf(b, sizeof(b), f, v);
  return b;
}

// The config with its data path made absolute (it is copied elsewhere) and a migration mode.
fs::path writeConfig(const Options& o, const std::string& migration, const fs::path& dir) {
  std::ifstream in(o.config);
  json j = json::parse(in);
  const fs::path base = fs::absolute(o.config).parent_path();
  for (const char* k : {"path", "scene"})
    if (j["data"].contains(k) && fs::path(j["data"][k].get<std::string>()).is_relative())
      j["data"][k] = fs::weakly_canonical(base / j["data"][k].get<std::string>()).string();
  j["mpi"] = {{"migration", migration}};
  j["search"]["generations"] = 0;
  j["search"]["max_evaluations"] = 0;
  j["search"]["wall_time_s"] = o.budget;
  j["output"]["front_csv"] = "";
  const fs::path p = dir / ("config_" + migration + ".json");
  std::ofstream(p) << j.dump(1);
  return p;
}

std::vector<double> costLevels(const Options& o) {
  // The quality report's levels for this table, when it lists the config; else a spread.
  const fs::path q = fs::absolute(o.config).parent_path().parent_path() / "quality.json";
  std::ifstream in(q);
  if (in) {
    const json j = json::parse(in);
    for (const auto& t : j["tables"])
      if (fs::path(t["config"].get<std::string>()).filename() == fs::path(o.config).filename())
        return t["cost_levels"].get<std::vector<double>>();
  }
  return {8, 15, 28, 44, 74};
}

int drive(const Options& o) {
  fs::create_directories(o.out);
  const fs::path work = fs::path(o.out) / "runs";
  fs::create_directories(work);
  const int threads = std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  const std::string cpu = lgp::bench::cpuModel();
  std::printf("lgp_mpi_bench: %s, %d hardware threads, %s, budget %.0f s, %d seeds\n", cpu.c_str(),
              threads, lgp::bench::utcNow().c_str(), o.budget, o.seeds);
  const auto levels = costLevels(o);
  const fs::path async_cfg = writeConfig(o, "async", work);
  const fs::path sync_cfg = writeConfig(o, "sync", work);
  const std::string np = std::to_string(o.ranks);
  const std::string one = "1 rank x " + std::to_string(o.ranks) + " threads";
  const std::string many_a = np + " ranks x 1 thread, async";
  const std::string many_s = np + " ranks x 1 thread, sync";
  // mpirun binds each rank to a core by default, which is what ranks x 1 thread should get.
  auto mpiArgs = [&](const fs::path& cfg, const fs::path& front, int seed) {
    return std::vector<std::string>{o.mpirun,     "--oversubscribe",
                                    "-np",        np,
                                    o.lgp,        "run",
                                    cfg.string(), "-q",
                                    "--threads",  "1",
                                    "--seed",     std::to_string(seed),
                                    "-o",         front.string()};
  };
  std::vector<Run> runs;
  for (int seed = 1; seed <= o.seeds; ++seed) {
    struct Plan {
      std::string mode;
      std::vector<std::string> args;
    };
    const fs::path fa = work / ("one_" + std::to_string(seed) + ".json");
    const fs::path fb = work / ("async_" + std::to_string(seed) + ".json");
    const fs::path fc = work / ("sync_" + std::to_string(seed) + ".json");
    std::vector<Plan> plans = {{one,
                                {o.lgp, "run", async_cfg.string(), "-q", "--threads", np, "--seed",
                                 std::to_string(seed), "-o", fa.string()}},
                               {many_a, mpiArgs(async_cfg, fb, seed)},
                               {many_s, mpiArgs(sync_cfg, fc, seed)}};
    // Interleaved, and the order rotates with the seed so no mode always runs first.
    std::rotate(plans.begin(), plans.begin() + (seed - 1) % 3, plans.end());
    for (auto& p : plans) {
      const fs::path front = p.args.back();
      std::fprintf(stderr, "  seed %d: %s ...", seed, p.mode.c_str());
      Run r = launch(p.args, front.string() + ".log");
      r.mode = p.mode;
      r.seed = seed;
      if (r.code == 0) {
        std::ifstream in(front);
        r.front = json::parse(in);
      }
      std::fprintf(stderr, " rc %d, %.1f s wall, %.1f s CPU\n", r.code, r.wall_s, r.cpu_s);
      runs.push_back(std::move(r));
    }
  }

  // Ping-pong over the same launcher.
  const fs::path pp = work / "pingpong.json";
  const Run ping =
      launch({o.mpirun, "--oversubscribe", "-np", "2", o.self, "--pingpong", pp.string()},
             work / "pingpong.log");
  json net = json::object();
  if (ping.code == 0) {
    std::ifstream in(pp);
    net = json::parse(in);
  }

  // Per mode: medians over seeds.
  json results = {
      {"cpu", cpu},           {"hardware_threads", threads}, {"date", lgp::bench::utcNow()},
      {"config", o.config},   {"budget_s", o.budget},        {"seeds", o.seeds},
      {"ranks", o.ranks},     {"cost_levels", levels},       {"network", net},
      {"runs", json::array()}};
  std::map<std::string, std::vector<const Run*>> by_mode;
  for (const auto& r : runs) {
    json jr = {{"mode", r.mode},
               {"seed", r.seed},
               {"code", r.code},
               {"wall_s", r.wall_s},
               {"cpu_s", r.cpu_s}};
    if (r.code == 0) {
      const auto& p = r.front["progress"];
      jr["evaluations"] = p["evaluations"];
      jr["generation"] = p["generation"];
      jr["migrants"] = p["migrants"];
      jr["remote_migrants"] = p.value("remote_migrants", 0);
      if (p.contains("mpi")) jr["mpi"] = p["mpi"];
      json best = json::array();
      for (double c : levels) {
        const double b = bestAtCost(r.front, c);
        best.push_back(std::isfinite(b) ? json(b) : json(nullptr));
      }
      jr["best_at_cost"] = best;
      by_mode[r.mode].push_back(&r);
    }
    results["runs"].push_back(jr);
  }

  std::ostringstream md;
  md << "# MPI: " << one << " against " << np << " ranks x 1 thread\n\n"
     << "- Machine: " << cpu << ", " << threads << " hardware threads; " << results["date"]
     << ".\n- Table and search: `" << o.config << "`, wall-time budget " << o.budget
     << " s per run (no generation or evaluation budget), seeds 1.." << o.seeds
     << ", modes interleaved per seed (the order rotates with the seed).\n"
     << "- Command: `lgp_mpi_bench --config " << o.config << " --budget " << o.budget << " --seeds "
     << o.seeds << " --ranks " << o.ranks << " --out " << o.out << "`\n\n"
     << "## Front quality and throughput (medians over seeds)\n\n"
     << "Best error (the search objective) among members at or below each cost.\n\n| mode |";
  for (double c : levels) md << " cost <= " << c << " |";
  md << " evaluations | evals/s (wall) | CPU / wall | generations | remote migrants | time in MPI "
        "calls |\n|---|";
  for (size_t i = 0; i < levels.size(); ++i) md << "---|";
  md << "---|---|---|---|---|---|\n";
  std::map<std::string, std::vector<double>> best_median;
  std::map<std::string, double> evals_median, gen_time_median, comm_median, bytes_per_msg;
  for (const std::string& mode : {one, many_a, many_s}) {
    const auto& rs = by_mode[mode];
    if (rs.empty()) {
      md << "| " << mode << " | failed (see runs/*.log) |\n";
      continue;
    }
    md << "| " << mode << " |";
    for (size_t i = 0; i < levels.size(); ++i) {
      std::vector<double> v;
      for (const Run* r : rs) v.push_back(bestAtCost(r->front, levels[i]));
      best_median[mode].push_back(median(v));
      md << " " << fmt(median(v)) << " |";
    }
    std::vector<double> ev, eps, cpu_ratio, gens, remote, comm, gen_time, bpm;
    for (const Run* r : rs) {
      const auto& p = r->front["progress"];
      const double e = p["evaluations"].get<double>();
      ev.push_back(e);
      eps.push_back(e / r->wall_s);
      cpu_ratio.push_back(r->cpu_s / r->wall_s);
      gens.push_back(p["generation"].get<double>());
      remote.push_back(p.value("remote_migrants", 0.0));
      gen_time.push_back(p["elapsed_s"].get<double>() / std::max(1.0, gens.back()));
      if (p.contains("mpi")) {
        comm.push_back(p["mpi"]["comm_share"].get<double>());
        double msgs = 0, bytes = 0;
        for (const auto& s : p["mpi"]["ranks"]) {
          msgs += s["migrant_batches"].get<double>();
          bytes += s["migrant_bytes"].get<double>();
        }
        if (msgs > 0) bpm.push_back(bytes / msgs);
      }
    }
    evals_median[mode] = median(ev);
    gen_time_median[mode] = median(gen_time);
    comm_median[mode] = comm.empty() ? 0 : median(comm);
    bytes_per_msg[mode] = bpm.empty() ? 0 : median(bpm);
    md << " " << fmt(median(ev), "%.3g") << " | " << fmt(median(eps), "%.3g") << " | "
       << fmt(median(cpu_ratio), "%.2f") << " | " << fmt(median(gens), "%.0f") << " | "
       << fmt(median(remote), "%.0f") << " | "
       << (comm.empty() ? "-" : fmt(100 * median(comm), "%.2f %%")) << " |\n";
  }
  md << "\nRatios against " << one << " (error: < 1 is better; evaluations: > 1 is more):\n\n"
     << "| mode |";
  for (double c : levels) md << " cost <= " << c << " |";
  md << " evaluations |\n|---|";
  for (size_t i = 0; i < levels.size(); ++i) md << "---|";
  md << "---|\n";
  for (const std::string& mode : {many_a, many_s}) {
    if (best_median[mode].empty() || best_median[one].empty()) continue;
    md << "| " << mode << " |";
    for (size_t i = 0; i < levels.size(); ++i)
      md << " " << fmt(best_median[mode][i] / best_median[one][i], "%.2f") << " |";
    md << " " << fmt(evals_median[mode] / evals_median[one], "%.2f") << " |\n";
  }

  // The model: per generation a rank computes its share of the population and, every
  // migration interval, sends one batch and receives one (the ring over consecutive ranges
  // has one edge into and one out of each rank, whatever N). Rank 0 also takes one report per
  // rank per report period. Sync adds an allreduce per generation. Strong scaling: the total
  // population stays; weak: it grows with N.
  md << "\n## Expected communication share at 8 to 64 ranks (model)\n\n";
  if (net.contains("sizes") && gen_time_median.count(many_a) && comm_median.count(many_a)) {
    double lat = 0, bw = 0;
    for (const auto& s : net["sizes"]) {
      if (s["bytes"] == 8) lat = s["one_way_s"].get<double>();
      if (s["bytes"] == 1048576) bw = 1048576.0 / s["one_way_s"].get<double>();
    }
    const double allreduce2 = net.value("allreduce_8b_s", lat);
    const double report_bytes = net.value("report_bytes", 8192.0);
    const double decode = net.value("report_decode_s", 0.0);
    std::ifstream cin_(async_cfg);
    const json cfg = json::parse(cin_);
    const double interval =
        cfg["search"].value("islands", json::object()).value("migration_interval", 10);
    const double batch = bytes_per_msg[many_a] > 0 ? bytes_per_msg[many_a] : 4096;
    // Measured at N = o.ranks (async): a generation's compute per rank, and the time per
    // generation inside MPI calls (polls, packing and unpacking, sends), which does not grow
    // with N: each rank keeps one ring neighbour on either side.
    const double t_gen = gen_time_median[many_a] * (1 - comm_median[many_a]);
    const double c_gen = gen_time_median[many_a] * comm_median[many_a];
    const double report_period = 1.0;
    md << "Inputs, measured here: one-way latency " << fmt(lat * 1e6, "%.2f") << " us, bandwidth "
       << fmt(bw / 1e9, "%.2f") << " GB/s (1 MiB messages), 8-byte allreduce on 2 ranks "
       << fmt(allreduce2 * 1e6, "%.2f") << " us, decoding a full report (" << report_bytes
       << " bytes) " << fmt(decode * 1e6, "%.1f") << " us; at " << o.ranks
       << " ranks (async) a generation takes " << fmt(t_gen * 1e3, "%.3f") << " ms of compute and "
       << fmt(c_gen * 1e3, "%.4f") << " ms inside MPI calls per rank; a migrant batch is "
       << fmt(batch, "%.0f") << " bytes; migration every " << interval
       << " generations, reports every " << report_period << " s.\n\n"
       << "Per generation a rank spends `c + 2 (L + S/B) / m` (c: the measured time in MPI "
          "calls per generation, L latency, S batch size, B bandwidth, m migration interval); "
          "rank 0 adds `(N - "
       << o.ranks
       << ") (L + R/B + d) t / P` for the reports of the "
          "extra ranks (R report size, d its decoding, t the generation time, P the report "
          "period); sync mode adds `2 log2(N) L` for the allreduce. Strong scaling keeps the "
          "population, so compute per rank falls as 1/N (until islands reach 4 individuals); "
          "weak scaling keeps it. Networks: this machine's shared memory, an InfiniBand-class "
          "fabric (L = 2 us, B = 10 GB/s) and 10 GbE (L = 30 us, B = 1 GB/s). Sync mode also "
          "waits for the slowest neighbour every generation; that imbalance is not modelled "
          "(the sync row above measures it at N = "
       << o.ranks << ").\n\n"
       << "| N | scaling | compute / gen | async, rank != 0 (IB) | async, rank 0 (IB) | sync, "
          "rank 0 (IB) | async, rank 0 (10 GbE) | async, rank 0 (this machine) |\n"
          "|---|---|---|---|---|---|---|---|\n";
    for (int n : {8, 16, 32, 64}) {
      for (const bool strong : {true, false}) {
        const double compute = strong ? t_gen * o.ranks / n : t_gen;
        auto share = [&](double l, double b, bool rank0, bool sync) {
          double over = c_gen + 2 * (l + batch / b) / interval;
          if (sync) over += 2 * std::log2(static_cast<double>(n)) * l;
          if (rank0)
            over +=
                (n - o.ranks) * (l + report_bytes / b + decode) * (compute + over) / report_period;
          return over / (compute + over);
        };
        md << "| " << n << " | " << (strong ? "strong" : "weak") << " | "
           << fmt(compute * 1e3, "%.3f") << " ms | "
           << fmt(100 * share(2e-6, 1e10, false, false), "%.3f %%") << " | "
           << fmt(100 * share(2e-6, 1e10, true, false), "%.3f %%") << " | "
           << fmt(100 * share(2e-6, 1e10, true, true), "%.3f %%") << " | "
           << fmt(100 * share(30e-6, 1e9, true, false), "%.3f %%") << " | "
           << fmt(100 * share(lat, bw, true, false), "%.3f %%") << " |\n";
      }
    }
    md << "\nWhat limits scaling is therefore not the network but the work per rank: with the "
          "population fixed, 64 ranks leave each rank a few islands of a few individuals, and "
          "generations become short enough for per-message costs and (in sync mode) "
          "neighbour waits to matter. Grow `search.population` (and islands) with the ranks "
          "for a cluster run.\n";
  } else {
    md << "Not computed: the ping-pong or the async runs failed (see runs/*.log).\n";
  }
  std::ofstream(fs::path(o.out) / "report.md") << md.str();
  std::ofstream(fs::path(o.out) / "results.json") << results.dump(1) << "\n";
  std::printf("%s", md.str().c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  o.self = fs::canonical("/proc/self/exe").string();
  // Next to this binary in the build tree: build/.../bench/mpi -> build/.../frontends/lgp.
  o.lgp =
      (fs::path(o.self).parent_path().parent_path().parent_path() / "frontends" / "lgp").string();
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--pingpong") return pingpong(lgp::bench::optionValue(argc, argv, i));
    if (a == "--config")
      o.config = lgp::bench::optionValue(argc, argv, i);
    else if (a == "--budget")
      o.budget = std::atof(lgp::bench::optionValue(argc, argv, i));
    else if (a == "--seeds")
      o.seeds = std::atoi(lgp::bench::optionValue(argc, argv, i));
    else if (a == "--ranks")
      o.ranks = std::atoi(lgp::bench::optionValue(argc, argv, i));
    else if (a == "--out")
      o.out = lgp::bench::optionValue(argc, argv, i);
    else if (a == "--lgp")
      o.lgp = lgp::bench::optionValue(argc, argv, i);
    else if (a == "--mpirun")
      o.mpirun = lgp::bench::optionValue(argc, argv, i);
    else {
      std::fprintf(stderr,
                   "usage: lgp_mpi_bench [--config F] [--budget S] [--seeds N] [--ranks R] "
                   "[--out DIR] [--lgp PATH] [--mpirun PATH]\n");
      return 2;
    }
  }
  if (o.budget <= 0 || o.seeds < 1 || o.ranks < 2) {
    std::fprintf(stderr, "--budget must be > 0, --seeds >= 1, --ranks >= 2\n");
    return 2;
  }
  if (geteuid() == 0) {
    setenv("OMPI_ALLOW_RUN_AS_ROOT", "1", 1);
    setenv("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1", 1);
  }
  return drive(o);
}
