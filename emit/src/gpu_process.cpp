// Worker processes for the GPU backends (see gpu_process.hpp).
#include "gpu_process.hpp"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/utsname.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <map>
#include <mutex>

#include "lgp/config/json_reader.hpp"

extern char** environ;

namespace lgp::emit::detail {

namespace fs = std::filesystem;

namespace {

std::string envOr(const char* name, const std::string& fallback = "") {
  const char* v = std::getenv(name);
  return v && *v ? std::string(v) : fallback;
}

bool executable(const fs::path& p) {
  std::error_code ec;
  return fs::is_regular_file(p, ec) && ::access(p.c_str(), X_OK) == 0;
}

// $LGP_GPU_TIMEOUT_S in milliseconds, else `fallback_ms`.
int timeoutMs(int fallback_ms) {
  const std::string v = envOr("LGP_GPU_TIMEOUT_S");
  char* end = nullptr;
  const double s = v.empty() ? 0 : std::strtod(v.c_str(), &end);
  if (v.empty() || end == v.c_str() || *end != 0 || !(s > 0) || s > 86400) return fallback_ms;
  return std::max(1, static_cast<int>(s * 1000));
}

// A worker's line as JSON (a parse error is null): the limits of every other JSON lgp reads.
nlohmann::json parseLine(const std::string& line) {
  auto j = parseJson(line);
  return j ? std::move(*j) : nlohmann::json();
}

}  // namespace

int greetingTimeoutMs() {
  return timeoutMs(180000);
}

int requestTimeoutMs() {
  return timeoutMs(120000);
}

Expected<std::string> gpuWorkerPath() {
  if (const std::string e = envOr("LGP_GPU_WORKER"); !e.empty()) {
    if (executable(e)) return e;
    return Status::error("LGP_GPU_WORKER=" + e + ": not an executable file");
  }
  std::vector<fs::path> candidates;
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) candidates.push_back(self.parent_path() / ".." / "libexec" / "lgp" / "lgp-gpu-worker");
#ifdef LGP_GPU_WORKER_INSTALL_PATH
  candidates.emplace_back(LGP_GPU_WORKER_INSTALL_PATH);
#endif
#ifdef LGP_GPU_WORKER_BUILD_PATH
  candidates.emplace_back(LGP_GPU_WORKER_BUILD_PATH);
#endif
  for (const auto& c : candidates)
    if (executable(c)) return fs::weakly_canonical(c, ec).string();
#ifdef LGP_GPU_DISABLED_REASON
  return Status::error(LGP_GPU_DISABLED_REASON);
#else
  return Status::error(
      "lgp-gpu-worker not found (set LGP_GPU_WORKER, or install lgp with its libexec/ folder)");
#endif
}

Expected<std::string> vulkanIcd(const std::string& stem) {
  const char* var = stem == "radeon_icd" ? "LGP_RADV_ICD" : "LGP_LAVAPIPE_ICD";
  if (const std::string e = envOr(var); !e.empty()) {
    std::error_code ec;
    const auto st = fs::status(e, ec);
    if (fs::is_regular_file(st)) return e;
    return Status::error(std::string(var) + "=" + e + ": " +
                         (!fs::exists(st) ? "no such file"
                          : fs::is_directory(st)
                              ? "a directory, not a driver manifest (a .json file)"
                              : "not a regular file (a device, FIFO or socket), not a driver "
                                "manifest (a .json file)"));
  }
  std::vector<fs::path> dirs;
  const std::string home = envOr("HOME");
  dirs.push_back(fs::path(envOr("XDG_DATA_HOME", home.empty() ? "" : home + "/.local/share")) /
                 "vulkan/icd.d");
  std::string data = envOr("XDG_DATA_DIRS", "/usr/local/share:/usr/share");
  for (size_t a = 0; a <= data.size();) {
    const size_t b = std::min(data.find(':', a), data.size());
    if (b > a) dirs.push_back(fs::path(data.substr(a, b - a)) / "vulkan/icd.d");
    a = b + 1;
  }
  dirs.push_back("/etc/vulkan/icd.d");
  struct utsname u {};
  const std::string arch = ::uname(&u) == 0 ? u.machine : "";
  std::string any;
  for (const auto& d : dirs) {
    std::error_code ec;
    if (d.empty() || !fs::is_directory(d, ec)) continue;
    for (const auto& f : fs::directory_iterator(d, ec)) {
      const std::string name = f.path().filename().string();
      if (name.rfind(stem, 0) != 0 || f.path().extension() != ".json") continue;
      if (!arch.empty() && name.find(arch) != std::string::npos) return f.path().string();
      if (any.empty()) any = f.path().string();
    }
  }
  if (!any.empty()) return any;
  return Status::error(std::string("no Vulkan driver manifest ") + stem +
                       "*.json (install mesa-vulkan-drivers, or set " + var + ")");
}

std::vector<std::string> workerEnvironment(const DriverSpec& d, const std::string& icd) {
  static const char* kSteering[] = {"VK_",      "RADV_", "ACO_", "MESA_", "LP_",
                                    "GALLIUM_", "AMD_",  "DRI_", "LIBGL_"};
  std::vector<std::string> env;
  for (char** e = environ; e && *e; ++e) {
    const std::string kv = *e;
    bool drop = false;
    for (const char* p : kSteering) drop = drop || kv.rfind(p, 0) == 0;
    if (!drop) env.push_back(kv);
  }
  env.push_back("VK_ICD_FILENAMES=" + icd);
  env.push_back("VK_DRIVER_FILES=" + icd);
  env.push_back("VK_LOADER_LAYERS_DISABLE=~all~");
  env.push_back("MESA_SHADER_CACHE_DISABLE=true");
  env.push_back("MESA_GLSL_CACHE_DISABLE=true");
  if (!d.radv_family.empty()) env.push_back("RADV_FORCE_FAMILY=" + d.radv_family);
  return env;
}

Expected<std::unique_ptr<GpuProcess>> GpuProcess::start(const DriverSpec& d, bool* timed_out) {
  auto exe = gpuWorkerPath();
  if (!exe) return exe.status();
  auto icd = vulkanIcd(d.mode == "stats" ? "radeon_icd" : "lvp_icd");
  if (!icd) return icd.status();
  int sv[2];
  if (::socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, sv) != 0)
    return Status::error(std::string("socketpair: ") + std::strerror(errno));
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_adddup2(&fa, sv[1], 0);
  posix_spawn_file_actions_adddup2(&fa, sv[1], 1);
  const std::vector<std::string> env = workerEnvironment(d, *icd);
  std::vector<char*> envp;
  for (const auto& e : env) envp.push_back(const_cast<char*>(e.c_str()));
  envp.push_back(nullptr);
  std::string mode = d.mode;
  char* argv[] = {const_cast<char*>(exe->c_str()), mode.data(), nullptr};
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, exe->c_str(), &fa, nullptr, argv, envp.data());
  posix_spawn_file_actions_destroy(&fa);
  ::close(sv[1]);
  if (rc != 0) {
    ::close(sv[0]);
    return Status::error("cannot start " + *exe + ": " + std::strerror(rc));
  }
  std::unique_ptr<GpuProcess> p(new GpuProcess());
  p->pid_ = pid;
  p->fd_ = sv[0];
  // Driver start-up (LLVM for lavapipe) takes seconds on a loaded machine.
  auto line = p->readLine(greetingTimeoutMs(), size_t{64} << 10);
  if (!line) {
    if (timed_out) *timed_out = p->timed_out_;
    return Status::error(
        "lgp-gpu-worker (" + d.key() + "): " +
        (p->timed_out_ ? "no greeting within " + std::to_string(greetingTimeoutMs() / 1000) + " s"
                       : line.error()));
  }
  p->hello_ = parseLine(*line);
  if (!p->hello_.is_object())
    return Status::error("lgp-gpu-worker (" + d.key() + "): unreadable greeting");
  const auto ok = p->hello_.find("ok");
  if (ok == p->hello_.end() || *ok != true) {
    const auto why = p->hello_.find("error");
    return Status::error(why != p->hello_.end() && why->is_string()
                             ? why->get<std::string>()
                             : std::string("the worker failed to start"));
  }
  return p;
}

GpuProcess::~GpuProcess() {
  if (fd_ >= 0) {
    ::close(fd_);  // end of input: the worker exits
    fd_ = -1;
  }
  if (pid_ > 0) {
    for (int i = 0; i < 200; ++i) {
      if (::waitpid(pid_, nullptr, WNOHANG) != 0) return;
      ::usleep(10000);
    }
    ::kill(pid_, SIGKILL);
    ::waitpid(pid_, nullptr, 0);
  }
}

void GpuProcess::kill() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  if (pid_ > 0) {
    ::kill(pid_, SIGKILL);
    ::waitpid(pid_, nullptr, 0);
    pid_ = -1;
  }
}

Expected<std::string> GpuProcess::readLine(int timeout_ms, size_t max_bytes) {
  timed_out_ = false;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
  size_t scanned = 0;  // bytes of buf_ known to hold no newline
  for (;;) {
    if (const size_t nl = buf_.find('\n', scanned); nl != std::string::npos) {
      if (nl > max_bytes) break;
      std::string line = buf_.substr(0, nl);
      buf_.erase(0, nl + 1);
      return line;
    }
    scanned = buf_.size();
    // Nothing a request asks for is this long: a worker gone wrong is not buffered whole.
    if (buf_.size() > max_bytes) break;
    if (fd_ < 0) return Status::error("the worker is gone");
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
                          deadline - std::chrono::steady_clock::now())
                          .count();
    if (left <= 0) {
      kill();
      timed_out_ = true;
      return Status::error("no reply within " + std::to_string(timeout_ms / 1000) + " s");
    }
    pollfd pfd{fd_, POLLIN, 0};
    const int r = ::poll(&pfd, 1, static_cast<int>(std::min<long long>(left, 1000)));
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) continue;
    char chunk[65536];
    const ssize_t n = ::read(fd_, chunk, sizeof chunk);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      kill();
      return Status::error("the worker exited (driver crash?)");
    }
    buf_.append(chunk, static_cast<size_t>(n));
  }
  kill();
  return Status::error("a reply line longer than " + std::to_string(max_bytes) +
                       " bytes (the most this request can need)");
}

Expected<nlohmann::json> GpuProcess::request(const nlohmann::json& req, int timeout_ms,
                                             size_t max_reply_bytes) {
  if (fd_ < 0) return Status::error("the worker is gone");
  const std::string line =
      req.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace) + "\n";
  for (size_t off = 0; off < line.size();) {
    const ssize_t n = ::send(fd_, line.data() + off, line.size() - off, MSG_NOSIGNAL);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      kill();
      return Status::error("the worker is gone");
    }
    off += static_cast<size_t>(n);
  }
  auto reply = readLine(timeout_ms, max_reply_bytes);
  if (!reply) return reply.status();
  auto j = parseLine(*reply);
  if (!j.is_object()) {
    kill();
    return Status::error("unreadable reply from the worker");
  }
  return j;
}

namespace {

// Running workers per driver, and the drivers that could not start.
class Pool {
 public:
  static Pool& instance() {
    static Pool p;
    return p;
  }

  struct Lease {
    Pool* pool;
    std::string key;
    std::unique_ptr<GpuProcess> proc;
    Lease(Pool* p, std::string k, std::unique_ptr<GpuProcess> g)
        : pool(p), key(std::move(k)), proc(std::move(g)) {}
    Lease(const Lease&) = delete;
    Lease& operator=(const Lease&) = delete;
    ~Lease() {
      if (pool && proc) pool->release(key, std::move(proc));
    }
  };

  Expected<std::unique_ptr<Lease>> acquire(const DriverSpec& d) {
    const std::string key = d.key();
    std::unique_lock lock(mu_);
    for (;;) {
      if (auto f = failed_.find(key); f != failed_.end()) return Status::error(f->second);
      auto& idle = idle_[key];
      if (!idle.empty()) {
        auto l = std::make_unique<Lease>(this, key, std::move(idle.back()));
        idle.pop_back();
        return l;
      }
      if (running_[key] < kMaxWorkersPerDriver) break;
      cv_.wait(lock);
    }
    ++running_[key];
    lock.unlock();
    bool timed_out = false;
    auto p = GpuProcess::start(d, &timed_out);
    lock.lock();
    if (!p) {
      --running_[key];
      if (timed_out)
        markHungLocked(key, p.error());
      else if (running_[key] == 0)
        failed_.emplace(key, p.error());
      cv_.notify_all();
      return p.status();
    }
    return std::make_unique<Lease>(this, key, std::move(*p));
  }

  // A driver that let a greeting or a request time out: every later request fails at once,
  // and the user is told once. A hung driver would otherwise cost the whole timeout per
  // request (per member of every front, per candidate of the search), silently.
  void markHung(const std::string& key, const std::string& why) {
    std::lock_guard lock(mu_);
    markHungLocked(key, why);
    cv_.notify_all();
  }

  void release(const std::string& key, std::unique_ptr<GpuProcess> p) {
    std::lock_guard lock(mu_);
    if (p->alive())
      idle_[key].push_back(std::move(p));
    else
      --running_[key];
    cv_.notify_all();
  }

 private:
  std::mutex mu_;
  std::condition_variable cv_;
  std::map<std::string, std::vector<std::unique_ptr<GpuProcess>>> idle_;
  std::map<std::string, int> running_;
  std::map<std::string, std::string> failed_;

  void markHungLocked(const std::string& key, const std::string& why) {
    if (failed_.emplace(key, why + " (earlier in this process; not tried again)").second)
      std::fprintf(stderr,
                   "warning: %s; this GPU driver is not used again by this process (measured "
                   "cost and Vulkan runs that need it are left out)\n",
                   why.c_str());
  }
};

}  // namespace

Expected<nlohmann::json> gpuRequest(const DriverSpec& d, const nlohmann::json& req,
                                    size_t max_reply_bytes) {
  auto lease = Pool::instance().acquire(d);
  if (!lease) return lease.status();
  auto r = (*lease)->proc->request(req, requestTimeoutMs(), max_reply_bytes);
  if (!r) {
    const std::string why = "lgp-gpu-worker (" + d.key() + "): " + r.error();
    if ((*lease)->proc->timedOut()) Pool::instance().markHung(d.key(), why);
    return Status::error(why);
  }
  const auto ok = r->find("ok");
  if (ok == r->end() || *ok != true) {
    const auto why = r->find("error");
    return Status::error(why != r->end() && why->is_string()
                             ? why->get<std::string>()
                             : std::string("the worker reported a failure"));
  }
  return r;
}

Expected<nlohmann::json> gpuHello(const DriverSpec& d) {
  auto lease = Pool::instance().acquire(d);
  if (!lease) return lease.status();
  return (*lease)->proc->hello();
}

}  // namespace lgp::emit::detail
