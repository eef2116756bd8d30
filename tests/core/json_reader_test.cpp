// The JSON path naming shared by the validators (lgp/config/json_reader.hpp): JSON Pointers
// with RFC 6901 escapes, the root shown as "/", unknown keys in the object's order.
#include "lgp/config/json_reader.hpp"

#include <gtest/gtest.h>

#include "lgp/config/config.hpp"

using nlohmann::json;

TEST(JsonPath, NamesMembersAndElements) {
  EXPECT_EQ(lgp::jsonPath("", "search"), "/search");
  EXPECT_EQ(lgp::jsonPath("/search", "islands"), "/search/islands");
  EXPECT_EQ(lgp::jsonPath("/references", size_t{3}), "/references/3");
  EXPECT_EQ(lgp::jsonPath("", ""), "/");  // the member named "" of the document
  // '~' and '/' are escaped, so "a/b" is one key, not two levels.
  EXPECT_EQ(lgp::jsonPath("/data/transforms", "a/b~c"), "/data/transforms/a~1b~0c");
  EXPECT_EQ(lgp::jsonPath("", "~1"), "/~01");
}

TEST(JsonPath, ErrorShowsTheRootAsSlash) {
  EXPECT_EQ(lgp::jsonError("", "must be an object"), "/: must be an object");
  EXPECT_EQ(lgp::jsonError("/eval/block_size", "must be a multiple of 16"),
            "/eval/block_size: must be a multiple of 16");
}

TEST(JsonObjectReader, ReportsTheFirstKeyNobodyAskedFor) {
  const json j = {{"b", 1}, {"a", 2}, {"c", 3}, {"x/y", 4}};
  lgp::JsonObjectReader o(j, "/obj");
  EXPECT_TRUE(o.isObject());
  EXPECT_EQ(o.path("k"), "/obj/k");
  EXPECT_EQ(o.unknownKey(), "/obj/a");  // nlohmann orders keys; so does the report
  EXPECT_TRUE(o.has("a"));
  EXPECT_FALSE(o.has("missing"));  // asking for an absent key is fine
  EXPECT_EQ(o.at("b"), 1);
  EXPECT_EQ(o.unknownKey(), "/obj/c");
  o.allow({"c"});
  EXPECT_EQ(o.unknownKey(), "/obj/x~1y");
  const std::vector<std::string> rest = {"x/y"};
  o.allowAll(rest);
  EXPECT_EQ(o.unknownKey(), std::nullopt);
}

TEST(JsonObjectReader, NotAnObject) {
  const json j = json::array({1, 2});
  lgp::JsonObjectReader o(j, "");
  EXPECT_FALSE(o.isObject());
  EXPECT_FALSE(o.has("a"));
  EXPECT_EQ(o.unknownKey(), std::nullopt);
}

// The run config reports through the helper: unknown keys, nested paths, escapes.
TEST(JsonObjectReader, RunConfigMessages) {
  const auto err = [](const char* text) {
    auto c = lgp::parseRunConfig(json::parse(text), ".");
    return c ? std::string("ok") : c.error();
  };
  const std::string data = R"("data": {"path": "t.csv", "outputs": ["A"]})";
  EXPECT_EQ(err("[]"), "/: must be an object (got array)");
  EXPECT_EQ(err(("{" + data + R"(, "a/b": 1})").c_str()), "/a~1b: unknown key");
  EXPECT_EQ(err(("{" + data + R"(, "search": {"islands": {"what": 1}}})").c_str()),
            "/search/islands/what: unknown key");
  EXPECT_EQ(err(("{" + data + R"(, "program": {"ops": ["add", 3]}})").c_str()),
            "/program/ops/1: must be an operator name");
  EXPECT_EQ(err(R"({"data": {"path": "t.csv", "outputs": ["A"], "transforms": {"B/C": "log"}},
                    "search": {"generations": 1}})"),
            "/data/transforms/B~1C: not one of data.outputs");
}

// parseJson: the checks nlohmann does not make, each with a message that says where.
TEST(ParseJson, Limits) {
  const auto err = [](const std::string& text, lgp::JsonLimits lim = {}) {
    auto j = lgp::parseJson(text, lim);
    return j ? std::string("ok") : j.error();
  };
  EXPECT_EQ(err(R"({"a": [1, {"b": "[[[{{{"}]})"), "ok");  // brackets in strings do not count
  EXPECT_EQ(err(std::string(64, '[') + std::string(64, ']')), "ok");
  EXPECT_EQ(err(std::string(65, '[') + std::string(65, ']')),
            "JSON nested deeper than 64 levels (at byte 64)");
  // 100k deep, the document that crashed lgpd: refused before any tree is built.
  std::string deep;
  for (int i = 0; i < 100000; ++i) deep += R"({"a":)";
  EXPECT_EQ(err(deep), "JSON nested deeper than 64 levels (at byte 320)");
  EXPECT_EQ(err(R"({"s": "\"[[[[\\"})", {.max_depth = 1}), "ok");  // escapes end strings right
  EXPECT_EQ(err("[1,2,3]", {.max_depth = 64, .max_bytes = 6}),
            "JSON text of 7 bytes exceeds the limit of 6");
  EXPECT_EQ(err(R"({"data": {"path": "a", "path": "b"}})"),
            "/data/path: key appears twice in one object");
  EXPECT_EQ(err(R"([{"x": 1}, {"x": 1, "y": [0, {"k": 1, "k": 2}]}])"),
            "/1/y/1/k: key appears twice in one object");
  EXPECT_EQ(err(R"([{"x": 1}, {"x": 2}])"), "ok");  // same key in sibling objects is fine
  EXPECT_NE(err(R"({"w": 1e999})").find("number out of range"), std::string::npos);
  EXPECT_NE(err("[" + std::string(400, '9') + "]").find("number out of range"), std::string::npos);
  EXPECT_EQ(err("[1e-310, 1e308]"), "ok");  // subnormal and large but finite
  EXPECT_NE(err("{\"a\": 1,}").find("invalid JSON"), std::string::npos);
  EXPECT_NE(err("").find("invalid JSON"), std::string::npos);
}

TEST(ParseJson, RunConfigTextUsesIt) {
  auto c = lgp::parseRunConfigText(R"({"data": {"path": "a.csv", "path": "b.csv"}})", "cfg.json");
  ASSERT_FALSE(c);
  EXPECT_EQ(c.error(), "cfg.json: /data/path: key appears twice in one object");
}
