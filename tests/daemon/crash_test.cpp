// Durability: kill -9 lgpd after a run's first checkpoint, restart it on the same data dir,
// and the run resumes from the checkpoint, finishes to the same budget, and loses nothing.
// The search is deterministic (RNG streams derive from seed, generation and index, and the
// checkpoint holds population, archive and counters), so the resumed run's front must equal
// an uninterrupted run's with the same seed. A graceful stop (SIGTERM) resumes the same way.
#include "daemon_harness.hpp"

namespace lgpd_test {
namespace {

// The comparable part of a front: objectives and expressions of every member.
json frontSignature(const json& front) {
  json sig = json::array();
  for (const auto& m : front["members"]) {
    json outs = json::array();
    for (const auto& o : m["outputs"]) outs.push_back(o["expression"]);
    sig.push_back({m["error"], m["cost"], m["discontinuity"], outs});
  }
  return sig;
}

// Budget long enough that the run is still going after its first checkpoint (a few
// seconds), small enough to finish quickly.
constexpr int kGenerations = 6000;

const std::vector<std::string> kFlags = {
    "--checkpoint-interval", "0.05", "--progress-interval", "0.02", "--front-interval", "0.05"};

struct Interrupted {
  std::string id;
  int checkpoint_before = -1;  // the checkpoint generation seen just before the kill
};

// Starts lgpd on `state`, submits `cfg`, waits for the first checkpoint, then kills lgpd
// with SIGKILL (hard) or SIGTERM (graceful).
::testing::AssertionResult interrupt(const fs::path& state, const json& cfg, bool hard,
                                     Interrupted* out) {
  Daemon d(state);
  if (auto ok = d.start(kFlags); !ok) return ok;
  out->id = d.submit(cfg);
  if (out->id.empty()) return ::testing::AssertionFailure() << "submit failed";
  json r = d.waitFor(out->id, [](const json& run) {
    const std::string s = run.value("status", "");
    return run["checkpoint"].is_object() || (s != "running" && s != "queued");
  });
  if (r.value("status", "") != "running" || !r["checkpoint"].is_object())
    return ::testing::AssertionFailure()
           << "the run ended before its first checkpoint; raise kGenerations\n"
           << r.dump();
  out->checkpoint_before = r["checkpoint"]["generation"].get<int>();
  if (hard) {
    d.kill9();
  } else if (d.stop() != 0) {
    return ::testing::AssertionFailure() << "lgpd did not stop cleanly\n" << d.log();
  }
  return ::testing::AssertionSuccess();
}

class CrashTest : public ::testing::TestWithParam<bool> {};

// No loss and monotone progress: the run resumes once, at or after the checkpoint seen
// before the kill, never goes back, and finishes to the full budget with a final front.
TEST_P(CrashTest, ResumesFromCheckpointAndFinishesToBudget) {
  const bool hard_kill = GetParam();
  TempDir tmp(hard_kill ? "crash" : "sigterm");
  fs::path table = writeGridTable(tmp.path(), 16);
  fs::path state = tmp.path() / "state";
  Interrupted in;
  ASSERT_TRUE(interrupt(state, runConfig(table, kGenerations, 48, 11), hard_kill, &in));

  Daemon d(state);
  ASSERT_TRUE(d.start(kFlags));
  json before = d.get("/api/v1/runs/" + in.id).j();
  ASSERT_TRUE(before.is_object());
  EXPECT_NE(before.value("status", ""), "failed") << before.dump();
  json done = d.waitDone(in.id, 180);
  ASSERT_EQ(done.value("status", ""), "finished") << done.dump() << d.log();
  EXPECT_EQ(done["generation"], kGenerations) << "finished to the same budget";
  EXPECT_EQ(done["resumes"], 1);
  EXPECT_EQ(done["stop_reason"], "generations");

  json hist = d.get("/api/v1/runs/" + in.id + "/history").j()["history"];
  int resumed_at = -1, last_ckpt = -1, resumes = 0;
  bool monotone = true;
  for (const auto& h : hist) {
    const std::string ev = h["event"];
    const int g = h["generation"];
    if (ev == "resumed") {
      ++resumes;
      resumed_at = g;
    }
    if (ev == "checkpoint") {
      monotone = monotone && g >= last_ckpt;
      last_ckpt = g;
    }
  }
  EXPECT_EQ(resumes, 1);
  EXPECT_GE(resumed_at, in.checkpoint_before);
  EXPECT_LT(resumed_at, kGenerations);
  EXPECT_TRUE(monotone) << hist.dump();
  EXPECT_EQ(hist.back()["event"], "finished");

  Reply f = d.get("/api/v1/runs/" + in.id + "/front");
  ASSERT_EQ(f.status, 200);
  EXPECT_GT(f.j()["members"].size(), 0u);
  EXPECT_TRUE(f.j()["lgpd"]["final"].get<bool>());
  EXPECT_EQ(d.stop(), 0);
}

INSTANTIATE_TEST_SUITE_P(Daemon, CrashTest, ::testing::Values(true, false),
                         [](const ::testing::TestParamInfo<bool>& p) {
                           return p.param ? "Kill9" : "Sigterm";
                         });

// Deterministic mode: the front of a run killed with -9 and resumed equals the front of an
// uninterrupted run with the same seed (search.hpp: checkpoint()/restore() continue the run
// exactly; no wall-time budget).
TEST(CrashDeterminism, ResumedFrontEqualsUninterruptedFront) {
  TempDir tmp("determinism");
  fs::path table = writeGridTable(tmp.path(), 16);
  fs::path state = tmp.path() / "state";
  const json cfg = runConfig(table, kGenerations, 48, 11);
  Interrupted in;
  ASSERT_TRUE(interrupt(state, cfg, true, &in));

  Daemon d(state);
  ASSERT_TRUE(d.start(kFlags));
  json done = d.waitDone(in.id, 180);
  ASSERT_EQ(done.value("status", ""), "finished") << d.log();
  ASSERT_EQ(done["resumes"], 1);
  std::string ref = d.submit(cfg);
  json rdone = d.waitDone(ref, 180);
  ASSERT_EQ(rdone.value("status", ""), "finished");
  EXPECT_EQ(rdone["resumes"], 0);
  json front = d.get("/api/v1/runs/" + in.id + "/front").j();
  json rfront = d.get("/api/v1/runs/" + ref + "/front").j();
  EXPECT_EQ(done["evaluations"], rdone["evaluations"]);
  EXPECT_EQ(frontSignature(front), frontSignature(rfront))
      << "the resumed front differs from the uninterrupted one (checkpoint at generation "
      << in.checkpoint_before << ")";
  EXPECT_EQ(d.stop(), 0);
}

}  // namespace
}  // namespace lgpd_test
