// lgp-gpu-worker: the only lgp code that talks to a Vulkan driver. The emit library starts it
// as a child process with the driver chosen in its environment (emit/src/gpu.cpp): RADV's null
// device (RADV_FORCE_FAMILY, compiles to real AMD ISA, runs nothing) for ISA statistics, or
// lavapipe (runs compute shaders on the CPU) for running emitted code over a table. A child
// keeps the driver's environment variables, its threads and any crash of its own out of the
// caller's process, and lets one caller hold several drivers at once.
//
// Usage: lgp-gpu-worker stats|run. It checks that the device it was given is the one the mode
// needs (a "Null hardware" RADV device for stats, llvmpipe for run) and refuses anything else,
// so a real GPU is never used. Protocol: one JSON object per line on stdin, one reply per line
// on stdout. The first reply, sent unasked, describes the device.
//   {"op": "stats", "lang": "glsl"|"hlsl", "source": "..."}
//     -> {"ok": true, "stats": {"Instructions": 28, "VGPRs": 8, ...}}  (every statistic the
//        driver reports for the compute shader, by its own name)
//   {"op": "run", "lang": ..., "source": ..., "inputs": [row-major floats], "in_stride": ni,
//    "out_stride": k, "rows": n}
//     -> {"ok": true, "output_bits": [row-major float32 bit patterns, as unsigned integers]}
//   {"op": "spirv", "lang": ..., "source": ...} -> {"ok": true, "words": n} (compile only)
//   any failure -> {"ok": false, "error": "..."}; the worker keeps serving.
// Shaders are compute shaders with `main` as entry point, two storage buffers (binding 0: the
// inputs, binding 1: the outputs, float32) and a 4-byte push constant (the row count).
// 16-bit arithmetic (GLSL float16_t) is enabled where the device exposes shaderFloat16.
#include <vulkan/vulkan.h>

#include <glslang/Public/ShaderLang.h>

#include <cstdio>
#include <cstring>
#include <iostream>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "pipeline_statistics.hpp"
#include "spirv_compile.hpp"

namespace {

using nlohmann::json;

struct Failure : std::runtime_error {
  using std::runtime_error::runtime_error;
};

void check(VkResult r, const char* what) {
  if (r != VK_SUCCESS)
    throw Failure(std::string(what) + " failed (VkResult " + std::to_string(r) + ")");
}

// Shader text to SPIR-V (spirv_compile.hpp); its errors reach the caller as failures.
std::vector<uint32_t> compile(const std::string& lang, const std::string& source) {
  try {
    return lgp::spirv::compileCompute(lang, source);
  } catch (const lgp::spirv::CompileError& e) {
    throw Failure(e.what());
  }
}

class Device {
 public:
  explicit Device(bool stats) : stats_(stats) {
    VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
    app.pApplicationName = "lgp-gpu-worker";
    app.apiVersion = VK_API_VERSION_1_1;
    VkInstanceCreateInfo ici{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
    ici.pApplicationInfo = &app;
    check(vkCreateInstance(&ici, nullptr, &instance_), "vkCreateInstance");
    uint32_t n = 0;
    check(vkEnumeratePhysicalDevices(instance_, &n, nullptr), "vkEnumeratePhysicalDevices");
    if (n == 0) throw Failure("the Vulkan loader found no device for this driver");
    std::vector<VkPhysicalDevice> devs(n);
    check(vkEnumeratePhysicalDevices(instance_, &n, devs.data()), "vkEnumeratePhysicalDevices");
    // Only the device the mode asks for: never a real GPU.
    for (VkPhysicalDevice d : devs) {
      VkPhysicalDeviceProperties p;
      vkGetPhysicalDeviceProperties(d, &p);
      const std::string name = p.deviceName;
      const bool ok =
          stats ? name.rfind("Null hardware", 0) == 0 && name.find("RADV") != std::string::npos
                : p.deviceType == VK_PHYSICAL_DEVICE_TYPE_CPU;
      if (ok) {
        phys_ = d;
        props_ = p;
        break;
      }
    }
    if (!phys_)
      throw Failure(
          stats ? "no RADV null device (is RADV_FORCE_FAMILY set and the RADV ICD selected?)"
                : "no CPU Vulkan device (is the lavapipe ICD selected?)");

    VkPhysicalDeviceDriverProperties drv{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_DRIVER_PROPERTIES};
    VkPhysicalDeviceProperties2 p2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
    p2.pNext = &drv;
    vkGetPhysicalDeviceProperties2(phys_, &p2);
    driver_ = std::string(drv.driverName) + " " + drv.driverInfo;

    VkPhysicalDeviceShaderFloat16Int8Features f16{
        VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_SHADER_FLOAT16_INT8_FEATURES};
    VkPhysicalDevicePipelineExecutablePropertiesFeaturesKHR exec{
        VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PIPELINE_EXECUTABLE_PROPERTIES_FEATURES_KHR};
    f16.pNext = &exec;
    VkPhysicalDeviceFeatures2 f2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
    f2.pNext = &f16;
    vkGetPhysicalDeviceFeatures2(phys_, &f2);
    half_ = f16.shaderFloat16 == VK_TRUE;
    if (stats && exec.pipelineExecutableInfo != VK_TRUE)
      throw Failure("the device does not report pipeline executable statistics");

    uint32_t nq = 0;
    vkGetPhysicalDeviceQueueFamilyProperties(phys_, &nq, nullptr);
    std::vector<VkQueueFamilyProperties> qf(nq);
    vkGetPhysicalDeviceQueueFamilyProperties(phys_, &nq, qf.data());
    queue_family_ = std::numeric_limits<uint32_t>::max();
    for (uint32_t i = 0; i < nq; ++i)
      if (qf[i].queueFlags & VK_QUEUE_COMPUTE_BIT) {
        queue_family_ = i;
        break;
      }
    if (queue_family_ == std::numeric_limits<uint32_t>::max()) throw Failure("no compute queue");

    float prio = 1.0f;
    VkDeviceQueueCreateInfo qci{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
    qci.queueFamilyIndex = queue_family_;
    qci.queueCount = 1;
    qci.pQueuePriorities = &prio;
    VkPhysicalDeviceShaderFloat16Int8Features want16{
        VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_SHADER_FLOAT16_INT8_FEATURES};
    want16.shaderFloat16 = half_ ? VK_TRUE : VK_FALSE;
    VkPhysicalDevicePipelineExecutablePropertiesFeaturesKHR want_exec{
        VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PIPELINE_EXECUTABLE_PROPERTIES_FEATURES_KHR};
    want_exec.pipelineExecutableInfo = stats ? VK_TRUE : VK_FALSE;
    want16.pNext = stats ? &want_exec : nullptr;
    const char* ext = "VK_KHR_pipeline_executable_properties";
    VkDeviceCreateInfo dci{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
    dci.pNext = &want16;
    dci.queueCreateInfoCount = 1;
    dci.pQueueCreateInfos = &qci;
    dci.enabledExtensionCount = stats ? 1 : 0;
    dci.ppEnabledExtensionNames = stats ? &ext : nullptr;
    check(vkCreateDevice(phys_, &dci, nullptr, &device_), "vkCreateDevice");
    vkGetDeviceQueue(device_, queue_family_, 0, &queue_);
    if (stats) {
      get_stats_ = reinterpret_cast<PFN_vkGetPipelineExecutableStatisticsKHR>(
          vkGetDeviceProcAddr(device_, "vkGetPipelineExecutableStatisticsKHR"));
      get_exec_ = reinterpret_cast<PFN_vkGetPipelineExecutablePropertiesKHR>(
          vkGetDeviceProcAddr(device_, "vkGetPipelineExecutablePropertiesKHR"));
      if (!get_stats_ || !get_exec_) throw Failure("vkGetPipelineExecutableStatisticsKHR missing");
    }

    VkDescriptorSetLayoutBinding b[2] = {};
    for (uint32_t i = 0; i < 2; ++i) {
      b[i].binding = i;
      b[i].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
      b[i].descriptorCount = 1;
      b[i].stageFlags = VK_SHADER_STAGE_COMPUTE_BIT;
    }
    VkDescriptorSetLayoutCreateInfo dl{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
    dl.bindingCount = 2;
    dl.pBindings = b;
    check(vkCreateDescriptorSetLayout(device_, &dl, nullptr, &set_layout_), "descriptor layout");
    VkPushConstantRange pr{VK_SHADER_STAGE_COMPUTE_BIT, 0, 4};
    VkPipelineLayoutCreateInfo pl{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
    pl.setLayoutCount = 1;
    pl.pSetLayouts = &set_layout_;
    pl.pushConstantRangeCount = 1;
    pl.pPushConstantRanges = &pr;
    check(vkCreatePipelineLayout(device_, &pl, nullptr, &layout_), "pipeline layout");
  }

  ~Device() {
    if (device_) {
      vkDestroyPipelineLayout(device_, layout_, nullptr);
      vkDestroyDescriptorSetLayout(device_, set_layout_, nullptr);
      vkDestroyDevice(device_, nullptr);
    }
    if (instance_) vkDestroyInstance(instance_, nullptr);
  }
  Device(const Device&) = delete;
  Device& operator=(const Device&) = delete;

  json hello() const {
    return {{"ok", true},
            {"device", props_.deviceName},
            {"driver", driver_},
            {"api", std::to_string(VK_API_VERSION_MAJOR(props_.apiVersion)) + "." +
                        std::to_string(VK_API_VERSION_MINOR(props_.apiVersion)) + "." +
                        std::to_string(VK_API_VERSION_PATCH(props_.apiVersion))},
            {"shader_float16", half_}};
  }

  json stats(const std::vector<uint32_t>& spirv) {
    Pipeline p(*this, spirv, true);
    std::string error;
    json out = lgp::spirv::pipelineStatistics({device_, get_exec_, get_stats_}, p.pipeline, error);
    if (!error.empty()) throw Failure(error);
    return out;
  }

  std::vector<float> run(const std::vector<uint32_t>& spirv, const std::vector<float>& in,
                         uint32_t rows, uint32_t out_stride) {
    Pipeline p(*this, spirv, false);
    const VkDeviceSize in_bytes = std::max<VkDeviceSize>(4, in.size() * sizeof(float));
    const VkDeviceSize out_bytes =
        std::max<VkDeviceSize>(4, VkDeviceSize(rows) * out_stride * sizeof(float));
    Buffer bi(*this, in_bytes), bo(*this, out_bytes);
    if (!in.empty()) std::memcpy(bi.map, in.data(), in.size() * sizeof(float));
    std::memset(bo.map, 0xff, out_bytes);  // NaN: a row the shader never wrote shows up

    VkDescriptorPoolSize ps{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 2};
    VkDescriptorPoolCreateInfo dpi{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
    dpi.maxSets = 1;
    dpi.poolSizeCount = 1;
    dpi.pPoolSizes = &ps;
    Handle<VkDescriptorPool> pool(device_, vkDestroyDescriptorPool);
    check(vkCreateDescriptorPool(device_, &dpi, nullptr, &pool.h), "descriptor pool");
    VkDescriptorSetAllocateInfo dai{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
    dai.descriptorPool = pool.h;
    dai.descriptorSetCount = 1;
    dai.pSetLayouts = &set_layout_;
    VkDescriptorSet set;
    check(vkAllocateDescriptorSets(device_, &dai, &set), "descriptor set");
    VkDescriptorBufferInfo dbi[2] = {{bi.buffer, 0, VK_WHOLE_SIZE}, {bo.buffer, 0, VK_WHOLE_SIZE}};
    VkWriteDescriptorSet w[2] = {};
    for (uint32_t i = 0; i < 2; ++i) {
      w[i].sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET;
      w[i].dstSet = set;
      w[i].dstBinding = i;
      w[i].descriptorCount = 1;
      w[i].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
      w[i].pBufferInfo = &dbi[i];
    }
    vkUpdateDescriptorSets(device_, 2, w, 0, nullptr);

    VkCommandPoolCreateInfo cpi{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
    cpi.queueFamilyIndex = queue_family_;
    Handle<VkCommandPool> cpool(device_, vkDestroyCommandPool);
    check(vkCreateCommandPool(device_, &cpi, nullptr, &cpool.h), "command pool");
    VkCommandBufferAllocateInfo cai{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
    cai.commandPool = cpool.h;
    cai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
    cai.commandBufferCount = 1;
    VkCommandBuffer cb;
    check(vkAllocateCommandBuffers(device_, &cai, &cb), "command buffer");
    VkCommandBufferBeginInfo bbi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
    bbi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
    check(vkBeginCommandBuffer(cb, &bbi), "vkBeginCommandBuffer");
    vkCmdBindPipeline(cb, VK_PIPELINE_BIND_POINT_COMPUTE, p.pipeline);
    vkCmdBindDescriptorSets(cb, VK_PIPELINE_BIND_POINT_COMPUTE, layout_, 0, 1, &set, 0, nullptr);
    vkCmdPushConstants(cb, layout_, VK_SHADER_STAGE_COMPUTE_BIT, 0, 4, &rows);
    vkCmdDispatch(cb, (rows + 63) / 64, 1, 1);
    VkMemoryBarrier mb{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    mb.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
    mb.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
    vkCmdPipelineBarrier(cb, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1,
                         &mb, 0, nullptr, 0, nullptr);
    check(vkEndCommandBuffer(cb), "vkEndCommandBuffer");
    VkFenceCreateInfo fci{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
    Handle<VkFence> fence(device_, vkDestroyFence);
    check(vkCreateFence(device_, &fci, nullptr, &fence.h), "fence");
    VkSubmitInfo si{VK_STRUCTURE_TYPE_SUBMIT_INFO};
    si.commandBufferCount = 1;
    si.pCommandBuffers = &cb;
    check(vkQueueSubmit(queue_, 1, &si, fence.h), "vkQueueSubmit");
    check(vkWaitForFences(device_, 1, &fence.h, VK_TRUE, 60ull * 1000 * 1000 * 1000),
          "vkWaitForFences");
    std::vector<float> out(size_t(rows) * out_stride);
    if (!out.empty()) std::memcpy(out.data(), bo.map, out.size() * sizeof(float));
    return out;
  }

 private:
  template <class H>
  struct Handle {
    VkDevice dev;
    void (*destroy)(VkDevice, H, const VkAllocationCallbacks*);
    H h = VK_NULL_HANDLE;
    Handle(VkDevice d, void (*f)(VkDevice, H, const VkAllocationCallbacks*)) : dev(d), destroy(f) {}
    ~Handle() {
      if (h) destroy(dev, h, nullptr);
    }
  };

  struct Pipeline {
    VkDevice dev;
    VkShaderModule module = VK_NULL_HANDLE;
    VkPipeline pipeline = VK_NULL_HANDLE;
    Pipeline(Device& d, const std::vector<uint32_t>& spirv, bool capture) : dev(d.device_) {
      VkShaderModuleCreateInfo mi{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
      mi.codeSize = spirv.size() * sizeof(uint32_t);
      mi.pCode = spirv.data();
      check(vkCreateShaderModule(dev, &mi, nullptr, &module), "vkCreateShaderModule");
      VkComputePipelineCreateInfo ci{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
      ci.flags = capture ? VK_PIPELINE_CREATE_CAPTURE_STATISTICS_BIT_KHR : 0;
      ci.stage.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO;
      ci.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
      ci.stage.module = module;
      ci.stage.pName = "main";
      ci.layout = d.layout_;
      check(vkCreateComputePipelines(dev, VK_NULL_HANDLE, 1, &ci, nullptr, &pipeline),
            "vkCreateComputePipelines");
    }
    ~Pipeline() {
      if (pipeline) vkDestroyPipeline(dev, pipeline, nullptr);
      if (module) vkDestroyShaderModule(dev, module, nullptr);
    }
  };

  struct Buffer {
    VkDevice dev;
    VkBuffer buffer = VK_NULL_HANDLE;
    VkDeviceMemory memory = VK_NULL_HANDLE;
    void* map = nullptr;
    Buffer(Device& d, VkDeviceSize bytes) : dev(d.device_) {
      VkBufferCreateInfo bci{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
      bci.size = bytes;
      bci.usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
      check(vkCreateBuffer(dev, &bci, nullptr, &buffer), "vkCreateBuffer");
      VkMemoryRequirements req;
      vkGetBufferMemoryRequirements(dev, buffer, &req);
      VkPhysicalDeviceMemoryProperties mp;
      vkGetPhysicalDeviceMemoryProperties(d.phys_, &mp);
      const VkMemoryPropertyFlags want =
          VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
      uint32_t type = std::numeric_limits<uint32_t>::max();
      for (uint32_t i = 0; i < mp.memoryTypeCount; ++i)
        if ((req.memoryTypeBits >> i & 1u) && (mp.memoryTypes[i].propertyFlags & want) == want) {
          type = i;
          break;
        }
      if (type == std::numeric_limits<uint32_t>::max()) throw Failure("no host-visible memory");
      VkMemoryAllocateInfo mai{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
      mai.allocationSize = req.size;
      mai.memoryTypeIndex = type;
      check(vkAllocateMemory(dev, &mai, nullptr, &memory), "vkAllocateMemory");
      check(vkBindBufferMemory(dev, buffer, memory, 0), "vkBindBufferMemory");
      check(vkMapMemory(dev, memory, 0, VK_WHOLE_SIZE, 0, &map), "vkMapMemory");
    }
    ~Buffer() {
      if (map) vkUnmapMemory(dev, memory);
      if (buffer) vkDestroyBuffer(dev, buffer, nullptr);
      if (memory) vkFreeMemory(dev, memory, nullptr);
    }
  };

  bool stats_;
  VkInstance instance_ = VK_NULL_HANDLE;
  VkPhysicalDevice phys_ = VK_NULL_HANDLE;
  VkPhysicalDeviceProperties props_{};
  std::string driver_;
  bool half_ = false;
  VkDevice device_ = VK_NULL_HANDLE;
  VkQueue queue_ = VK_NULL_HANDLE;
  uint32_t queue_family_ = 0;
  VkDescriptorSetLayout set_layout_ = VK_NULL_HANDLE;
  VkPipelineLayout layout_ = VK_NULL_HANDLE;
  PFN_vkGetPipelineExecutableStatisticsKHR get_stats_ = nullptr;
  PFN_vkGetPipelineExecutablePropertiesKHR get_exec_ = nullptr;
};

json serve(Device& dev, bool stats_mode, const json& req) {
  const std::string op = req.at("op").get<std::string>();
  const std::string lang = req.at("lang").get<std::string>();
  const std::string source = req.at("source").get<std::string>();
  const std::vector<uint32_t> spirv = compile(lang, source);
  if (op == "spirv") return {{"ok", true}, {"words", spirv.size()}};
  if (op == "stats") {
    if (!stats_mode) throw Failure("op stats: this worker runs shaders (mode run)");
    return {{"ok", true}, {"stats", dev.stats(spirv)}};
  }
  if (op == "run") {
    if (stats_mode) throw Failure("op run: the null device cannot run shaders (mode stats)");
    const auto rows = req.at("rows").get<uint32_t>();
    const auto in_stride = req.at("in_stride").get<uint32_t>();
    const auto out_stride = req.at("out_stride").get<uint32_t>();
    const auto in = req.at("inputs").get<std::vector<float>>();
    if (in.size() != size_t(rows) * in_stride)
      throw Failure(
          "inputs: expected rows * in_stride = " + std::to_string(size_t(rows) * in_stride) +
          " values, got " + std::to_string(in.size()));
    if (out_stride == 0 || rows == 0) throw Failure("rows and out_stride must be positive");
    // Bit patterns, so NaN and infinities come back as they were written.
    const std::vector<float> out = dev.run(spirv, in, rows, out_stride);
    std::vector<uint32_t> bits(out.size());
    if (!out.empty()) std::memcpy(bits.data(), out.data(), out.size() * sizeof(float));
    return {{"ok", true}, {"output_bits", bits}};
  }
  throw Failure("op: expected stats, run or spirv, got '" + op + "'");
}

}  // namespace

int main(int argc, char** argv) {
  const std::string mode = argc > 1 ? argv[1] : "";
  if (mode != "stats" && mode != "run") {
    std::fprintf(stderr, "usage: lgp-gpu-worker stats|run  (started by the lgp emit library)\n");
    return 2;
  }
  std::ios::sync_with_stdio(false);
  glslang::InitializeProcess();
  int rc = 0;
  try {
    Device dev(mode == "stats");
    std::cout << dev.hello().dump() << '\n' << std::flush;
    std::string line;
    while (std::getline(std::cin, line)) {
      if (line.empty()) continue;
      json reply;
      try {
        reply = serve(dev, mode == "stats", json::parse(line));
      } catch (const std::exception& e) {
        reply = {{"ok", false}, {"error", e.what()}};
      }
      std::cout << reply.dump(-1, ' ', false, json::error_handler_t::replace) << '\n' << std::flush;
    }
  } catch (const std::exception& e) {
    std::cout << json{{"ok", false}, {"error", e.what()}}.dump() << '\n' << std::flush;
    rc = 1;
  }
  glslang::FinalizeProcess();
  return rc;
}
