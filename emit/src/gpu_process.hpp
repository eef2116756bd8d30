// The lgp-gpu-worker child processes (emit/worker/gpu_worker.cpp): where the worker and the
// Vulkan drivers are, the environment that selects a driver, and a pool of running workers
// per driver. Private to emit/.
#pragma once

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "lgp/core/status.hpp"

namespace lgp::emit::detail {

// A driver a worker is started for: the mode ("stats" on RADV's null device, "run" on
// lavapipe) and, for stats, the RADV family (RADV_FORCE_FAMILY, e.g. "navi21").
struct DriverSpec {
  std::string mode;
  std::string radv_family;
  std::string key() const { return mode + ":" + radv_family; }
};

// The worker executable: $LGP_GPU_WORKER, else ../libexec/lgp/lgp-gpu-worker next to the
// running program, else the install and build locations recorded at configure time.
Expected<std::string> gpuWorkerPath();
// A Vulkan ICD manifest whose file name starts with `stem` ("radeon_icd", "lvp_icd"):
// $LGP_RADV_ICD / $LGP_LAVAPIPE_ICD, else the loader's search directories
// ($XDG_DATA_HOME, $XDG_DATA_DIRS, /etc, each + /vulkan/icd.d), preferring this machine's arch.
Expected<std::string> vulkanIcd(const std::string& stem);

// The child's environment: this process's, minus every variable that steers Vulkan or Mesa
// (VK_*, RADV_*, ACO_*, MESA_*, LP_*, GALLIUM_*, AMD_*), plus the explicit selection: the ICD
// file (VK_ICD_FILENAMES and VK_DRIVER_FILES), no layers (VK_LOADER_LAYERS_DISABLE=~all~, so
// no implicit layer probes real devices), no on-disk shader cache, and RADV_FORCE_FAMILY.
std::vector<std::string> workerEnvironment(const DriverSpec& d, const std::string& icd);

// How long a worker may take to greet (driver start-up: LLVM for lavapipe takes seconds on a
// loaded machine) and to answer one request; $LGP_GPU_TIMEOUT_S (seconds, > 0) sets both.
int greetingTimeoutMs();
int requestTimeoutMs();

// One running worker: a request line out, a reply line back.
class GpuProcess {
 public:
  // `timed_out` (if given): set when the worker did not greet in time.
  static Expected<std::unique_ptr<GpuProcess>> start(const DriverSpec& d,
                                                     bool* timed_out = nullptr);
  ~GpuProcess();
  GpuProcess(const GpuProcess&) = delete;
  GpuProcess& operator=(const GpuProcess&) = delete;

  // Sends one request and waits up to `timeout_ms` for its reply line of at most
  // `max_reply_bytes`. A worker that dies, hangs, answers garbage or too much is killed, and
  // every later request fails (the pool replaces it).
  Expected<nlohmann::json> request(const nlohmann::json& req, int timeout_ms,
                                   size_t max_reply_bytes);
  const nlohmann::json& hello() const { return hello_; }
  bool alive() const { return fd_ >= 0; }
  // The last request (or the greeting) got no answer in time.
  bool timedOut() const { return timed_out_; }

 private:
  GpuProcess() = default;
  Expected<std::string> readLine(int timeout_ms, size_t max_bytes);
  void kill();

  int pid_ = -1;
  int fd_ = -1;
  bool timed_out_ = false;
  std::string buf_;
  nlohmann::json hello_;
};

// Sends `req` to a worker of driver `d`, starting one if none is idle (at most
// `kMaxWorkersPerDriver` per driver). A driver that failed to start, or that let a greeting
// or a request time out once, is not tried again in this process: its error is returned at
// once (a driver that hangs would cost every later request the whole timeout), and the
// timeout is reported once on stderr.
inline constexpr size_t kDefaultMaxReplyBytes = size_t{1} << 20;
Expected<nlohmann::json> gpuRequest(const DriverSpec& d, const nlohmann::json& req,
                                    size_t max_reply_bytes = kDefaultMaxReplyBytes);
// The hello line of a worker of `d` (device and driver), starting one if needed.
Expected<nlohmann::json> gpuHello(const DriverSpec& d);
inline constexpr int kMaxWorkersPerDriver = 4;

}  // namespace lgp::emit::detail
