#include "mpi_launch.hpp"

#include <spdlog/spdlog.h>

#include <fcntl.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>

#include "files.hpp"

extern char** environ;

namespace lgpd {

using lgp::Expected;
using lgp::Status;
using nlohmann::json;
namespace fs = std::filesystem;

namespace {

bool isExecutableFile(const fs::path& p) {
  std::error_code ec;
  return fs::is_regular_file(p, ec) && ::access(p.c_str(), X_OK) == 0;
}

// The lgp binary that belongs to this lgpd: installed side by side (bin/lgpd, bin/lgp) or in
// the build tree (frontends/lgpd/lgpd next to frontends/lgp, or frontends/lgp/lgp).
std::optional<fs::path> siblingLgp() {
  std::error_code ec;
  std::string self = fs::read_symlink("/proc/self/exe", ec).string();
  if (ec || self.empty()) return std::nullopt;
  // A binary replaced while it runs (a rebuild) reads as "PATH (deleted)".
  constexpr std::string_view kDeleted = " (deleted)";
  if (self.size() > kDeleted.size() && self.ends_with(kDeleted))
    self.resize(self.size() - kDeleted.size());
  const fs::path dir = fs::path(self).parent_path();
  for (const fs::path& p : {dir / "lgp", dir / ".." / "lgp", dir / ".." / "lgp" / "lgp"})
    if (isExecutableFile(p)) return fs::weakly_canonical(p, ec);
  return std::nullopt;
}

std::string formatSeconds(double s) {
  char buf[32];
  auto [end, ec] = std::to_chars(buf, buf + sizeof buf, s);
  return ec == std::errc() ? std::string(buf, end) : std::to_string(s);
}

}  // namespace

Expected<fs::path> findExecutable(const std::string& name) {
  if (name.empty()) return Status::error("empty program name");
  if (name.find('/') != std::string::npos) {
    fs::path p = fs::absolute(name).lexically_normal();
    if (!isExecutableFile(p)) return Status::error(p.string() + " is not an executable file");
    return p;
  }
  const char* path = std::getenv("PATH");
  std::string_view rest = path ? path : "/usr/local/bin:/usr/bin:/bin";
  while (true) {
    auto colon = rest.find(':');
    std::string_view dir = rest.substr(0, colon);
    if (!dir.empty()) {
      fs::path p = fs::path(std::string(dir)) / name;
      if (isExecutableFile(p)) return fs::absolute(p).lexically_normal();
    }
    if (colon == std::string_view::npos) break;
    rest.remove_prefix(colon + 1);
  }
  return Status::error("'" + name + "' is not found in PATH");
}

MpiTools resolveMpiTools(const MpiDaemonConfig& cfg) {
  MpiTools t;
  auto launcher = findExecutable(cfg.launcher);
  if (!launcher) {
    t.unavailable = "/mpi/launcher: " + launcher.error();
    return t;
  }
  t.launcher = *launcher;
  if (!cfg.lgp.empty()) {
    auto lgp = findExecutable(cfg.lgp.string());
    if (!lgp) {
      t.unavailable = "/mpi/lgp: " + lgp.error();
      return t;
    }
    t.lgp = *lgp;
  } else if (auto sib = siblingLgp()) {
    t.lgp = *sib;
  } else if (auto lgp = findExecutable("lgp")) {
    t.lgp = *lgp;
  } else {
    t.unavailable = "/mpi/lgp: no lgp binary next to lgpd, in ../lgp/ or in PATH; set mpi.lgp";
    return t;
  }
  if (!cfg.hostfile.empty()) {
    std::error_code ec;
    t.hostfile = fs::absolute(cfg.hostfile).lexically_normal();
    if (!fs::is_regular_file(t.hostfile, ec) || ::access(t.hostfile.c_str(), R_OK) != 0) {
      t.unavailable = "/mpi/hostfile: cannot read " + t.hostfile.string();
      return t;
    }
  }
  return t;
}

std::vector<std::string> mpiArgv(const MpiTools& tools, const MpiDaemonConfig& cfg, int np,
                                 const MpiWorkDir& work, double checkpoint_interval_s,
                                 bool resume) {
  std::vector<std::string> a = {tools.launcher.string(), "-np", std::to_string(np)};
  if (!tools.hostfile.empty()) a.insert(a.end(), {"--hostfile", tools.hostfile.string()});
  a.insert(a.end(), cfg.args.begin(), cfg.args.end());
  a.insert(a.end(),
           {tools.lgp.string(), "run", work.config().string(), "-q", "-o", work.front().string(),
            "--csv", "", "--checkpoint", work.checkpoint().string(), "--checkpoint-interval",
            formatSeconds(checkpoint_interval_s), "--status", work.status().string()});
  if (resume) a.push_back("--resume");
  return a;
}

ChildProcess::~ChildProcess() {
  if (pid_ <= 0) return;
  ::kill(-pid_, SIGKILL);
  ::kill(pid_, SIGKILL);
  int st = 0;
  ::waitpid(pid_, &st, 0);
}

Expected<ChildProcess> ChildProcess::spawn(const std::vector<std::string>& argv,
                                           const std::vector<std::string>& env,
                                           const fs::path& log) {
  if (argv.empty()) return Status::error("spawn: empty argv");
  // Everything the child touches is built before fork: between fork and execve it may only
  // make async-signal-safe calls (lgpd has many threads; one may hold the malloc lock).
  std::vector<std::string> env_strings;
  for (char** e = environ; e && *e; ++e) {
    std::string_view kv(*e);
    bool overridden = false;
    for (const auto& x : env) {
      auto eq = x.find('=');
      overridden = overridden || kv.substr(0, kv.find('=')) == std::string_view(x).substr(0, eq);
    }
    if (!overridden) env_strings.emplace_back(kv);
  }
  env_strings.insert(env_strings.end(), env.begin(), env.end());
  std::vector<char*> argv_c, envp_c;
  for (const auto& a : argv) argv_c.push_back(const_cast<char*>(a.c_str()));
  argv_c.push_back(nullptr);
  for (auto& e : env_strings) envp_c.push_back(e.data());
  envp_c.push_back(nullptr);
  const std::string exec_failed = "lgpd: cannot execute " + argv[0] + "\n";

  int devnull = ::open("/dev/null", O_RDONLY | O_CLOEXEC);
  int logfd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (devnull < 0 || logfd < 0) {
    const int err = errno;
    if (devnull >= 0) ::close(devnull);
    if (logfd >= 0) ::close(logfd);
    return Status::error("cannot open " + (logfd < 0 ? log.string() : "/dev/null") + ": " +
                         std::strerror(err));
  }
  const pid_t parent = ::getpid();
  const long max_fd = ::sysconf(_SC_OPEN_MAX);
  sigset_t none;
  sigemptyset(&none);

  const pid_t pid = ::fork();
  if (pid == 0) {
    ::setpgid(0, 0);  // signals to the group reach the launcher and what it forks locally
    ::prctl(PR_SET_PDEATHSIG, SIGTERM);
    if (::getppid() != parent) ::_exit(126);  // lgpd died before prctl took effect
    ::dup2(devnull, 0);
    ::dup2(logfd, 1);
    ::dup2(logfd, 2);
    // No SQLite handle or listening socket may leak into the search.
    if (::close_range(3, ~0U, 0) != 0)
      for (long fd = 3; fd < max_fd; ++fd) ::close(static_cast<int>(fd));
    // lgpd blocks SIGINT/SIGTERM in every thread (its sigwait thread takes them) and
    // ignores SIGPIPE; masks and ignored signals survive execve, so reset both.
    struct sigaction dfl {};
    dfl.sa_handler = SIG_DFL;
    for (int s : {SIGPIPE, SIGINT, SIGTERM, SIGUSR1, SIGHUP, SIGCHLD})
      ::sigaction(s, &dfl, nullptr);
    ::sigprocmask(SIG_SETMASK, &none, nullptr);
    ::execve(argv_c[0], argv_c.data(), envp_c.data());
    ssize_t ignored = ::write(2, exec_failed.data(), exec_failed.size());
    (void)ignored;
    ::_exit(127);
  }
  const int fork_errno = errno;
  ::close(devnull);
  ::close(logfd);
  if (pid < 0) return Status::error(std::string("fork: ") + std::strerror(fork_errno));
  ::setpgid(pid, pid);  // also here, so the group exists before any signal we send; an
                        // EACCES after the child's execve is harmless
  ChildProcess c;
  c.pid_ = c.pgid_ = pid;
  return c;
}

std::optional<int> ChildProcess::poll() {
  if (pid_ <= 0) return std::nullopt;
  int st = 0;
  pid_t r = ::waitpid(pid_, &st, WNOHANG);
  if (r == 0) return std::nullopt;
  if (r < 0 && errno == EINTR) return std::nullopt;
  pid_ = -1;
  if (r < 0) return 255 << 8;  // ECHILD: someone else reaped it; report a failure
  return st;
}

void ChildProcess::signal(int sig) const {
  if (pid_ > 0) ::kill(pid_, sig);
}

void ChildProcess::signalGroup(int sig) const {
  if (pgid_ > 0) ::kill(-pgid_, sig);
}

std::string describeWaitStatus(int st) {
  if (WIFEXITED(st)) return "exited with status " + std::to_string(WEXITSTATUS(st));
  if (WIFSIGNALED(st)) {
    const int sig = WTERMSIG(st);
    const char* abbrev = ::sigabbrev_np(sig);
    return "was killed by signal " + std::to_string(sig) +
           (abbrev ? std::string(" (SIG") + abbrev + ")" : std::string());
  }
  return "ended with wait status " + std::to_string(st);
}

std::string fileTail(const fs::path& p, size_t max_lines, size_t max_bytes) {
  std::ifstream f(p, std::ios::binary);
  if (!f) return "";
  f.seekg(0, std::ios::end);
  const auto size = static_cast<size_t>(std::max<std::streamoff>(0, f.tellg()));
  const size_t from = size > max_bytes ? size - max_bytes : 0;
  f.seekg(static_cast<std::streamoff>(from));
  std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  if (from > 0) {
    auto nl = text.find('\n');  // drop the partial first line
    text.erase(0, nl == std::string::npos ? 0 : nl + 1);
  }
  std::vector<std::string_view> lines;
  std::string_view rest(text);
  while (!rest.empty()) {
    auto nl = rest.find('\n');
    lines.push_back(rest.substr(0, nl));
    if (nl == std::string_view::npos) break;
    rest.remove_prefix(nl + 1);
  }
  while (!lines.empty() && lines.back().find_first_not_of(" \t\r") == std::string_view::npos)
    lines.pop_back();
  std::string out;
  for (size_t i = lines.size() > max_lines ? lines.size() - max_lines : 0; i < lines.size(); ++i) {
    if (!out.empty()) out += '\n';
    out += lines[i];
  }
  return out;
}

std::optional<json> readJsonFile(const fs::path& p) {
  std::error_code ec;
  if (!fs::exists(p, ec)) return std::nullopt;
  // The child writes these files, but they are read with the limits of a request body all
  // the same (depth, size, numbers, duplicate keys), and never from a FIFO.
  auto j = readJsonDocument(p, kMaxChildJsonBytes);
  if (!j) {
    spdlog::warn("{}", j.error());
    return std::nullopt;
  }
  return std::move(*j);
}

FileVersion FileVersion::of(const fs::path& p) {
  struct stat st {};
  FileVersion v;
  if (::stat(p.c_str(), &st) != 0) return v;
  v.exists = true;
  v.ino = st.st_ino;
  v.size = static_cast<uint64_t>(st.st_size);
  v.mtime_ns = static_cast<int64_t>(st.st_mtim.tv_sec) * 1000000000 + st.st_mtim.tv_nsec;
  return v;
}

}  // namespace lgpd
