// A compiled pipeline's statistics as its Vulkan driver reports them
// (VK_KHR_pipeline_executable_properties): what the lgp-gpu-worker measures on RADV's null
// device and what the GPU timing benchmark (bench/gpu_time) records on any driver.
#pragma once

#include <vulkan/vulkan.h>

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace lgp::spirv {

struct PipelineStatisticsApi {
  VkDevice device = VK_NULL_HANDLE;
  PFN_vkGetPipelineExecutablePropertiesKHR get_exec = nullptr;
  PFN_vkGetPipelineExecutableStatisticsKHR get_stats = nullptr;
};

// Every statistic of the pipeline's first executable, by the driver's own name (numbers and
// booleans), plus "Subgroup size". The pipeline must have been created with
// VK_PIPELINE_CREATE_CAPTURE_STATISTICS_BIT_KHR. On failure: an empty object and `error` says
// which call failed.
inline nlohmann::json pipelineStatistics(const PipelineStatisticsApi& api, VkPipeline pipeline,
                                         std::string& error) {
  nlohmann::json out = nlohmann::json::object();
  error.clear();
  VkPipelineInfoKHR pi{VK_STRUCTURE_TYPE_PIPELINE_INFO_KHR, nullptr, pipeline};
  uint32_t ne = 0;
  if (api.get_exec(api.device, &pi, &ne, nullptr) != VK_SUCCESS) {
    error = "vkGetPipelineExecutablePropertiesKHR failed";
    return out;
  }
  std::vector<VkPipelineExecutablePropertiesKHR> ep(
      ne, VkPipelineExecutablePropertiesKHR{VK_STRUCTURE_TYPE_PIPELINE_EXECUTABLE_PROPERTIES_KHR});
  if (api.get_exec(api.device, &pi, &ne, ep.data()) != VK_SUCCESS || ne == 0) {
    error =
        ne == 0 ? "the pipeline has no executable" : "vkGetPipelineExecutablePropertiesKHR failed";
    return out;
  }
  VkPipelineExecutableInfoKHR ei{VK_STRUCTURE_TYPE_PIPELINE_EXECUTABLE_INFO_KHR, nullptr, pipeline,
                                 0};
  uint32_t ns = 0;
  if (api.get_stats(api.device, &ei, &ns, nullptr) != VK_SUCCESS) {
    error = "vkGetPipelineExecutableStatisticsKHR failed";
    return out;
  }
  std::vector<VkPipelineExecutableStatisticKHR> st(
      ns, VkPipelineExecutableStatisticKHR{VK_STRUCTURE_TYPE_PIPELINE_EXECUTABLE_STATISTIC_KHR});
  if (api.get_stats(api.device, &ei, &ns, st.data()) != VK_SUCCESS) {
    error = "vkGetPipelineExecutableStatisticsKHR failed";
    return out;
  }
  for (const auto& s : st) {
    switch (s.format) {
      case VK_PIPELINE_EXECUTABLE_STATISTIC_FORMAT_UINT64_KHR:
        out[s.name] = s.value.u64;
        break;
      case VK_PIPELINE_EXECUTABLE_STATISTIC_FORMAT_INT64_KHR:
        out[s.name] = s.value.i64;
        break;
      case VK_PIPELINE_EXECUTABLE_STATISTIC_FORMAT_FLOAT64_KHR:
        out[s.name] = s.value.f64;
        break;
      case VK_PIPELINE_EXECUTABLE_STATISTIC_FORMAT_BOOL32_KHR:
        out[s.name] = s.value.b32 == VK_TRUE;
        break;
      default:
        break;
    }
  }
  out["Subgroup size"] = ep[0].subgroupSize;
  return out;
}

}  // namespace lgp::spirv
