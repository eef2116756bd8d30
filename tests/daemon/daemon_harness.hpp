// Test harness for lgpd: a scratch directory, a tiny 2-input table, and a real lgpd process
// started with fork/exec (fixed argv, no shell) on a free loopback port, stopped at the end.
// Every wait is a bounded poll; nothing asserts on timing.
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <sys/mount.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <httplib.h>
#include <nlohmann/json.hpp>

namespace lgpd_test {

namespace fs = std::filesystem;
using nlohmann::json;

inline void sleepMs(int ms) {
  std::this_thread::sleep_for(std::chrono::milliseconds(ms));
}

// A fresh directory under the build tree, removed on destruction unless LGPD_KEEP_TMP is set.
class TempDir {
 public:
  explicit TempDir(const std::string& tag) {
    fs::path base = fs::path(LGPD_TEST_OUT) / "tmp";
    fs::create_directories(base);
    std::string tmpl = (base / (tag + "-XXXXXX")).string();
    std::vector<char> buf(tmpl.begin(), tmpl.end());
    buf.push_back('\0');
    char* p = mkdtemp(buf.data());
    if (!p) throw std::runtime_error("mkdtemp failed for " + tmpl);
    path_ = p;
  }
  ~TempDir() {
    if (std::getenv("LGPD_KEEP_TMP")) return;
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

// f(x, y) = x*y + 0.5*x - y/(1+x) on an n x n grid of [0.1, 1]^2: smooth, so a short search
// finds a useful front.
inline fs::path writeGridTable(const fs::path& dir, int n = 12) {
  fs::path p = dir / "table.csv";
  std::ofstream f(p);
  f << "x,y,f\n";
  f.precision(17);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      double x = 0.1 + 0.9 * i / (n - 1), y = 0.1 + 0.9 * j / (n - 1);
      f << x << "," << y << "," << (x * y + 0.5 * x - y / (1 + x)) << "\n";
    }
  return p;
}

// An lgp-table/1 document whose inputs are `inputs` (f = the first input plus a tenth of the
// others) on `rows` rows, with its roles, so that a config need not name its columns.
inline json jsonTable(const std::vector<std::string>& inputs, int rows = 40) {
  json cols = json::object();
  std::vector<double> f(rows, 0.0);
  for (size_t i = 0; i < inputs.size(); ++i) {
    json col = json::array();
    for (int r = 0; r < rows; ++r) {
      const double v = 0.1 + 0.9 * ((r * (i + 3)) % rows) / rows;
      col.push_back(v);
      f[r] += i == 0 ? v : 0.1 * v;
    }
    cols[inputs[i]] = col;
  }
  cols["f"] = f;
  return {{"format", "lgp-table/1"}, {"inputs", inputs}, {"outputs", {"f"}}, {"columns", cols}};
}

inline json runConfig(const fs::path& table, int generations, int population = 32,
                      uint64_t seed = 7) {
  return {
      {"data", {{"path", table.string()}, {"inputs", {"x", "y"}}, {"outputs", {"f"}}}},
      {"search",
       {{"population", population}, {"generations", generations}, {"seed", seed}, {"threads", 1}}}};
}

struct Reply {
  int status = 0;  // 0 = no response (connection failed)
  std::string body;
  json j() const { return json::parse(body, nullptr, false); }
};

// An lgpd child process.
// A run that has ended: finished, cancelled or failed.
inline bool runEnded(const json& run) {
  const std::string s = run.value("status", "");
  return s == "finished" || s == "cancelled" || s == "failed";
}

class Daemon {
 public:
  explicit Daemon(fs::path data_dir) : data_dir_(std::move(data_dir)) {}
  ~Daemon() { stop(); }

  // Starts lgpd and waits until /api/v1/health answers. extra: more argv entries.
  ::testing::AssertionResult start(const std::vector<std::string>& extra = {}) {
    fs::path port_file = data_dir_ / "port";
    std::error_code ec;
    fs::remove(port_file, ec);
    fs::create_directories(data_dir_);
    std::vector<std::string> args = {LGPD_BIN,           "--data-dir",  data_dir_.string(),
                                     "--listen",         "127.0.0.1:0", "--port-file",
                                     port_file.string(), "--log-level", "info"};
    args.insert(args.end(), extra.begin(), extra.end());
    pid_ = spawn(args, data_dir_ / "lgpd.log");
    if (pid_ <= 0) return ::testing::AssertionFailure() << "fork failed";
    for (int i = 0; i < 600; ++i) {  // up to ~30 s
      if (exited()) return ::testing::AssertionFailure() << "lgpd exited early:\n" << log();
      std::ifstream f(port_file);
      if (f >> port_ && port_ > 0) break;
      sleepMs(50);
    }
    if (port_ <= 0) return ::testing::AssertionFailure() << "lgpd wrote no port\n" << log();
    for (int i = 0; i < 200; ++i) {
      if (get("/api/v1/health").status == 200) return ::testing::AssertionSuccess();
      sleepMs(50);
    }
    return ::testing::AssertionFailure() << "lgpd does not answer\n" << log();
  }

  // SIGTERM (graceful: jobs checkpoint), then SIGKILL if it does not exit within ~20 s.
  int stop() {
    if (pid_ <= 0) return exit_code_;
    ::kill(pid_, SIGTERM);
    for (int i = 0; i < 400 && !exited(); ++i) sleepMs(50);
    if (!exited()) {
      ::kill(pid_, SIGKILL);
      int st = 0;
      ::waitpid(pid_, &st, 0);
      exit_code_ = -1;
    }
    pid_ = -1;
    return exit_code_;
  }

  void kill9() {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGKILL);
    int st = 0;
    ::waitpid(pid_, &st, 0);
    pid_ = -1;
  }

  // True once the child has exited (reaped).
  bool exited() {
    if (pid_ <= 0) return true;
    int st = 0;
    pid_t r = ::waitpid(pid_, &st, WNOHANG);
    if (r == pid_) {
      exit_code_ = WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
      pid_ = -1;
      return true;
    }
    return false;
  }
  bool alive() { return !exited(); }
  int exitCode() const { return exit_code_; }
  pid_t pid() const { return pid_; }

  std::string url() const { return "http://127.0.0.1:" + std::to_string(port_); }
  int port() const { return port_; }
  std::string log() const {
    std::ifstream f(data_dir_ / "lgpd.log");
    std::stringstream ss;
    ss << f.rdbuf();
    return ss.str();
  }

  void setToken(std::string t) { token_ = std::move(t); }

  Reply request(const std::string& method, const std::string& path, const std::string& body = "",
                httplib::Headers headers = {}) const {
    httplib::Client c("127.0.0.1", port_);
    c.set_connection_timeout(5);
    c.set_read_timeout(60);
    c.set_write_timeout(60);
    if (!token_.empty()) headers.emplace("Authorization", "Bearer " + token_);
    auto res = method == "GET"    ? c.Get(path, headers)
               : method == "POST" ? c.Post(path, headers, body, "application/json")
                                  : c.Delete(path, headers);
    if (!res) return {};
    return {res->status, res->body};
  }
  Reply get(const std::string& path) const { return request("GET", path); }
  Reply post(const std::string& path, const std::string& body) const {
    return request("POST", path, body);
  }
  Reply del(const std::string& path) const { return request("DELETE", path); }

  // Submits a config; returns the id ("" on failure, with the reply in *out).
  std::string submit(const json& cfg, Reply* out = nullptr) const {
    Reply r = post("/api/v1/runs", cfg.dump());
    if (out) *out = r;
    if (r.status != 201) return "";
    return r.j().value("id", "");
  }

  // Polls GET /api/v1/runs/{id} until pred(run) or ~timeout_s; returns the last run JSON.
  json waitFor(const std::string& id, const std::function<bool(const json&)>& pred,
               double timeout_s = 120) const {
    json last;
    // LGP_TEST_TIME_SCALE (scripts/sanitize.sh sets it): an instrumented lgpd (-O1 ASan)
    // runs the same generations many times slower; the deadline is a hang guard, not a bound.
    const char* k = std::getenv("LGP_TEST_TIME_SCALE");
    if (const double scale = k ? std::atof(k) : 1; scale > 1) timeout_s *= scale;
    const int steps = static_cast<int>(timeout_s / 0.02);
    for (int i = 0; i < steps; ++i) {
      Reply r = get("/api/v1/runs/" + id);
      if (r.status == 200) {
        last = r.j();
        if (pred(last)) return last;
      }
      sleepMs(20);
    }
    return last;
  }
  json waitDone(const std::string& id, double timeout_s = 120) const {
    return waitFor(id, runEnded, timeout_s);
  }

  // fork/exec with stdout+stderr to `log_path`; no shell involved.
  static pid_t spawn(const std::vector<std::string>& args, const fs::path& log_path) {
    std::vector<char*> argv;
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    pid_t pid = ::fork();
    if (pid == 0) {
      int fd = ::open(log_path.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
      if (fd >= 0) {
        ::dup2(fd, 1);
        ::dup2(fd, 2);
        ::close(fd);
      }
      ::execv(argv[0], argv.data());
      ::_exit(127);
    }
    return pid;
  }

 private:
  fs::path data_dir_;
  pid_t pid_ = -1;
  int port_ = 0;
  int exit_code_ = 0;
  std::string token_;
};

// Runs a program to completion (bounded by timeout_s, then SIGKILL) with stdout captured
// into *out and stderr appended to `log`. Returns the exit code (-1 on timeout).
inline int runProgram(const std::vector<std::string>& args, std::string* out,
                      const fs::path& err_log, double timeout_s = 120,
                      const std::vector<std::string>& env = {}) {
  int pipefd[2];
  if (::pipe(pipefd) != 0) return -1;
  std::vector<char*> argv;
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  // The environment is built before fork: the child only calls async-signal-safe functions.
  std::vector<std::string> env_strings;
  for (char** e = environ; *e; ++e) env_strings.emplace_back(*e);
  env_strings.insert(env_strings.end(), env.begin(), env.end());
  std::vector<char*> envp;
  for (auto& e : env_strings) envp.push_back(e.data());
  envp.push_back(nullptr);
  pid_t pid = ::fork();
  if (pid == 0) {
    ::close(pipefd[0]);
    ::dup2(pipefd[1], 1);
    int fd = ::open(err_log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
    if (fd >= 0) ::dup2(fd, 2);
    ::execve(argv[0], argv.data(), envp.data());
    ::_exit(127);
  }
  ::close(pipefd[1]);
  ::fcntl(pipefd[0], F_SETFL, O_NONBLOCK);
  std::string buf;
  char chunk[65536];
  auto deadline = std::chrono::steady_clock::now() +
                  std::chrono::milliseconds(static_cast<int>(timeout_s * 1000));
  int code = -1;
  for (;;) {
    ssize_t n;
    while ((n = ::read(pipefd[0], chunk, sizeof chunk)) > 0) buf.append(chunk, n);
    int st = 0;
    if (::waitpid(pid, &st, WNOHANG) == pid) {
      while ((n = ::read(pipefd[0], chunk, sizeof chunk)) > 0) buf.append(chunk, n);
      code = WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
      break;
    }
    if (std::chrono::steady_clock::now() > deadline) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, &st, 0);
      break;
    }
    sleepMs(20);
  }
  ::close(pipefd[0]);
  if (out) *out = std::move(buf);
  return code;
}

// A tmpfs of `mb` MiB on `dir`, unmounted on destruction; mounted() is false where this
// process may not mount (not root, no CAP_SYS_ADMIN, a restricted container).
class SmallDisk {
 public:
  SmallDisk(const fs::path& dir, int mb) : dir_(dir) {
    fs::create_directories(dir);
    const std::string opts = "size=" + std::to_string(mb) + "m";
    if (::mount("tmpfs", dir.c_str(), "tmpfs", 0, opts.c_str()) == 0)
      mounted_ = true;
    else
      why_ = std::strerror(errno);
  }
  ~SmallDisk() {
    if (mounted_) ::umount2(dir_.c_str(), MNT_DETACH);
  }
  bool mounted() const { return mounted_; }
  const fs::path& dir() const { return dir_; }
  const std::string& why() const { return why_; }

  // Writes a file until the disk is full. Returns the bytes written.
  size_t fill() const {
    int fd = ::open((dir_ / "filler").c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
    if (fd < 0) return 0;
    size_t total = 0;
    std::vector<char> chunk(1 << 20, 'x');
    for (size_t size : {size_t{1} << 20, size_t{4096}, size_t{1}})
      for (;;) {
        ssize_t n = ::write(fd, chunk.data(), size);
        if (n <= 0) break;
        total += static_cast<size_t>(n);
      }
    ::close(fd);
    return total;
  }
  void unfill() const {
    std::error_code ec;
    fs::remove(dir_ / "filler", ec);
  }

 private:
  fs::path dir_;
  bool mounted_ = false;
  std::string why_;
};

}  // namespace lgpd_test
