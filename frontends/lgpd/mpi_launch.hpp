// Launching `lgp run` under an MPI launcher for runs whose config sets mpi.np > 0.
//
// lgpd never runs a shell. The launcher (mpirun) gets an argument vector built from the
// daemon config and one validated integer from the request (np); everything else a request
// says goes into a config file that lgpd writes into the run's work directory
// (<data-dir>/mpi/<run-id>/). The child reports back through files there: a status file at
// every progress tick, a checkpoint every checkpoint interval and the final front, each
// written atomically (write, then rename) by rank 0.
#pragma once

#include <sys/types.h>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "daemon_config.hpp"
#include "lgp/core/status.hpp"

namespace lgpd {

// The programs behind MPI runs, resolved once when lgpd starts. A daemon without a usable
// launcher or lgp binary still serves in-process runs; MPI submissions get a 400 that says
// why (`unavailable`).
struct MpiTools {
  std::filesystem::path launcher;  // absolute
  std::filesystem::path lgp;       // absolute
  std::filesystem::path hostfile;  // absolute, or empty
  std::string unavailable;         // empty = MPI runs can be launched
  bool usable() const { return unavailable.empty(); }
};
MpiTools resolveMpiTools(const MpiDaemonConfig& cfg);

// A name without '/' is looked up in PATH; a path is made absolute. Either way it must be an
// executable regular file.
lgp::Expected<std::filesystem::path> findExecutable(const std::string& name);

// The files of one MPI run.
struct MpiWorkDir {
  std::filesystem::path dir;
  std::filesystem::path config() const { return dir / "run.json"; }
  std::filesystem::path front() const { return dir / "front.json"; }
  std::filesystem::path checkpoint() const { return dir / "checkpoint.json"; }
  std::filesystem::path status() const { return dir / "status.json"; }
  std::filesystem::path log() const { return dir / "launcher.log"; }
  std::filesystem::path pidFile() const { return dir / "launcher.pid"; }
};

// [launcher, -np, N, (--hostfile, F), args..., lgp, run, CFG, -q, -o, FRONT, --csv, "",
//  --checkpoint, CKPT, --checkpoint-interval, S, --status, STATUS, (--resume)]
std::vector<std::string> mpiArgv(const MpiTools& tools, const MpiDaemonConfig& cfg, int np,
                                 const MpiWorkDir& work, double checkpoint_interval_s, bool resume);

// A child process in its own process group, started with fork + execve (no shell). Its
// stdin is /dev/null, stdout and stderr append to `log`, it inherits no other descriptor,
// and it gets SIGTERM when the thread that spawned it exits (PR_SET_PDEATHSIG), so a
// kill -9 of lgpd takes the launch down with it. That thread must therefore own the child
// until it is reaped.
class ChildProcess {
 public:
  ChildProcess() = default;
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;
  ChildProcess(ChildProcess&& o) noexcept : pid_(o.pid_), pgid_(o.pgid_) { o.pid_ = o.pgid_ = -1; }
  // Kills and reaps a child still running (only on error paths; normal ends are reaped).
  ~ChildProcess();

  // env: extra "KEY=VALUE" entries over lgpd's own environment.
  static lgp::Expected<ChildProcess> spawn(const std::vector<std::string>& argv,
                                           const std::vector<std::string>& env,
                                           const std::filesystem::path& log);

  pid_t pid() const { return pid_; }
  // The wait status once the child has ended (it is then reaped), nullopt while it runs.
  std::optional<int> poll();
  void signal(int sig) const;  // the launcher, while it runs
  // Its whole process group; also after the launcher was reaped (what it left behind: the
  // kernel keeps the group's id reserved while any member lives).
  void signalGroup(int sig) const;

 private:
  pid_t pid_ = -1;
  pid_t pgid_ = -1;
};

// "exited with status 3", "was killed by signal 9 (SIGKILL)".
std::string describeWaitStatus(int wait_status);
// The last `max_lines` lines of a text file, at most `max_bytes` of them; "" if unreadable.
std::string fileTail(const std::filesystem::path& p, size_t max_lines, size_t max_bytes);
// Reads and parses a JSON file that its writer replaces atomically, with lgp::parseJson's
// limits and at most kMaxChildJsonBytes; nullopt if it is missing, not a regular file or
// does not parse (logged).
inline constexpr size_t kMaxChildJsonBytes = size_t{1} << 28;
std::optional<nlohmann::json> readJsonFile(const std::filesystem::path& p);

// Identifies one version of a file that is replaced by rename: a change of inode, size or
// mtime means a new version.
struct FileVersion {
  uint64_t ino = 0, size = 0;
  int64_t mtime_ns = 0;
  bool exists = false;
  bool operator==(const FileVersion&) const = default;
  static FileVersion of(const std::filesystem::path& p);
};

}  // namespace lgpd
