// Vulkan timestamps around compute dispatches: see vk_timer.hpp.
#include "vk_timer.hpp"

#include "pipeline_statistics.hpp"
#include "timing_kernel.hpp"

#include <vulkan/vulkan.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>

namespace lgp::bench {
namespace {

std::string failed(const char* what, VkResult r) {
  return std::string(what) + " failed (VkResult " + std::to_string(r) + ")";
}

std::string typeName(VkPhysicalDeviceType t) {
  switch (t) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU:
      return "discrete";
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU:
      return "integrated";
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU:
      return "virtual";
    case VK_PHYSICAL_DEVICE_TYPE_CPU:
      return "cpu";
    default:
      return "other";
  }
}

}  // namespace

struct VkTimer::Impl {
  VkInstance instance = VK_NULL_HANDLE;
  VkPhysicalDevice phys = VK_NULL_HANDLE;
  VkDevice device = VK_NULL_HANDLE;
  VkQueue queue = VK_NULL_HANDLE;
  uint32_t family = 0;
  uint32_t timestamp_bits = 0;
  PFN_vkGetPipelineExecutablePropertiesKHR get_exec = nullptr;
  PFN_vkGetPipelineExecutableStatisticsKHR get_stats = nullptr;
  VkDescriptorSetLayout set_layout = VK_NULL_HANDLE;
  VkPipelineLayout layout = VK_NULL_HANDLE;

  // The driver's statistics of a pipeline (empty where it reports none).
  nlohmann::json statistics(VkPipeline p) const {
    if (!get_exec || !get_stats) return nlohmann::json::object();
    std::string error;
    return spirv::pipelineStatistics({device, get_exec, get_stats}, p, error);
  }

  bool submitted = false;  // a compile-only device (RADV's null device) cannot even wait idle

  ~Impl() {
    if (device) {
      if (submitted) vkDeviceWaitIdle(device);
      if (layout) vkDestroyPipelineLayout(device, layout, nullptr);
      if (set_layout) vkDestroyDescriptorSetLayout(device, set_layout, nullptr);
      vkDestroyDevice(device, nullptr);
    }
    if (instance) vkDestroyInstance(instance, nullptr);
  }
};

VkTimer::~VkTimer() = default;

Expected<std::unique_ptr<VkTimer>> VkTimer::open(const TimerOptions& o) {
  std::unique_ptr<VkTimer> t(new VkTimer());
  t->impl_ = std::make_unique<Impl>();
  Impl& m = *t->impl_;
  VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
  app.pApplicationName = "lgp_gpu_time";
  app.apiVersion = VK_API_VERSION_1_1;
  VkInstanceCreateInfo ici{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
  ici.pApplicationInfo = &app;
  if (VkResult r = vkCreateInstance(&ici, nullptr, &m.instance); r != VK_SUCCESS)
    return Status::error(failed("vkCreateInstance", r) + " (is a Vulkan driver installed?)");
  uint32_t n = 0;
  vkEnumeratePhysicalDevices(m.instance, &n, nullptr);
  std::vector<VkPhysicalDevice> devs(n);
  vkEnumeratePhysicalDevices(m.instance, &n, devs.data());
  VkPhysicalDeviceProperties chosen{};
  for (VkPhysicalDevice d : devs) {
    VkPhysicalDeviceProperties p;
    vkGetPhysicalDeviceProperties(d, &p);
    t->info_.all.push_back(std::string(p.deviceName) + " (" + typeName(p.deviceType) + ")");
    const bool cpu = p.deviceType == VK_PHYSICAL_DEVICE_TYPE_CPU;
    const bool named =
        o.device.empty() || std::string(p.deviceName).find(o.device) != std::string::npos;
    if (!m.phys && named && (!cpu || o.allow_cpu)) {
      m.phys = d;
      chosen = p;
    }
  }
  if (!m.phys) {
    std::string list;
    for (const auto& s : t->info_.all) list += (list.empty() ? "" : ", ") + s;
    return Status::error("no Vulkan device matches (device '" + o.device + "', " +
                         (o.allow_cpu ? "CPU devices allowed" : "GPUs only") +
                         "); the loader lists: " + (list.empty() ? "none" : list));
  }
  t->info_.name = chosen.deviceName;
  t->info_.type = typeName(chosen.deviceType);
  t->info_.api = std::to_string(VK_API_VERSION_MAJOR(chosen.apiVersion)) + "." +
                 std::to_string(VK_API_VERSION_MINOR(chosen.apiVersion)) + "." +
                 std::to_string(VK_API_VERSION_PATCH(chosen.apiVersion));
  t->info_.timestamp_period_ns = chosen.limits.timestampPeriod;
  VkPhysicalDeviceDriverProperties drv{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_DRIVER_PROPERTIES};
  VkPhysicalDeviceProperties2 p2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
  p2.pNext = &drv;
  vkGetPhysicalDeviceProperties2(m.phys, &p2);
  t->info_.driver = std::string(drv.driverName) + " " + drv.driverInfo;

  uint32_t nq = 0;
  vkGetPhysicalDeviceQueueFamilyProperties(m.phys, &nq, nullptr);
  std::vector<VkQueueFamilyProperties> qf(nq);
  vkGetPhysicalDeviceQueueFamilyProperties(m.phys, &nq, qf.data());
  m.family = std::numeric_limits<uint32_t>::max();
  for (uint32_t i = 0; i < nq; ++i)
    if ((qf[i].queueFlags & VK_QUEUE_COMPUTE_BIT) && qf[i].timestampValidBits > 0) {
      m.family = i;
      m.timestamp_bits = qf[i].timestampValidBits;
      break;
    }
  if (m.family == std::numeric_limits<uint32_t>::max())
    return Status::error("the device has no compute queue with timestamps");
  // The driver's own statistics of each kernel, where it reports them.
  uint32_t next = 0;
  vkEnumerateDeviceExtensionProperties(m.phys, nullptr, &next, nullptr);
  std::vector<VkExtensionProperties> exts(next);
  vkEnumerateDeviceExtensionProperties(m.phys, nullptr, &next, exts.data());
  const char* kExecProps = VK_KHR_PIPELINE_EXECUTABLE_PROPERTIES_EXTENSION_NAME;
  for (const auto& e : exts)
    if (std::strcmp(e.extensionName, kExecProps) == 0) t->info_.pipeline_statistics = true;
  VkPhysicalDevicePipelineExecutablePropertiesFeaturesKHR exec{
      VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PIPELINE_EXECUTABLE_PROPERTIES_FEATURES_KHR};
  exec.pipelineExecutableInfo = VK_TRUE;

  float prio = 1.0f;
  VkDeviceQueueCreateInfo qci{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
  qci.queueFamilyIndex = m.family;
  qci.queueCount = 1;
  qci.pQueuePriorities = &prio;
  VkDeviceCreateInfo dci{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
  dci.queueCreateInfoCount = 1;
  dci.pQueueCreateInfos = &qci;
  if (t->info_.pipeline_statistics) {
    dci.pNext = &exec;
    dci.enabledExtensionCount = 1;
    dci.ppEnabledExtensionNames = &kExecProps;
  }
  if (VkResult r = vkCreateDevice(m.phys, &dci, nullptr, &m.device); r != VK_SUCCESS)
    return Status::error(failed("vkCreateDevice", r));
  vkGetDeviceQueue(m.device, m.family, 0, &m.queue);
  if (t->info_.pipeline_statistics) {
    m.get_exec = reinterpret_cast<PFN_vkGetPipelineExecutablePropertiesKHR>(
        vkGetDeviceProcAddr(m.device, "vkGetPipelineExecutablePropertiesKHR"));
    m.get_stats = reinterpret_cast<PFN_vkGetPipelineExecutableStatisticsKHR>(
        vkGetDeviceProcAddr(m.device, "vkGetPipelineExecutableStatisticsKHR"));
    t->info_.pipeline_statistics = m.get_exec && m.get_stats;
  }

  VkDescriptorSetLayoutBinding b{};
  b.binding = 0;
  b.descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
  b.descriptorCount = 1;
  b.stageFlags = VK_SHADER_STAGE_COMPUTE_BIT;
  VkDescriptorSetLayoutCreateInfo dl{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
  dl.bindingCount = 1;
  dl.pBindings = &b;
  if (VkResult r = vkCreateDescriptorSetLayout(m.device, &dl, nullptr, &m.set_layout);
      r != VK_SUCCESS)
    return Status::error(failed("vkCreateDescriptorSetLayout", r));
  VkPushConstantRange pr{VK_SHADER_STAGE_COMPUTE_BIT, 0, 4};
  VkPipelineLayoutCreateInfo pl{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
  pl.setLayoutCount = 1;
  pl.pSetLayouts = &m.set_layout;
  pl.pushConstantRangeCount = 1;
  pl.pPushConstantRanges = &pr;
  if (VkResult r = vkCreatePipelineLayout(m.device, &pl, nullptr, &m.layout); r != VK_SUCCESS)
    return Status::error(failed("vkCreatePipelineLayout", r));
  return t;
}

namespace {

// Destroys what it holds when the timing ends, however it ends.
struct Resources {
  VkDevice dev;
  std::vector<VkShaderModule> modules;
  std::vector<VkPipeline> pipelines;
  VkBuffer buffer = VK_NULL_HANDLE;
  VkDeviceMemory memory = VK_NULL_HANDLE;
  void* map = nullptr;
  VkDescriptorPool pool = VK_NULL_HANDLE;
  VkQueryPool queries = VK_NULL_HANDLE;
  VkCommandPool cpool = VK_NULL_HANDLE;
  VkFence fence = VK_NULL_HANDLE;
  bool submitted = false;
  explicit Resources(VkDevice d) : dev(d) {}
  ~Resources() {
    if (submitted) vkDeviceWaitIdle(dev);
    if (fence) vkDestroyFence(dev, fence, nullptr);
    if (cpool) vkDestroyCommandPool(dev, cpool, nullptr);
    if (queries) vkDestroyQueryPool(dev, queries, nullptr);
    if (pool) vkDestroyDescriptorPool(dev, pool, nullptr);
    if (map) vkUnmapMemory(dev, memory);
    if (buffer) vkDestroyBuffer(dev, buffer, nullptr);
    if (memory) vkFreeMemory(dev, memory, nullptr);
    for (VkPipeline p : pipelines) vkDestroyPipeline(dev, p, nullptr);
    for (VkShaderModule s : modules) vkDestroyShaderModule(dev, s, nullptr);
  }
};

}  // namespace

Expected<TimedRun> VkTimer::time(const std::vector<std::vector<uint32_t>>& kernels,
                                 uint32_t invocations, uint32_t iters, int rounds, int warmup,
                                 uint32_t keep) {
  Impl& m = *impl_;
  if (invocations == 0 || invocations % kTimingWorkgroup != 0)
    return Status::error("invocations: must be a positive multiple of " +
                         std::to_string(kTimingWorkgroup));
  if (rounds < 0 || warmup < 0) return Status::error("rounds and warmup must be >= 0");
  Resources r(m.device);
  for (const auto& spirv : kernels) {
    VkShaderModuleCreateInfo mi{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
    mi.codeSize = spirv.size() * sizeof(uint32_t);
    mi.pCode = spirv.data();
    VkShaderModule sm;
    if (VkResult e = vkCreateShaderModule(m.device, &mi, nullptr, &sm); e != VK_SUCCESS)
      return Status::error(failed("vkCreateShaderModule", e));
    r.modules.push_back(sm);
    VkComputePipelineCreateInfo ci{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
    if (m.get_stats) ci.flags = VK_PIPELINE_CREATE_CAPTURE_STATISTICS_BIT_KHR;
    ci.stage.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO;
    ci.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
    ci.stage.module = sm;
    ci.stage.pName = "main";
    ci.layout = m.layout;
    VkPipeline p;
    if (VkResult e = vkCreateComputePipelines(m.device, VK_NULL_HANDLE, 1, &ci, nullptr, &p);
        e != VK_SUCCESS)
      return Status::error(failed("vkCreateComputePipelines", e));
    r.pipelines.push_back(p);
  }
  TimedRun out;
  for (VkPipeline p : r.pipelines) out.stats.push_back(m.statistics(p));
  out.ns.assign(kernels.size(), {});
  out.finite.assign(kernels.size(), true);
  out.head.assign(kernels.size(), {});
  if (rounds == 0) return out;  // compile only: the statistics

  // The output: one float per invocation, host-visible (device-local too where offered).
  const VkDeviceSize bytes = VkDeviceSize(invocations) * sizeof(float);
  VkBufferCreateInfo bci{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
  bci.size = bytes;
  bci.usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
  if (VkResult e = vkCreateBuffer(m.device, &bci, nullptr, &r.buffer); e != VK_SUCCESS)
    return Status::error(failed("vkCreateBuffer", e));
  VkMemoryRequirements req;
  vkGetBufferMemoryRequirements(m.device, r.buffer, &req);
  VkPhysicalDeviceMemoryProperties mp;
  vkGetPhysicalDeviceMemoryProperties(m.phys, &mp);
  const VkMemoryPropertyFlags host =
      VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
  uint32_t type = std::numeric_limits<uint32_t>::max();
  for (VkMemoryPropertyFlags want : {host | VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, host}) {
    for (uint32_t i = 0; i < mp.memoryTypeCount && type == std::numeric_limits<uint32_t>::max();
         ++i)
      if ((req.memoryTypeBits >> i & 1u) && (mp.memoryTypes[i].propertyFlags & want) == want)
        type = i;
  }
  if (type == std::numeric_limits<uint32_t>::max())
    return Status::error("no host-visible memory for the output buffer");
  VkMemoryAllocateInfo mai{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
  mai.allocationSize = req.size;
  mai.memoryTypeIndex = type;
  if (VkResult e = vkAllocateMemory(m.device, &mai, nullptr, &r.memory); e != VK_SUCCESS)
    return Status::error(failed("vkAllocateMemory", e));
  vkBindBufferMemory(m.device, r.buffer, r.memory, 0);
  vkMapMemory(m.device, r.memory, 0, VK_WHOLE_SIZE, 0, &r.map);

  VkDescriptorPoolSize ps{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1};
  VkDescriptorPoolCreateInfo dpi{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
  dpi.maxSets = 1;
  dpi.poolSizeCount = 1;
  dpi.pPoolSizes = &ps;
  vkCreateDescriptorPool(m.device, &dpi, nullptr, &r.pool);
  VkDescriptorSetAllocateInfo dai{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
  dai.descriptorPool = r.pool;
  dai.descriptorSetCount = 1;
  dai.pSetLayouts = &m.set_layout;
  VkDescriptorSet set;
  if (VkResult e = vkAllocateDescriptorSets(m.device, &dai, &set); e != VK_SUCCESS)
    return Status::error(failed("vkAllocateDescriptorSets", e));
  VkDescriptorBufferInfo dbi{r.buffer, 0, VK_WHOLE_SIZE};
  VkWriteDescriptorSet w{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
  w.dstSet = set;
  w.dstBinding = 0;
  w.descriptorCount = 1;
  w.descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
  w.pBufferInfo = &dbi;
  vkUpdateDescriptorSets(m.device, 1, &w, 0, nullptr);

  VkQueryPoolCreateInfo qpi{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
  qpi.queryType = VK_QUERY_TYPE_TIMESTAMP;
  qpi.queryCount = 2;
  vkCreateQueryPool(m.device, &qpi, nullptr, &r.queries);
  VkCommandPoolCreateInfo cpi{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
  cpi.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
  cpi.queueFamilyIndex = m.family;
  vkCreateCommandPool(m.device, &cpi, nullptr, &r.cpool);
  VkCommandBufferAllocateInfo cai{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
  cai.commandPool = r.cpool;
  cai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  cai.commandBufferCount = 1;
  VkCommandBuffer cb;
  vkAllocateCommandBuffers(m.device, &cai, &cb);
  VkFenceCreateInfo fci{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
  vkCreateFence(m.device, &fci, nullptr, &r.fence);

  const uint64_t mask =
      m.timestamp_bits >= 64 ? ~uint64_t{0} : (uint64_t{1} << m.timestamp_bits) - 1;
  for (int round = 0; round < warmup + rounds; ++round) {
    const bool last = round + 1 == warmup + rounds;
    for (size_t k = 0; k < kernels.size(); ++k) {
      vkResetCommandBuffer(cb, 0);
      VkCommandBufferBeginInfo bbi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
      bbi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
      vkBeginCommandBuffer(cb, &bbi);
      vkCmdResetQueryPool(cb, r.queries, 0, 2);
      vkCmdBindPipeline(cb, VK_PIPELINE_BIND_POINT_COMPUTE, r.pipelines[k]);
      vkCmdBindDescriptorSets(cb, VK_PIPELINE_BIND_POINT_COMPUTE, m.layout, 0, 1, &set, 0, nullptr);
      vkCmdPushConstants(cb, m.layout, VK_SHADER_STAGE_COMPUTE_BIT, 0, 4, &iters);
      vkCmdWriteTimestamp(cb, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, r.queries, 0);
      vkCmdDispatch(cb, invocations / kTimingWorkgroup, 1, 1);
      vkCmdWriteTimestamp(cb, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, r.queries, 1);
      VkMemoryBarrier mb{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
      mb.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
      mb.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
      vkCmdPipelineBarrier(cb, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0,
                           1, &mb, 0, nullptr, 0, nullptr);
      vkEndCommandBuffer(cb);
      VkSubmitInfo si{VK_STRUCTURE_TYPE_SUBMIT_INFO};
      si.commandBufferCount = 1;
      si.pCommandBuffers = &cb;
      vkResetFences(m.device, 1, &r.fence);
      r.submitted = m.submitted = true;
      if (VkResult e = vkQueueSubmit(m.queue, 1, &si, r.fence); e != VK_SUCCESS)
        return Status::error(failed("vkQueueSubmit", e));
      if (VkResult e = vkWaitForFences(m.device, 1, &r.fence, VK_TRUE, 120ull * 1000 * 1000 * 1000);
          e != VK_SUCCESS)
        return Status::error(failed("vkWaitForFences", e));
      uint64_t ts[2] = {0, 0};
      if (VkResult e =
              vkGetQueryPoolResults(m.device, r.queries, 0, 2, sizeof ts, ts, sizeof(uint64_t),
                                    VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT);
          e != VK_SUCCESS)
        return Status::error(failed("vkGetQueryPoolResults", e));
      const double ticks = static_cast<double>((ts[1] - ts[0]) & mask);
      if (round >= warmup) out.ns[k].push_back(ticks * info_.timestamp_period_ns);
      if (last) {
        const float* v = static_cast<const float*>(r.map);
        out.head[k].assign(v, v + std::min(keep, invocations));
        for (uint32_t i = 0; i < invocations; ++i)
          if (!std::isfinite(v[i])) {
            out.finite[k] = false;
            break;
          }
      }
    }
  }
  return out;
}

}  // namespace lgp::bench
