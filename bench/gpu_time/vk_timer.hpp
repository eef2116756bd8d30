// Times compute kernels on a Vulkan device with GPU timestamps (bench/gpu_time). Unlike the
// lgp-gpu-worker, which refuses real GPUs, this is meant for one: the loader's devices are
// listed and the first that is not a CPU device is used, or the one whose name contains
// `device` (a CPU device, such as lavapipe, only with allow_cpu: its timings say nothing about
// a GPU, but it runs the same code, which is what the test uses it for).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lgp/core/status.hpp"

namespace lgp::bench {

struct TimerOptions {
  std::string device;      // substring of the device name; empty: the first GPU
  bool allow_cpu = false;  // accept a CPU device
};

struct DeviceInfo {
  std::string name, driver, api, type;  // type: "discrete", "integrated", "cpu", ...
  std::vector<std::string> all;         // every device the loader listed
  double timestamp_period_ns = 0;
  bool pipeline_statistics = false;  // VK_KHR_pipeline_executable_properties is enabled
};

struct TimedRun {
  std::vector<std::vector<double>> ns;   // [kernel][round]: one dispatch each
  std::vector<bool> finite;              // [kernel]: every value the kernel wrote is finite
  std::vector<std::vector<float>> head;  // [kernel]: the values of the first `keep` invocations
  // [kernel]: the driver's own statistics of the compiled kernel, by the driver's names (where
  // it offers VK_KHR_pipeline_executable_properties; else empty objects)
  std::vector<nlohmann::json> stats;
};

class VkTimer {
 public:
  static Expected<std::unique_ptr<VkTimer>> open(const TimerOptions& o);
  ~VkTimer();
  VkTimer(const VkTimer&) = delete;
  VkTimer& operator=(const VkTimer&) = delete;
  const DeviceInfo& info() const { return info_; }

  // Builds one pipeline per kernel (SPIR-V, the layout of timing_kernel.hpp), then for each
  // round dispatches every kernel once, in order (rounds interleave the kernels, so a clock
  // that drifts moves them all alike): `invocations` threads of `iters` iterations each.
  // The first `warmup` rounds are run and dropped. rounds = 0: the pipelines are built and
  // their statistics read, nothing runs (a compile-only device such as RADV's null device). The last round's values of the first
  // `keep` invocations of each kernel are kept (TimedRun::head), to be checked.
  Expected<TimedRun> time(const std::vector<std::vector<uint32_t>>& kernels, uint32_t invocations,
                          uint32_t iters, int rounds, int warmup, uint32_t keep);

 private:
  VkTimer() = default;
  struct Impl;
  std::unique_ptr<Impl> impl_;
  DeviceInfo info_;
};

}  // namespace lgp::bench
