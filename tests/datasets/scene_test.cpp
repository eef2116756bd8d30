#include "lgp/datasets/scene.hpp"

#include "lgp/datasets/edges.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>

using namespace lgp::datasets;
using nlohmann::json;

namespace {
json dfgScene() {
  return json::parse(R"({
    "material": {"visibility": "smith-correlated", "fresnel": {"model": "schlick", "f90": 1},
                 "roughness": "perceptual"},
    "light": {"type": "environment"},
    "outputs": ["A", "B"],
    "grid": {"mu": {"count": 64, "range": [0.015625, 1], "spacing": "edge"},
             "r": {"count": 64, "range": [0, 1], "spacing": "edge"}},
    "accuracy": {"abs_error": 1e-6}
  })");
}
std::string errorOf(const json& j) {
  auto s = parseScene(j, "s.json");
  return s ? std::string() : s.error();
}
}  // namespace

TEST(Scene, ParsesTheDfgExample) {
  auto s = parseScene(dfgScene());
  ASSERT_TRUE(s) << s.error();
  EXPECT_EQ(s->inputNames(), (std::vector<std::string>{"mu", "r"}));
  EXPECT_EQ(s->rows(), 64u * 64u);
  EXPECT_DOUBLE_EQ(s->grid[0].values.front(), 1.0 / 64);
  EXPECT_DOUBLE_EQ(s->grid[0].values.back(), 1.0);
  EXPECT_DOUBLE_EQ(s->grid[1].values.front(), 0.0);
  EXPECT_DOUBLE_EQ(s->grid[1].values.back(), 1.0);
  EXPECT_TRUE(s->needs(Effect::Fresnel));
  EXPECT_FALSE(s->needs(Effect::Diffuse));
  EXPECT_FALSE(s->needs(Effect::Normalization));
  // canonical JSON round-trips
  auto again = parseScene(toJson(*s));
  ASSERT_TRUE(again) << again.error();
  EXPECT_EQ(toJson(*again), toJson(*s));
}

TEST(Scene, GridSpacings) {
  json j = dfgScene();
  j["grid"]["mu"] = {{"count", 4}, {"range", {0, 1}}, {"spacing", "cell"}};
  j["grid"]["r"] = {{"values", {0.25, 0.5}}};
  auto s = parseScene(j);
  ASSERT_TRUE(s) << s.error();
  EXPECT_EQ(s->grid[0].values, (std::vector<double>{0.125, 0.375, 0.625, 0.875}));
  EXPECT_EQ(s->grid[1].values, (std::vector<double>{0.25, 0.5}));
  auto again = parseScene(toJson(*s));  // canonical form of explicit values round-trips
  ASSERT_TRUE(again) << again.error();
  EXPECT_EQ(toJson(*again), toJson(*s));
}

TEST(Scene, ErrorsNameThePathAndReason) {
  json j = dfgScene();
  j["grid"]["mu"]["count"] = 0;
  EXPECT_NE(errorOf(j).find("s.json: /grid/mu/count: must be an integer"), std::string::npos)
      << errorOf(j);
  j = dfgScene();
  j["material"]["visibility"] = "smith";
  EXPECT_NE(errorOf(j).find("/material/visibility: must be one of"), std::string::npos);
  j = dfgScene();
  j["outputs"] = {"A", "Q"};
  EXPECT_NE(errorOf(j).find("/outputs/1: unknown output \"Q\""), std::string::npos);
  j = dfgScene();
  j["grid"].erase("r");
  EXPECT_NE(errorOf(j).find("/grid/r: missing"), std::string::npos);
  j = dfgScene();
  j["grid"]["mu"]["range"] = {-0.5, 1};
  EXPECT_NE(errorOf(j).find("/grid/mu: value -0.5 outside the domain"), std::string::npos);
  j = dfgScene();
  j["material"]["fresnel"] = "none";
  EXPECT_NE(errorOf(j).find("/material/fresnel"), std::string::npos);
  j = dfgScene();
  j["outputs"] = {"N"};
  EXPECT_NE(errorOf(j).find("/light/type: output \"N\" needs a sphere light"), std::string::npos);
  j = dfgScene();
  j["extra"] = 1;
  EXPECT_NE(errorOf(j).find("/extra: unknown key"), std::string::npos);
  j = dfgScene();
  j["accuracy"]["abs_error"] = "tiny";
  EXPECT_NE(errorOf(j).find("/accuracy/abs_error: must be a finite number"), std::string::npos);
  EXPECT_NE(errorOf(json::array()).find("s.json: /: must be an object"), std::string::npos);
  auto missing = loadScene("/nonexistent/scene.json");
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.error().find("/nonexistent/scene.json: cannot open"), std::string::npos);
}

TEST(Scene, SphereLight) {
  json j = json::parse(R"({
    "light": {"type": "sphere", "size": "tan_half_theta_s", "range": [0, 0.5]},
    "outputs": ["N"],
    "grid": {"r": {"count": 3, "range": [0.1, 1]}, "tan_half_theta_s": {"count": 5}}
  })");
  auto s = parseScene(j);
  ASSERT_TRUE(s) << s.error();
  EXPECT_EQ(s->inputNames(), (std::vector<std::string>{"r", "tan_half_theta_s"}));
  EXPECT_DOUBLE_EQ(s->grid[1].values.back(), 0.5);
  EXPECT_TRUE(s->needs(Effect::Normalization));
  EXPECT_FALSE(s->needs(Effect::Fresnel));
  j["outputs"] = {"N", "A"};
  EXPECT_NE(errorOf(j).find("/outputs: \"N\" has inputs"), std::string::npos);
}

TEST(Scene, MalformedScenesAreErrorsNotCrashes) {
  const char* cases[] = {
      R"({"outputs": "A"})",
      R"({"outputs": ["A"], "grid": {"mu": 5, "r": {"count": 2}}})",
      R"({"outputs": ["A"], "grid": {"mu": {"count": 2.5}, "r": {"count": 2}}})",
      R"({"outputs": ["A"], "grid": {"mu": {"count": 2, "spacing": 3}, "r": {"count": 2}}})",
      R"({"outputs": ["A"], "grid": {"mu": {"count": 2, "range": [1]}, "r": {"count": 2}}})",
      R"({"outputs": ["A"], "grid": {"mu": {"values": ["x"]}, "r": {"count": 2}}})",
      R"({"outputs": ["A"], "grid": {"mu": {"values": []}, "r": {"count": 2}}})",
      R"({"outputs": ["A"], "grid": {"mu": {"count": 2, "range": [1, 0]}, "r": {"count": 2}}})",
      R"({"outputs": ["N"], "light": {"type": 5}, "grid": {}})",
      R"({"outputs": ["N"], "light": {"type": "sphere", "range": [0, 2]}, "grid": {}})",
      R"({"outputs": ["N"], "light": {"type": "sphere", "softmin_s": 3}, "grid": {}})",
      R"({"outputs": ["N"], "light": {"type": "sphere", "incidence": "averaged"}, "grid": {}})",
      R"({"outputs": ["E"], "light": {"type": "environment", "range": [0, 1]}, "grid": {}})",
      R"({"outputs": ["A"], "material": {"fresnel": {"model": "schlick", "f90": 2}}, "grid": {}})",
      R"({"outputs": ["A"], "material": 3, "grid": {}})",
      R"({"outputs": ["A", "A"], "grid": {}})",
      R"({"outputs": [], "grid": {}})",
      R"({"outputs": ["A"], "grid": {"mu": {"count": 2}, "r": {"count": 2}, "x": {}}})",
      R"({"format": 2, "outputs": ["A"]})",
      R"({"outputs": ["A"], "grid": {"mu": {"count": 2}, "r": {"count": 2}},
          "accuracy": {"integrator": "monte-carlo"}})",
      R"({"outputs": ["A"], "grid": {"mu": {"count": 2}, "r": {"count": 2}},
          "accuracy": {"abs_error": 0}})",
      "null",
      "[]",
      "3"};
  for (const char* c : cases) {
    auto s = parseScene(json::parse(c), "s.json");
    EXPECT_FALSE(s) << c;
    if (!s) {
      EXPECT_EQ(s.error().rfind("s.json: /", 0), 0u) << s.error();
    }
  }
}

// The grid is bounded before anything of its size is allocated (a 100000 x 100000 grid
// ended in a bare std::bad_alloc), and scene files are read with the checked reader.
TEST(Scene, GridSizeIsLimited) {
  json j = dfgScene();
  j["grid"]["mu"] = {{"count", 100000}};
  j["grid"]["r"] = {{"count", 100000}};
  EXPECT_EQ(errorOf(j),
            "s.json: /grid: 100000 x 100000 = 10000000000 cells, more than the "
            "limit of 16777216 (kMaxSceneCells)");
  j["grid"]["mu"] = {{"count", 4096}};
  j["grid"]["r"] = {{"count", 4096}};  // exactly the limit
  auto s = parseScene(j, "s.json");
  ASSERT_TRUE(s) << s.error();
  EXPECT_EQ(s->rows(), kMaxSceneCells);
  j["grid"]["r"] = {{"count", 4097}};
  EXPECT_NE(errorOf(j).find("/grid: 4096 x 4097"), std::string::npos) << errorOf(j);
}

TEST(Scene, SceneFilesAreReadWithTheCheckedParser) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / ("lgp_scene_" + std::to_string(::getpid()));
  fs::create_directories(dir / "a_dir.json");
  auto d = loadScene(dir / "a_dir.json");
  ASSERT_FALSE(d);
  EXPECT_EQ(d.error(), (dir / "a_dir.json").string() + ": is a directory");
  std::ofstream(dir / "dup.json") << R"({"outputs": ["A"], "outputs": ["B"]})";
  auto dup = loadScene(dir / "dup.json");
  ASSERT_FALSE(dup);
  EXPECT_NE(dup.error().find("/outputs: key appears twice"), std::string::npos) << dup.error();
  std::ofstream(dir / "deep.json") << std::string(100000, '[') << std::string(100000, ']');
  auto deep = loadScene(dir / "deep.json");
  ASSERT_FALSE(deep);
  EXPECT_NE(deep.error().find("nested deeper than"), std::string::npos) << deep.error();
  fs::remove_all(dir);
}

// A table's inputs are the union of its outputs' (mu, r, eta, in that order); the outputs over
// eta need the exact dielectric Fresnel, the 3-D albedo needs eta >= 1, and E_sheen is refused
// where it is infinite.
TEST(Scene, InputsFollowTheOutputs) {
  auto s = parseScene(json::parse(R"({
    "material": {"fresnel": "dielectric"},
    "outputs": ["E_dielectric", "F_avg"],
    "grid": {"mu": {"count": 4}, "r": {"count": 3}, "eta": {"count": 2}}})"));
  ASSERT_TRUE(s) << s.error();
  EXPECT_EQ(s->inputNames(), (std::vector<std::string>{"mu", "r", "eta"}));
  EXPECT_EQ(s->rows(), 24u);
  EXPECT_EQ(s->grid[2].values, (std::vector<double>{1.0, 3.0}));  // eta's default range
  EXPECT_TRUE(s->needs(Effect::Dielectric));
  EXPECT_FALSE(s->needs(Effect::Specular));
  // canonical form names the transmission convention, and round-trips
  EXPECT_EQ(toJson(*s)["material"]["transmission"], "flux");
  auto again = parseScene(toJson(*s));
  ASSERT_TRUE(again) << again.error();
  EXPECT_EQ(toJson(*again), toJson(*s));

  auto f = parseScene(json::parse(R"({"material": {"fresnel": "dielectric"}, "outputs": ["F_avg"],
                                      "grid": {"eta": {"values": [0.5, 1, 2]}}})"));
  ASSERT_TRUE(f) << f.error();
  EXPECT_EQ(f->inputNames(), (std::vector<std::string>{"eta"}));

  auto d = parseScene(json::parse(R"({"outputs": ["E_sheen", "E_burley", "E_oren_nayar"],
                                      "grid": {"mu": {"count": 3, "range": [0.1, 1]},
                                               "r": {"count": 3}}})"));
  ASSERT_TRUE(d) << d.error();
  EXPECT_TRUE(d->needs(Effect::Sheen));
  EXPECT_TRUE(d->needs(Effect::DiffuseAlbedo));
  EXPECT_FALSE(d->needs(Effect::Specular));
  // an older scene keeps its canonical form (no transmission key): its cache key is unchanged
  EXPECT_FALSE(toJson(*parseScene(dfgScene()))["material"].contains("transmission"));
}

TEST(Scene, NewEffectsNameTheirRequirements) {
  EXPECT_NE(errorOf(json::parse(R"({"outputs": ["E_refl"],
      "grid": {"mu": {"count": 2}, "r": {"count": 2}, "eta": {"count": 2}}})"))
                .find("s.json: /material/fresnel: outputs over eta use the exact dielectric "
                      "Fresnel; they need \"dielectric\""),
            std::string::npos);
  EXPECT_NE(errorOf(json::parse(R"({"material": {"fresnel": "dielectric"}, "outputs": ["E_trans"],
      "grid": {"mu": {"count": 2}, "r": {"count": 2}, "eta": {"values": [0.8, 1.5]}}})"))
                .find("/grid/eta: E_refl, E_trans and E_dielectric are defined for eta >= 1"),
            std::string::npos);
  EXPECT_NE(
      errorOf(json::parse(R"({"material": {"fresnel": "dielectric"}, "outputs": ["F_avg"],
      "grid": {"eta": {"values": [0.1]}}})"))
          .find("/grid/eta: value 0.10000000000000001 outside the domain [0.20000000000000001, 5]"),
      std::string::npos);
  EXPECT_NE(errorOf(json::parse(R"({"outputs": ["E_sheen"],
      "grid": {"mu": {"count": 3}, "r": {"count": 3}}})"))
                .find("s.json: /grid: E_sheen diverges at mu = 0 with alpha = 0"),
            std::string::npos);
  EXPECT_NE(errorOf(json::parse(R"({"material": {"transmission": "energy"}, "outputs": ["E"],
      "grid": {"mu": {"count": 2}, "r": {"count": 2}}})"))
                .find("/material/transmission: must be one of \"flux\", \"radiance\""),
            std::string::npos);
  EXPECT_NE(errorOf(json::parse(R"({"material": {"fresnel": "dielectric"}, "outputs": ["A"],
      "grid": {"mu": {"count": 2}, "r": {"count": 2}}})"))
                .find("/material/fresnel: outputs \"A\"/\"B\" are the Fresnel split"),
            std::string::npos);
  // the grid names exactly the union of the outputs' inputs
  EXPECT_NE(errorOf(json::parse(R"({"material": {"fresnel": "dielectric"}, "outputs": ["F_avg"],
      "grid": {"mu": {"count": 2}, "eta": {"count": 2}}})"))
                .find("/grid/mu: not an input of the requested outputs (inputs: eta)"),
            std::string::npos);
}

// The declared domain adds edge values only where it reaches beyond the grid: the DFG grid
// starts at mu = 1/64 (n.v 1e-4 lies beyond) and spans r over [0, 1]; edgeScene refuses a
// domain that adds nothing, with the reason.
TEST(Scene, DomainBeyondGridIsWhereEdgeValuesExist) {
  auto s = parseScene(dfgScene());
  ASSERT_TRUE(s) << s.error();
  EXPECT_TRUE(domainBeyondGrid(*s, {{"mu", {1e-4, 1}}}));
  EXPECT_FALSE(domainBeyondGrid(*s, {{"r", {0, 1}}}));
  EXPECT_FALSE(domainBeyondGrid(*s, {{"mu", {0.1, 0.9}}}));
  EXPECT_FALSE(domainBeyondGrid(*s, {{"eta", {1, 3}}}));
  EXPECT_FALSE(domainBeyondGrid(*s, {{"mu", {1, 1e-4}}}));
  EXPECT_TRUE(edgeScene(*s, {{"mu", {1e-4, 1}}, {"r", {0, 1}}}, "s.json"));
  auto none = edgeScene(*s, {{"r", {0, 1}}}, "s.json");
  ASSERT_FALSE(none);
  EXPECT_NE(none.error().find("the declared domain adds no value to the grid"), std::string::npos)
      << none.error();
}
