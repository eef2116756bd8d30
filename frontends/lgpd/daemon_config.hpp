// lgpd's own configuration (not a run config): where it listens, how many jobs run at once,
// how often they checkpoint, and the safety limits of the HTTP API. Read from an optional
// JSON file (--config) and overridden by command-line flags; see README.md for an example.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lgp/core/status.hpp"

namespace lgpd {

// How lgpd launches runs whose config asks for MPI (run config "mpi": {"np": N}). Set by the
// daemon operator only: a request contributes nothing to the command line but np.
struct MpiDaemonConfig {
  std::string launcher = "mpirun";  // a name looked up in PATH at startup, or a path
  std::filesystem::path hostfile;   // passed as --hostfile; empty = none
  std::vector<std::string> args;    // extra launcher arguments, e.g. {"--oversubscribe"}
  int max_np = 64;                  // largest mpi.np a submission may ask for
  std::filesystem::path lgp;        // the lgp binary; empty = next to lgpd, ../lgp/lgp, PATH
  double stop_grace_s = 30;         // cancel/shutdown: SIGUSR1, then SIGTERM after this long
};

struct DaemonConfig {
  std::filesystem::path data_dir;         // SQLite database and materialised inline tables
  std::string listen = "127.0.0.1:8737";  // host:port; port 0 picks a free port
  int max_jobs = 1;                       // jobs running at once (each uses its config's threads)
  double checkpoint_interval_s = 60;      // seconds between checkpoints of a running job (> 0)
  double progress_interval_s = 1;         // seconds between progress rows (>= 0; 0 = every gen)
  double front_interval_s = 10;           // seconds between live front snapshots (>= 0)
  std::string token;                      // bearer token (>= 16 non-space characters);
                                          // required for a non-loopback listen
  size_t max_body_bytes = 16u << 20;      // request bodies above this get 413
  std::filesystem::path data_base_dir;    // relative data paths of submissions resolve here;
                                          // empty = lgpd's working directory at start
  std::vector<std::filesystem::path> allowed_data_dirs;  // if set, data files must be inside
  int http_threads = 8;        // threads that run the routes (connections hold none)
  int max_connections = 1024;  // open connections in all
  // Connections one client address (an IPv6 /64) may hold at once; 0 = max_connections / 2.
  int max_connections_per_client = 0;
  double read_timeout_s = 5;          // longest pause inside a request
  double request_timeout_s = 60;      // a whole request (line, headers, body) must arrive
  double write_timeout_s = 60;        // a whole response must leave
  double keep_alive_timeout_s = 5;    // an idle kept-alive connection is closed
  int keep_alive_max_requests = 100;  // requests per connection
  // Host header names accepted besides 127.0.0.1, localhost, [::1] and the listen address
  // (lower case, no port; IPv6 in brackets; "*" accepts any). Refusing the rest stops DNS
  // rebinding: a page served from evil.example that resolves to 127.0.0.1 sends
  // "Host: evil.example".
  std::vector<std::string> allowed_hosts;
  // Origins ("http://name:port") whose POST and DELETE requests are accepted besides the
  // daemon's own (an Origin naming the same host and port as the Host header).
  std::vector<std::string> allowed_origins;
  // Runs waiting in the queue at most; past it POST /api/v1/runs answers 429 with
  // Retry-After (kQueueRetryAfterS).
  int max_queued_runs = 64;
  // The memory a run's search may need (an estimate from population, program shape, islands
  // and the semantic cache, estimateSearchBytes), in MiB; a submission above it gets a 400
  // naming the field that weighs most.
  // 0 = half the machine's physical memory.
  int64_t max_run_memory_mb = 0;
  MpiDaemonConfig mpi;

  // max_run_memory_mb in bytes, with the default filled in.
  uint64_t runMemoryBytes() const;
  // max_connections_per_client with the default filled in.
  int connectionsPerClient() const;

  // Checks every field; the message names the JSON key.
  lgp::Status validate() const;
};

// Seconds a 429 for a full queue asks the client to wait.
inline constexpr int kQueueRetryAfterS = 30;

// "host:port" split; port must be 0..65535. IPv6 hosts are written in brackets: "[::1]:8737".
struct ListenAddress {
  std::string host;
  int port = 0;
};
lgp::Expected<ListenAddress> parseListen(const std::string& s);
// True for 127.0.0.0/8, ::1 and "localhost".
bool isLoopbackHost(const std::string& host);

// A Host header value split into a lower-case host (IPv6 in brackets) and its port (-1 when
// none); nullopt when it is not host[:port].
struct HostPort {
  std::string host;
  int port = -1;
};
std::optional<HostPort> parseHostHeader(const std::string& value);
// "http://name[:port]" or "https://..." (no path) split into scheme and authority; nullopt
// otherwise (including "null").
struct Origin {
  std::string scheme;
  HostPort authority;
};
std::optional<Origin> parseOrigin(const std::string& value);

// A bearer token must have at least this many characters other than spaces.
inline constexpr size_t kMinTokenCharacters = 16;
// Empty (no token) or a valid token; the message says what is wrong.
lgp::Status checkToken(const std::string& token);

// Applies the keys present in `j` over `cfg`; unknown keys and wrong types are errors that
// name the key, e.g. "/max_jobs: must be an integer >= 1".
lgp::Status applyDaemonConfigJson(const nlohmann::json& j, DaemonConfig& cfg);

// Makes the relative paths a config file set (data_dir, data_base_dir, allowed_data_dirs,
// mpi.hostfile, and mpi.launcher or mpi.lgp where they contain a '/') relative to the file's
// directory `dir`, as a run config's paths are. Bare names stay PATH lookups; paths from the
// command line stay relative to the working directory.
void resolveConfigFilePaths(DaemonConfig& cfg, const std::filesystem::path& dir);

}  // namespace lgpd
