#include "lgp/datasets/generate.hpp"

#include <gtest/gtest.h>
#include <omp.h>

#include <atomic>
#include <cmath>
#include <functional>
#include <fstream>
#include <sstream>

using namespace lgp::datasets;
using lgp::RawTable;
using lgp::Table;
using nlohmann::json;
namespace fs = std::filesystem;

namespace {
Scene scene(const std::string& text) {
  auto s = parseScene(json::parse(text), "test");
  EXPECT_TRUE(s) << s.error();
  return *s;
}
// mu in {1, 0.5, 0.2}, r = sqrt(alpha) for alpha in {1, 0.25, 0.5}
const char* kCheck = R"({
  "material": {"fresnel": {"model": "schlick", "f90": 1}},
  "outputs": ["A", "B", "E"],
  "grid": {"mu": {"values": [1, 0.5, 0.2]}, "r": {"values": [1, 0.5, 0.7071067811865476]}},
  "accuracy": {"abs_error": 1e-7}
})";
double at(const GeneratedTable& g, const std::string& out, double x0, double x1) {
  const Table& t = g.table;
  for (size_t k = 0; k < t.output_names.size(); ++k)
    if (t.output_names[k] == out)
      for (size_t row = 0; row < t.rows(); ++row)
        if (std::abs(t.inputs[0][row] - x0) < 1e-12 && std::abs(t.inputs[1][row] - x1) < 1e-12)
          return t.outputs[k][row];
  ADD_FAILURE() << "no " << out << " at " << x0 << ", " << x1;
  return NAN;
}
fs::path tempDir(const std::string& name) {
  fs::path d = fs::temp_directory_path() /
               ("lgp_datasets_test_" + name + "_" +
                std::to_string(::testing::UnitTest::GetInstance()->random_seed()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}
}  // namespace

TEST(Generate, CheckValuesAndMetadata) {
  auto g = generate(scene(kCheck));
  ASSERT_TRUE(g) << g.error();
  EXPECT_NEAR(at(*g, "E", 1.0, 1.0), 1.0 - std::log(2.0), 1e-7);  // TABLES: 0.30686
  EXPECT_NEAR(at(*g, "E", 0.5, 1.0), 0.45069, 5e-6);
  EXPECT_NEAR(at(*g, "E", 0.5, 0.5), 0.85726, 5e-6);
  EXPECT_NEAR(at(*g, "E", 0.2, 0.7071067811865476), 0.78993, 5e-6);
  EXPECT_LE(g->max_error, 1e-7);
  EXPECT_TRUE(g->converged);
  const json& m = g->table.meta;
  for (const char* k : {"definition", "scene", "grid", "integrator", "sample_counts",
                        "max_estimated_error", "generator_version"})
    EXPECT_TRUE(m.contains(k)) << k;
  EXPECT_EQ(m["generator_version"], kGeneratorVersion);
  EXPECT_EQ(m["integrator"]["method"], "adaptive");
  EXPECT_GT(m["sample_counts"]["total"].get<uint64_t>(), 0u);
  // lgp-table/1 JSON
  const json j = toTableJson(*g);
  EXPECT_EQ(j["format"], "lgp-table/1");
  EXPECT_EQ(j["inputs"], json({"mu", "r"}));
  EXPECT_EQ(j["outputs"], json({"A", "B", "E"}));
  EXPECT_EQ(j["columns"]["A"].size(), 9u);
  EXPECT_EQ(j["errors"]["B"].size(), 9u);
  auto back = fromTableJson(j, "mem");
  ASSERT_TRUE(back) << back.error();
  EXPECT_EQ(back->table.outputs, g->table.outputs);
  EXPECT_EQ(back->errors, g->errors);
  RawTable raw = toRawTable(*g);
  EXPECT_EQ(raw.names, (std::vector<std::string>{"mu", "r", "A", "B", "E"}));
  EXPECT_EQ(raw.default_outputs, (std::vector<std::string>{"A", "B", "E"}));
}

TEST(Generate, SimulatesOnlyWhatTheSceneAsksFor) {
  const std::string grid = R"("grid": {"mu": {"count": 3}, "r": {"count": 3}})";
  {  // E with Fresnel off: no Fresnel split, no ZH, no normalization
    auto g =
        generate(scene(R"({"material": {"fresnel": "none"}, "outputs": ["E"], )" + grid + "}"));
    ASSERT_TRUE(g) << g.error();
    EXPECT_GT(g->counters.specular, 0u);
    EXPECT_EQ(g->counters.fresnel, 0u);
    EXPECT_EQ(g->counters.diffuse, 0u);
    EXPECT_EQ(g->counters.rep_point, 0u);
  }
  {  // the DFG split: Fresnel, but no ZH or normalization
    auto g = generate(scene(R"({"outputs": ["A", "B"], )" + grid + "}"));
    ASSERT_TRUE(g) << g.error();
    EXPECT_EQ(g->counters.fresnel, g->counters.specular);
    EXPECT_EQ(g->counters.diffuse, 0u);
    EXPECT_EQ(g->counters.rep_point, 0u);
  }
  {  // ZH only: no specular work at all
    auto g = generate(scene(R"({"outputs": ["ZH0", "ZH1_over_ZH0"], )" + grid + "}"));
    ASSERT_TRUE(g) << g.error();
    EXPECT_EQ(g->counters.specular, 0u);
    EXPECT_EQ(g->counters.fresnel, 0u);
    EXPECT_GT(g->counters.diffuse, 0u);
    EXPECT_EQ(g->counters.rep_point, 0u);
  }
  {  // normalization: sphere light only
    auto g = generate(scene(R"({"light": {"type": "sphere", "range": [0, 0.5]},
                                "outputs": ["N"],
                                "grid": {"r": {"count": 2, "range": [0.5, 1]},
                                         "theta_s": {"count": 3}}})"));
    ASSERT_TRUE(g) << g.error();
    EXPECT_GT(g->counters.rep_point, 0u);
    EXPECT_EQ(g->counters.fresnel, 0u);
    EXPECT_EQ(g->counters.diffuse, 0u);
    EXPECT_EQ(at(*g, "N", 0.5, 0.0), 1.0);
  }
}

TEST(Generate, HardCaseGridIsFiniteAndBounded) {
  auto g = generate(scene(R"({
    "outputs": ["A", "B", "E", "one_minus_E", "E_avg", "ZH0", "ZH2_over_ZH0", "beta"],
    "grid": {"mu": {"values": [0, 1e-7, 0.015625, 0.5, 1]}, "r": {"values": [0, 1e-4, 0.5, 1]}},
    "accuracy": {"abs_error": 1e-5}
  })"));
  ASSERT_TRUE(g) << g.error();
  for (size_t k = 0; k < g->table.outputs.size(); ++k)
    for (size_t row = 0; row < g->table.rows(); ++row) {
      ASSERT_TRUE(std::isfinite(g->table.outputs[k][row]));
      ASSERT_TRUE(std::isfinite(g->errors[k][row]));
    }
  for (double mu : {0.0, 0.015625, 0.5, 1.0}) {
    EXPECT_EQ(at(*g, "E", mu, 0.0), 1.0);  // mirror limit
    for (double r : {0.0, 0.5, 1.0}) {
      EXPECT_GE(at(*g, "A", mu, r), 0.0);
      EXPECT_LE(at(*g, "A", mu, r), 1.0);
      EXPECT_GE(at(*g, "B", mu, r), 0.0);
      EXPECT_LE(at(*g, "B", mu, r), 1.0);
    }
  }
  EXPECT_NEAR(at(*g, "E", 1.0, 1.0), 1.0 - std::log(2.0), 1e-5);
  EXPECT_NEAR(at(*g, "one_minus_E", 1.0, 1.0), std::log(2.0), 1e-5);
  EXPECT_EQ(at(*g, "E_avg", 0.5, 0.0), 1.0);
}

TEST(Generate, CacheHitsAndRejectsCorruptFiles) {
  const fs::path dir = tempDir("cache");
  const Scene s = scene(R"({"outputs": ["E"], "grid": {"mu": {"count": 4}, "r": {"count": 4}}})");
  auto first = generateCached(s, dir);
  ASSERT_TRUE(first) << first.error();
  EXPECT_FALSE(first->hit);
  ASSERT_TRUE(fs::exists(first->file));
  auto second = generateCached(s, dir);
  ASSERT_TRUE(second) << second.error();
  EXPECT_TRUE(second->hit);
  EXPECT_EQ(second->table.table.outputs, first->table.table.outputs);
  EXPECT_EQ(second->table.errors, first->table.errors);
  // a different scene (or generator version) has a different key
  const Scene s2 = scene(R"({"outputs": ["E"], "grid": {"mu": {"count": 5}, "r": {"count": 4}}})");
  EXPECT_NE(cacheKey(s2), cacheKey(s));

  // flip one digit in the payload: detected by checksum, regenerated, never used
  std::string bytes;
  {
    std::ifstream in(first->file, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  std::string bad = bytes;
  const size_t pos = bad.find("0.", bad.find("\"E\""));
  ASSERT_NE(pos, std::string::npos);
  bad[pos + 3] = bad[pos + 3] == '7' ? '3' : '7';
  std::ofstream(first->file, std::ios::binary) << bad;
  auto third = generateCached(s, dir);
  ASSERT_TRUE(third) << third.error();
  EXPECT_FALSE(third->hit);
  EXPECT_NE(third->note.find("checksum mismatch"), std::string::npos) << third->note;
  EXPECT_EQ(third->table.table.outputs, first->table.table.outputs);
  EXPECT_TRUE(generateCached(s, dir)->hit);  // rewritten

  // truncated file
  std::ofstream(first->file, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  auto fourth = generateCached(s, dir);
  ASSERT_TRUE(fourth) << fourth.error();
  EXPECT_FALSE(fourth->hit);
  EXPECT_NE(fourth->note.find("truncated"), std::string::npos) << fourth->note;
  // garbage header
  std::ofstream(first->file, std::ios::binary) << "garbage";
  auto fifth = generateCached(s, dir);
  ASSERT_TRUE(fifth) << fifth.error();
  EXPECT_FALSE(fifth->hit);
  fs::remove_all(dir);
}

namespace {
// Rewrites a cache entry's payload with `edit` and a recomputed checksum: what anyone who can
// write the file can do.
void forgeEntry(const fs::path& file, const std::function<void(json&)>& edit) {
  std::ifstream in(file, std::ios::binary);
  std::string bytes(std::istreambuf_iterator<char>(in), {});
  json j = json::parse(bytes.substr(bytes.find('\n') + 1));
  edit(j);
  const std::string payload = j.dump();
  uint64_t h = 0xcbf29ce484222325ull;
  for (unsigned char c : payload) h = (h ^ c) * 0x100000001b3ull;
  char sum[17];
  std::snprintf(sum, sizeof sum, "%016llx", static_cast<unsigned long long>(h));
  std::ofstream(file, std::ios::binary | std::ios::trunc)
      << "lgp-cache/1 " << sum << " " << payload.size() << "\n" << payload;
}
}  // namespace

// Hardening round 4, F1: a checksum is no signature. An entry rewritten with a recomputed
// checksum (F_avg = 7 everywhere), or another scene's entry under this scene's key, was served
// as the scene's integral; now each is recognised, regenerated and rewritten.
TEST(Generate, CacheEntriesAreCheckedAgainstTheirScene) {
  const fs::path dir = tempDir("poison");
  fs::permissions(dir, fs::perms::owner_all, fs::perm_options::replace);
  const Scene s = scene(R"({"material": {"fresnel": {"model": "dielectric"}},
    "outputs": ["F_avg"], "grid": {"eta": {"count": 6, "range": [1, 2.5]}}})");
  auto first = generateCached(s, dir);
  ASSERT_TRUE(first) << first.error();
  const auto truth = first->table.table.outputs;
  forgeEntry(first->file, [](json& j) {
    for (auto& v : j["columns"]["F_avg"]) v = 7.0;
  });
  auto poisoned = generateCached(s, dir);
  ASSERT_TRUE(poisoned) << poisoned.error();
  EXPECT_FALSE(poisoned->hit);
  EXPECT_NE(poisoned->note.find("not this scene's table"), std::string::npos) << poisoned->note;
  EXPECT_EQ(poisoned->table.table.outputs, truth);
  EXPECT_TRUE(generateCached(s, dir)->hit);  // rewritten with the truth
  // One row poisoned among 6: the spot check recomputes every row of a table this small.
  forgeEntry(first->file, [](json& j) { j["columns"]["F_avg"][3] = 0.5; });
  EXPECT_FALSE(generateCached(s, dir)->hit);
  // Another scene's entry (more eta points) under this scene's key.
  const Scene other = scene(R"({"material": {"fresnel": {"model": "dielectric"}},
    "outputs": ["F_avg"], "grid": {"eta": {"count": 7, "range": [1, 2.5]}}})");
  auto o = generateCached(other, dir);
  ASSERT_TRUE(o) << o.error();
  fs::copy_file(o->file, first->file, fs::copy_options::overwrite_existing);
  auto swapped = generateCached(s, dir);
  ASSERT_TRUE(swapped) << swapped.error();
  EXPECT_FALSE(swapped->hit);
  EXPECT_NE(swapped->note.find("made for another scene"), std::string::npos) << swapped->note;
  // Its recorded scene edited to match, the columns still the other grid's.
  forgeEntry(first->file, [&](json& j) {
    j["columns"] = toTableJson(o->table)["columns"];
    j["errors"] = toTableJson(o->table)["errors"];
  });
  auto grid = generateCached(s, dir);
  ASSERT_TRUE(grid) << grid.error();
  EXPECT_FALSE(grid->hit);
  EXPECT_NE(grid->note.find("columns are not the scene's"), std::string::npos) << grid->note;
  EXPECT_EQ(grid->table.table.outputs, truth);
  // refresh: regenerated whatever the entry holds.
  auto refreshed = generateCached(s, dir, {}, true);
  ASSERT_TRUE(refreshed) << refreshed.error();
  EXPECT_FALSE(refreshed->hit);
  fs::remove_all(dir);
}

// A cache others can write is neither read nor written: an entry writable by the group, or a
// directory writable by others without the sticky bit.
TEST(Generate, CacheOthersCanWriteIsNotUsed) {
  const fs::path dir = tempDir("shared");
  fs::permissions(dir, fs::perms::owner_all, fs::perm_options::replace);
  const Scene s = scene(R"({"outputs": ["E"], "grid": {"mu": {"count": 3}, "r": {"count": 3}}})");
  auto first = generateCached(s, dir);
  ASSERT_TRUE(first) << first.error();
  fs::permissions(first->file, fs::perms::group_write, fs::perm_options::add);
  auto g = generateCached(s, dir);
  ASSERT_TRUE(g) << g.error();
  EXPECT_FALSE(g->hit);
  EXPECT_NE(g->note.find("writable by other users"), std::string::npos) << g->note;
  fs::remove(first->file);
  fs::permissions(dir, fs::perms::others_write, fs::perm_options::add);
  auto w = generateCached(s, dir);
  ASSERT_TRUE(w) << w.error();
  EXPECT_FALSE(fs::exists(first->file));  // not written there
  EXPECT_NE(w->note.find("directory is writable by other users"), std::string::npos) << w->note;
  fs::permissions(dir, fs::perms::sticky_bit, fs::perm_options::add);  // as /tmp: trusted
  ASSERT_TRUE(generateCached(s, dir));
  EXPECT_TRUE(generateCached(s, dir)->hit);
  fs::remove_all(dir);
}

// Hardening round 4, F2: generation polls GenerateOptions::stop and ends with
// kGenerationStopped instead of running every row.
TEST(Generate, StopEndsGeneration) {
  const Scene s = scene(R"({"outputs": ["E"], "grid": {"mu": {"count": 64}, "r": {"count": 64}}})");
  std::atomic<int> polls{0};
  GenerateOptions o;
  o.threads = 2;
  o.stop = [&] { return ++polls > 10; };
  auto g = generate(s, o);
  ASSERT_FALSE(g);
  EXPECT_EQ(g.error(), kGenerationStopped);
  EXPECT_LT(polls.load(), 64 * 64);  // polled at most once per row after the request
  auto c = generateCached(s, tempDir("stop"), o);
  ASSERT_FALSE(c);
  EXPECT_EQ(c.error(), kGenerationStopped);
}

// Hardening round 4, F11: threads are capped at the cores this process may use (3000 under an
// address-space limit ended the process).
TEST(Generate, ThreadsAreCappedAtTheCores) {
  const Scene s = scene(R"({"outputs": ["E"], "grid": {"mu": {"count": 8}, "r": {"count": 8}}})");
  std::atomic<int> widest{0};
  GenerateOptions o;
  o.threads = 3000;
  o.stop = [&] {
    int w = widest.load();
    while (omp_get_num_threads() > w && !widest.compare_exchange_weak(w, omp_get_num_threads())) {
    }
    return false;
  };
  auto g = generate(s, o);
  ASSERT_TRUE(g) << g.error();
  EXPECT_GE(widest.load(), 1);
  EXPECT_LE(widest.load(), omp_get_num_procs());
}

// Hardening round 4, F9: a non-finite value names its point as the grid has it (5e-324, not
// 0.000000).
TEST(Generate, NonFiniteValueNamesItsPoint) {
  const Scene s = scene(R"({"material": {"roughness": "linear"}, "outputs": ["E_sheen"],
    "grid": {"mu": {"values": [5e-324, 0.5]}, "r": {"values": [5e-324, 0.5]}}})");
  auto g = generate(s);
  ASSERT_FALSE(g);
  EXPECT_NE(g.error().find("E_sheen at mu=5e-324, r=5e-324 (row 1)"), std::string::npos)
      << g.error();
}

TEST(Generate, PlotsAndCsv) {
  const fs::path dir = tempDir("plots");
  auto g = generate(scene(R"({"outputs": ["A", "B"], "grid": {"mu": {"count": 5},
                              "r": {"count": 4}}, "accuracy": {"abs_error": 1e-4}})"));
  ASSERT_TRUE(g) << g.error();
  auto files = writePlots(*g, dir, "dfg");
  ASSERT_TRUE(files) << files.error();
  EXPECT_EQ(files->size(), 4u);  // heatmap + slices per output
  for (const auto& f : *files) {
    std::ifstream in(f);
    std::string head;
    std::getline(in, head);
    EXPECT_EQ(head.rfind("<svg", 0), 0u) << f;
  }
  ASSERT_TRUE(writeTableCsv(*g, dir / "t.csv"));
  std::ifstream in(dir / "t.csv");
  std::string header;
  std::getline(in, header);
  EXPECT_EQ(header, "mu,r,A,B");
  int lines = 0;
  for (std::string l; std::getline(in, l);) ++lines;
  EXPECT_EQ(lines, 20);
  fs::remove_all(dir);
}

TEST(Generate, IntegratorsAgreeOnATable) {
  const std::string base = R"("outputs": ["A", "B"],
      "grid": {"mu": {"count": 4, "range": [0.1, 1]}, "r": {"count": 3, "range": [0.3, 1]}})";
  auto a = generate(scene("{" + base + R"(, "accuracy": {"integrator": "adaptive"}})"));
  auto q = generate(scene("{" + base + R"(, "accuracy": {"integrator": "qmc",
                                            "abs_error": 0.01, "qmc_points": 8192}})"));
  ASSERT_TRUE(a && q);
  for (size_t k = 0; k < 2; ++k)
    for (size_t row = 0; row < a->table.rows(); ++row)
      EXPECT_NEAR(a->table.outputs[k][row], q->table.outputs[k][row],
                  q->errors[k][row] + a->errors[k][row] + 1e-9);
  EXPECT_EQ(q->table.meta["integrator"]["method"], "qmc");
}

TEST(Generate, NewEffectsOnlyWhatIsAskedFor) {
  {  // sheen: its own counter, no GGX
    auto g = generate(scene(R"({"outputs": ["E_sheen"], "grid": {"mu": {"count": 3,
                                "range": [0.2, 1]}, "r": {"count": 2, "range": [0.5, 1]}}})"));
    ASSERT_TRUE(g) << g.error();
    EXPECT_GT(g->counters.sheen, 0u);
    EXPECT_EQ(g->counters.specular + g->counters.dielectric + g->counters.diffuse, 0u);
    EXPECT_EQ(g->table.meta["sample_counts"]["sheen"], g->counters.sheen);
  }
  {  // diffuse albedo: closed forms, no integral
    auto g = generate(scene(R"({"outputs": ["E_burley", "E_oren_nayar"],
                                "grid": {"mu": {"count": 3}, "r": {"count": 2}}})"));
    ASSERT_TRUE(g) << g.error();
    EXPECT_EQ(g->counters.specular + g->counters.sheen + g->counters.dielectric, 0u);
    EXPECT_LE(g->max_error, 1e-13);  // the rounding floor, 64 eps |E|
  }
  {  // F and F_avg only: no microfacet integral
    auto g = generate(scene(R"({"material": {"fresnel": "dielectric"},
                                "outputs": ["F_dielectric", "F_avg"],
                                "grid": {"mu": {"count": 3}, "eta": {"values": [1, 1.5]}}})"));
    ASSERT_TRUE(g) << g.error();
    EXPECT_EQ(g->counters.specular, 0u);
    EXPECT_EQ(at(*g, "F_avg", 0.0, 1.0), 0.0);
    EXPECT_NEAR(at(*g, "F_dielectric", 1.0, 1.5), 0.04, 1e-15);
    EXPECT_EQ(at(*g, "F_avg", 0.0, 1.5), at(*g, "F_avg", 1.0, 1.5));  // repeated along mu
  }
  {  // older tables keep their metadata: no sheen or dielectric counts
    auto g =
        generate(scene(R"({"outputs": ["E"], "grid": {"mu": {"count": 2}, "r": {"count": 2}}})"));
    ASSERT_TRUE(g) << g.error();
    EXPECT_FALSE(g->table.meta["sample_counts"].contains("sheen"));
    EXPECT_FALSE(g->table.meta["sample_counts"].contains("dielectric"));
  }
}

// Three inputs: the first fastest, E_dielectric the sum of its lobes, and the limits where
// they are closed forms (alpha = 0: F and 1 - F; eta = 1: no reflection).
TEST(Generate, ThreeInputDielectricTable) {
  auto g = generate(scene(R"({"material": {"fresnel": "dielectric"},
      "outputs": ["E_refl", "E_trans", "E_dielectric", "F_dielectric"],
      "grid": {"mu": {"values": [0.25, 1]}, "r": {"values": [0, 0.5]},
               "eta": {"values": [1, 1.5, 2]}}, "accuracy": {"abs_error": 1e-6}})"));
  ASSERT_TRUE(g) << g.error();
  const lgp::Table& t = g->table;
  ASSERT_EQ(t.rows(), 12u);
  EXPECT_EQ(t.input_names, (std::vector<std::string>{"mu", "r", "eta"}));
  EXPECT_EQ(g->table.meta["grid"]["row_order"],
            "row = i_mu + 2 * i_r + 2 * 2 * i_eta (first input fastest)");
  for (size_t row = 0; row < t.rows(); ++row) {
    EXPECT_EQ(t.inputs[0][row], (row % 2 == 0 ? 0.25 : 1.0));
    EXPECT_EQ(t.inputs[2][row], (std::vector<double>{1, 1.5, 2})[row / 4]);
    EXPECT_NEAR(t.outputs[2][row], t.outputs[0][row] + t.outputs[1][row], 1e-15);
    if (t.inputs[1][row] == 0.0) {
      EXPECT_EQ(t.outputs[0][row], t.outputs[3][row]);  // E_refl = F
      EXPECT_NEAR(t.outputs[2][row], 1.0, 1e-15);       // flux: nothing lost
    }
    if (t.inputs[2][row] == 1.0) {
      EXPECT_EQ(t.outputs[0][row], 0.0);
    }
  }
  EXPECT_LE(g->max_error, 1e-6);
  EXPECT_GT(g->counters.dielectric, 0u);
  const fs::path dir = tempDir("plots3");
  auto files = writePlots(*g, dir, "glass");
  ASSERT_TRUE(files) << files.error();
  EXPECT_EQ(files->size(), 4u * 3u * 2u);  // per output, at each eta: heatmap + slices
  fs::remove_all(dir);
}
