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
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <map>
#include <mutex>

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

}  // namespace

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
    if (fs::is_regular_file(e, ec)) return e;
    return Status::error(std::string(var) + "=" + e + ": no such file");
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

Expected<std::unique_ptr<GpuProcess>> GpuProcess::start(const DriverSpec& d) {
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
  auto line = p->readLine(180000);
  if (!line) return Status::error("lgp-gpu-worker (" + d.key() + "): " + line.error());
  try {
    p->hello_ = nlohmann::json::parse(*line);
  } catch (const std::exception&) {
    return Status::error("lgp-gpu-worker (" + d.key() + "): unreadable greeting");
  }
  if (!p->hello_.value("ok", false))
    return Status::error(p->hello_.value("error", std::string("the worker failed to start")));
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

Expected<std::string> GpuProcess::readLine(int timeout_ms) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
  for (;;) {
    if (const size_t nl = buf_.find('\n'); nl != std::string::npos) {
      std::string line = buf_.substr(0, nl);
      buf_.erase(0, nl + 1);
      return line;
    }
    if (fd_ < 0) return Status::error("the worker is gone");
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
                          deadline - std::chrono::steady_clock::now())
                          .count();
    if (left <= 0) {
      kill();
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
}

Expected<nlohmann::json> GpuProcess::request(const nlohmann::json& req, int timeout_ms) {
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
  auto reply = readLine(timeout_ms);
  if (!reply) return reply.status();
  try {
    return nlohmann::json::parse(*reply);
  } catch (const std::exception&) {
    kill();
    return Status::error("unreadable reply from the worker");
  }
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
    auto p = GpuProcess::start(d);
    lock.lock();
    if (!p) {
      --running_[key];
      if (running_[key] == 0) failed_[key] = p.error();
      cv_.notify_all();
      return p.status();
    }
    return std::make_unique<Lease>(this, key, std::move(*p));
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
};

}  // namespace

Expected<nlohmann::json> gpuRequest(const DriverSpec& d, const nlohmann::json& req,
                                    int timeout_ms) {
  auto lease = Pool::instance().acquire(d);
  if (!lease) return lease.status();
  auto r = (*lease)->proc->request(req, timeout_ms);
  if (!r) return Status::error("lgp-gpu-worker (" + d.key() + "): " + r.error());
  if (!r->value("ok", false))
    return Status::error(r->value("error", std::string("the worker reported a failure")));
  return r;
}

Expected<nlohmann::json> gpuHello(const DriverSpec& d) {
  auto lease = Pool::instance().acquire(d);
  if (!lease) return lease.status();
  return (*lease)->proc->hello();
}

}  // namespace lgp::emit::detail
