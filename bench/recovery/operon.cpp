#include "operon.hpp"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <sstream>

namespace recovery {

namespace {

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> t;
  std::istringstream ss(line);
  for (std::string w; ss >> w;) t.push_back(w);
  return t;
}

bool number(const std::string& s, double& v) {
  char* end = nullptr;
  v = std::strtod(s.c_str(), &end);
  return end != s.c_str() && *end == '\0';
}

std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : ",") + x;
  return s;
}

}  // namespace

std::vector<std::string> operonArgs(const OperonJob& j) {
  return {j.exe,
          "--dataset",
          j.csv,
          "--target",
          j.target,
          "--inputs",
          join(j.inputs),
          "--train",
          "0:" + std::to_string(j.train_rows),
          "--test",
          std::to_string(j.train_rows) + ":" + std::to_string(j.train_rows + j.test_rows),
          "--population-size",
          "1000",
          "--pool-size",
          "1000",
          "--generations",
          "100000",
          "--evaluations",
          "1000000000",
          "--iterations",
          "5",
          "--timelimit",
          std::to_string(j.budget_s),
          "--threads",
          std::to_string(j.threads),
          "--seed",
          std::to_string(j.seed),
          "--enable-symbols",
          join(j.symbols)};
}

OperonResult runOperon(const OperonJob& job) {
  OperonResult r;
  if (access(job.exe.c_str(), X_OK) != 0) {
    r.error = "cannot execute " + job.exe;
    return r;
  }
  const auto args = operonArgs(job);
  // Through `stdbuf -oL` where it exists: on a pipe Operon's rows are block-buffered, and a
  // run could not be stopped at recovery until the buffer fills. The times are Operon's own
  // `elapsed` either way.
  const std::vector<std::string> pre = {"stdbuf", "-oL"};
  std::vector<char*> argv;
  for (const auto& a : pre) argv.push_back(const_cast<char*>(a.c_str()));
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);

  int fd[2];
  if (pipe2(fd, O_CLOEXEC) != 0) {  // only the child's dup2 copies survive exec
    r.error = std::string("pipe: ") + std::strerror(errno);
    return r;
  }
  const pid_t pid = fork();
  if (pid < 0) {
    r.error = std::string("fork: ") + std::strerror(errno);
    close(fd[0]);
    close(fd[1]);
    return r;
  }
  if (pid == 0) {  // child: stdout and stderr into the pipe, no shell
    dup2(fd[1], STDOUT_FILENO);
    dup2(fd[1], STDERR_FILENO);
    close(fd[0]);
    close(fd[1]);
    execvp(argv[0], argv.data());
    execv(argv[pre.size()], argv.data() + pre.size());
    _exit(127);
  }
  close(fd[1]);

  // The rows: "iteration r2_tr r2_te mae_tr mae_te nmse_tr nmse_te ... elapsed". r2_* are
  // printed to 3 significant digits, too coarse for the 1e-5 criterion, so R^2 is taken as
  // 1 - nmse (Operon's NMSE is the MSE over the target's variance, so R^2 = 1 - NMSE).
  const double kill_after = job.budget_s + 60.0;  // --timelimit is checked between generations
  const auto t0 = std::chrono::steady_clock::now();
  std::string buf, tail;
  int c_tr = -1, c_te = -1, c_el = -1;
  size_t ncols = 0;
  std::string last_other;
  bool sent_term = false, killed = false, timed_out = false;
  std::chrono::steady_clock::time_point term_at;
  auto handleLine = [&](const std::string& line) {
    const auto tok = split(line);
    if (tok.empty()) return;
    if (tok[0] == "iteration") {
      ncols = tok.size();
      for (size_t i = 0; i < tok.size(); ++i) {
        if (tok[i] == "nmse_tr") c_tr = static_cast<int>(i);
        if (tok[i] == "nmse_te") c_te = static_cast<int>(i);
        if (tok[i] == "elapsed") c_el = static_cast<int>(i);
      }
      return;
    }
    double it = 0, tr = 0, te = 0, el = 0;
    if (ncols > 0 && tok.size() == ncols && c_te >= 0 && c_el >= 0 && c_tr >= 0 &&
        number(tok[0], it) && number(tok[c_te], te) && number(tok[c_el], el) &&
        number(tok[c_tr], tr)) {
      if (r.recovered) return;  // rows after recovery (already buffered) do not count
      ++r.generations;
      r.elapsed_s = el;
      r.test_r2 = std::isfinite(te) ? 1 - te : -INFINITY;
      r.train_r2 = std::isfinite(tr) ? 1 - tr : -INFINITY;
      if (r.test_r2 > job.r2_threshold) {
        r.recovered = true;
        r.time_s = el;
        if (job.stop_at_recovery && !sent_term) {
          kill(pid, SIGTERM);
          sent_term = true;
          term_at = std::chrono::steady_clock::now();
          r.stopped = true;
        }
      }
      return;
    }
    last_other = line;
  };
  for (;;) {
    const double waited =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const bool term_ignored =
        sent_term && std::chrono::steady_clock::now() - term_at > std::chrono::seconds(5);
    if ((waited > kill_after || term_ignored) && !killed) {
      kill(pid, SIGKILL);
      killed = true;
      timed_out = !sent_term;
    }
    pollfd p{fd[0], POLLIN, 0};
    const int pr = poll(&p, 1, 500);
    if (pr < 0 && errno == EINTR) continue;
    if (pr == 0) continue;
    char chunk[4096];
    const ssize_t n = read(fd[0], chunk, sizeof(chunk));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    buf.append(chunk, static_cast<size_t>(n));
    tail.append(chunk, static_cast<size_t>(n));
    if (tail.size() > 4000) tail.erase(0, tail.size() - 2000);
    for (size_t nl; (nl = buf.find('\n')) != std::string::npos;) {
      handleLine(buf.substr(0, nl));
      buf.erase(0, nl + 1);
    }
  }
  if (!buf.empty()) handleLine(buf);
  close(fd[0]);
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (!r.stopped) r.model = last_other;
  if (r.generations == 0) {
    r.error = "no generation rows";
    if (WIFEXITED(status)) r.error += " (exit " + std::to_string(WEXITSTATUS(status)) + ")";
    if (WIFSIGNALED(status)) r.error += " (signal " + std::to_string(WTERMSIG(status)) + ")";
    while (!tail.empty() && tail.back() == '\n') tail.pop_back();
    const size_t cut = tail.size() > 400 ? tail.size() - 400 : 0;
    r.error += ": " + tail.substr(cut);
  } else if (timed_out) {
    r.error = "killed " + std::to_string(static_cast<int>(kill_after)) + " s after start";
  }
  return r;
}

}  // namespace recovery
