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

// One running worker: a request line out, a reply line back.
class GpuProcess {
 public:
  static Expected<std::unique_ptr<GpuProcess>> start(const DriverSpec& d);
  ~GpuProcess();
  GpuProcess(const GpuProcess&) = delete;
  GpuProcess& operator=(const GpuProcess&) = delete;

  // Sends one request and waits up to `timeout_ms` for its reply. A worker that dies, hangs or
  // answers garbage is killed, and every later request fails (the pool replaces it).
  Expected<nlohmann::json> request(const nlohmann::json& req, int timeout_ms);
  const nlohmann::json& hello() const { return hello_; }
  bool alive() const { return fd_ >= 0; }

 private:
  GpuProcess() = default;
  Expected<std::string> readLine(int timeout_ms);
  void kill();

  int pid_ = -1;
  int fd_ = -1;
  std::string buf_;
  nlohmann::json hello_;
};

// Sends `req` to a worker of driver `d`, starting one if none is idle (at most
// `kMaxWorkersPerDriver` per driver). A driver that failed to start is not tried again in
// this process: its error is returned at once.
Expected<nlohmann::json> gpuRequest(const DriverSpec& d, const nlohmann::json& req,
                                    int timeout_ms = 120000);
// The hello line of a worker of `d` (device and driver), starting one if needed.
Expected<nlohmann::json> gpuHello(const DriverSpec& d);
inline constexpr int kMaxWorkersPerDriver = 4;

}  // namespace lgp::emit::detail
