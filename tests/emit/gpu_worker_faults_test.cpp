// The GPU backends against a worker gone wrong (hardening round 3): a fake lgp-gpu-worker (a
// shell script, through $LGP_GPU_WORKER) that never answers, never greets, answers garbage
// statistics or a reply longer than any request needs, and a driver manifest that is a device.
// No GPU and no Vulkan driver are needed. Each test uses its own driver (GPU family or mode):
// the worker pool remembers a failed driver for the whole process, as it should.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "../../emit/src/gpu_process.hpp"
#include "lgp/emit/emit.hpp"
#include "lgp/emit/gpu_cost.hpp"
#include "lgp/emit/vulkan_run.hpp"

namespace lgp::emit {
namespace {

namespace fs = std::filesystem;

class GpuWorkerFaults : public ::testing::Test {
 protected:
  fs::path dir =
      fs::temp_directory_path() / ("lgp_gpu_faults_" + std::to_string(getpid()) + "_" +
                                   ::testing::UnitTest::GetInstance()->current_test_info()->name());
  void SetUp() override {
    fs::create_directories(dir);
    std::ofstream(dir / "icd.json") << R"({"file_format_version": "1.0.0"})";
    ::setenv("LGP_RADV_ICD", (dir / "icd.json").c_str(), 1);
    ::setenv("LGP_LAVAPIPE_ICD", (dir / "icd.json").c_str(), 1);
    ::setenv("LGP_GPU_TIMEOUT_S", "1", 1);
    ::setenv("FAKE_WORKER_LOG", (dir / "requests.log").c_str(), 1);
  }
  void TearDown() override {
    for (const char* v : {"LGP_GPU_WORKER", "LGP_RADV_ICD", "LGP_LAVAPIPE_ICD", "LGP_GPU_TIMEOUT_S",
                          "FAKE_WORKER_LOG"})
      ::unsetenv(v);
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
  // A fake worker: `body` is shell run after the start is logged; each request it reads is
  // logged as one line of requests.log.
  void worker(const std::string& body) {
    const fs::path p = dir / "worker.sh";
    std::ofstream(p) << "#!/bin/sh\necho started >> \"$FAKE_WORKER_LOG.starts\"\n" << body;
    fs::permissions(p, fs::perms::owner_all);
    ::setenv("LGP_GPU_WORKER", p.c_str(), 1);
  }
  static constexpr const char* kGreet =
      "echo '{\"ok\": true, \"device\": \"fake\", \"driver\": \"fake\"}'\n";
  static constexpr const char* kLogRequest = "echo request >> \"$FAKE_WORKER_LOG\"\n";
  size_t lines(const fs::path& p) const {
    std::ifstream f(p);
    size_t n = 0;
    for (std::string l; std::getline(f, l);) ++n;
    return n;
  }
  size_t requests() const { return lines(dir / "requests.log"); }
  size_t starts() const { return lines(dir.string() + "/requests.log.starts"); }
};

bool has(const std::string& s, const std::string& what) {
  return s.find(what) != std::string::npos;
}

// Took 120 s per member, every time, silently: 480 s for a 4-member front, at every lgpd
// snapshot, and per candidate of measured_cost.in_search.
TEST_F(GpuWorkerFaults, AHungDriverCostsOneTimeoutThenFailsAtOnceWithAWarning) {
  worker(std::string(kGreet) + "while IFS= read -r line; do " + kLogRequest + "done\n");
  ::testing::internal::CaptureStderr();
  auto a = shaderIsaStats(GpuFamily::Rdna2, Language::Glsl, "void main() { /* a */ }");
  auto b = shaderIsaStats(GpuFamily::Rdna2, Language::Glsl, "void main() { /* b */ }");
  auto c = shaderIsaStats(GpuFamily::Rdna2, Language::Hlsl, "void main() { /* c */ }");
  const std::string err = ::testing::internal::GetCapturedStderr();
  ASSERT_FALSE(a);
  EXPECT_TRUE(has(a.error(), "no reply within 1 s")) << a.error();
  for (const auto* r : {&b, &c}) {
    ASSERT_FALSE(*r);
    EXPECT_TRUE(has(r->error(), "no reply within 1 s")) << r->error();
    EXPECT_TRUE(has(r->error(), "not tried again")) << r->error();
  }
  EXPECT_EQ(requests(), 1u) << "the hung driver was asked again";
  // Told once, on stderr.
  EXPECT_TRUE(has(err, "warning: lgp-gpu-worker (stats:navi21): no reply within 1 s")) << err;
  EXPECT_EQ(err.find("warning", err.find("warning") + 1), std::string::npos) << err;
}

// Cost 180 s at the first use, then a retry for every later one.
TEST_F(GpuWorkerFaults, AWorkerThatNeverGreetsIsNotStartedAgain) {
  worker("exec sleep 30\n");
  ::testing::internal::CaptureStderr();
  const auto first = isaBackendStatus(GpuFamily::Rdna3);
  const auto second = isaBackendStatus(GpuFamily::Rdna3);
  const std::string err = ::testing::internal::GetCapturedStderr();
  EXPECT_FALSE(first.available);
  EXPECT_TRUE(has(first.detail, "no greeting within 1 s")) << first.detail;
  EXPECT_FALSE(second.available);
  EXPECT_TRUE(has(second.detail, "not tried again")) << second.detail;
  EXPECT_EQ(starts(), 1u);
  EXPECT_TRUE(has(err, "warning: lgp-gpu-worker (stats:gfx1100): no greeting within 1 s")) << err;
}

// Statistics that are not counts were recorded as 0 instructions.
TEST_F(GpuWorkerFaults, GarbageStatisticsAreAnErrorNotZeroInstructions) {
  worker(std::string(kGreet) +
         "read -r l; echo '{\"ok\": true, \"stats\": {\"Instructions\": \"lots\"}}'\n"
         "read -r l; echo '{\"ok\": true, \"stats\": {\"VGPRs\": 8}}'\n"
         "read -r l; echo '{\"ok\": true, \"stats\": {\"Instructions\": -3}}'\n"
         "read -r l; echo '{\"ok\": true}'\n"
         "read -r l; echo '{\"ok\": true, \"stats\": {\"Instructions\": 28, \"VGPRs\": 8}}'\n"
         "read -r l\n");
  const std::vector<std::string> want = {
      "statistic \"Instructions\" is not a count (got \"lots\")", "lack \"Instructions\"",
      "statistic \"Instructions\" is not a count (got -3)", "a reply without statistics"};
  for (size_t i = 0; i < want.size(); ++i) {
    auto s = shaderIsaStats(GpuFamily::Gcn5, Language::Glsl, "// " + std::to_string(i));
    ASSERT_FALSE(s) << i << ": " << s->instructions;
    EXPECT_TRUE(has(s.error(), want[i])) << s.error();
  }
  auto ok = shaderIsaStats(GpuFamily::Gcn5, Language::Glsl, "// good");
  ASSERT_TRUE(ok) << ok.error();
  EXPECT_EQ(ok->instructions, 28);
  EXPECT_EQ(ok->vgprs, 8);
  EXPECT_EQ(ok->latency, 0);  // not reported by this driver
}

// A 1 GiB line from the worker was buffered whole before it was parsed.
TEST_F(GpuWorkerFaults, AReplyLongerThanTheRequestNeedsIsCutOff) {
  // Greets, then answers the run request with an endless line.
  worker(std::string(kGreet) + "read -r l; yes 0, | tr -d '\\n'\n");
  Table t;
  t.input_names = {"x"};
  t.output_names = {"y"};
  t.inputs = {{0.5, 0.25}};
  t.outputs = {{0.0, 0.0}};
  EmitInput in = emitInputForTable(Program{}, t);
  in.program.code = {Instr{Op::Add, {inputOperand(0), inputOperand(0)}}};
  in.program.outputs = {0};
  auto e = emitProgram(in, Language::Glsl, EmitOptions{});
  ASSERT_TRUE(e) << e.error();
  auto r = runEmitted(*e, Language::Glsl, Precision::Float, t);
  ASSERT_FALSE(r);
  EXPECT_TRUE(has(r.error(), "a reply line longer than")) << r.error();
}

// Was reported as "no such file".
TEST_F(GpuWorkerFaults, AManifestThatIsADeviceIsNamedAsOne) {
  ::setenv("LGP_RADV_ICD", "/dev/zero", 1);
  auto icd = detail::vulkanIcd("radeon_icd");
  ASSERT_FALSE(icd);
  EXPECT_TRUE(has(icd.error(), "LGP_RADV_ICD=/dev/zero: not a regular file")) << icd.error();
  ::setenv("LGP_RADV_ICD", dir.c_str(), 1);
  icd = detail::vulkanIcd("radeon_icd");
  ASSERT_FALSE(icd);
  EXPECT_TRUE(has(icd.error(), "a directory")) << icd.error();
  ::setenv("LGP_RADV_ICD", (dir / "none.json").c_str(), 1);
  icd = detail::vulkanIcd("radeon_icd");
  ASSERT_FALSE(icd);
  EXPECT_TRUE(has(icd.error(), "no such file")) << icd.error();
}

}  // namespace
}  // namespace lgp::emit
