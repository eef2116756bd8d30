// Text from tables, configs and fronts that reaches messages and emitted code (issue 21):
// a control character in a column name or a data path is refused at every loader, with a
// message that names the field and does not quote the text.
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "lgp/config/config.hpp"
#include "lgp/core/table.hpp"
#include "lgp/core/text_check.hpp"
#include "lgp/io/result.hpp"

namespace lgp {
namespace {

namespace fs = std::filesystem;

const std::string kInject = "mu\n#include </etc/shadow>\nint pwn(){return 1;}\n//";

bool contains(const std::string& s, const std::string& what) {
  return s.find(what) != std::string::npos;
}

class UntrustedText : public ::testing::Test {
 protected:
  fs::path dir = fs::temp_directory_path() / ("lgp_untrusted_" + std::to_string(getpid()));
  void SetUp() override { fs::create_directories(dir); }
  void TearDown() override { fs::remove_all(dir); }
  fs::path write(const std::string& name, const std::string& text) {
    std::ofstream(dir / name, std::ios::binary) << text;
    return dir / name;
  }
  // The error names the field and the control character, and quotes none of the text.
  static void expectRefused(const Status& s, const std::string& field, const std::string& what) {
    ASSERT_FALSE(s.isOk()) << what << " was accepted";
    EXPECT_TRUE(contains(s.message(), field)) << what << ": " << s.message();
    EXPECT_TRUE(contains(s.message(), "control character (0x")) << what << ": " << s.message();
    EXPECT_FALSE(contains(s.message(), "pwn")) << what << ": " << s.message();
    EXPECT_FALSE(contains(s.message(), "\n")) << what << ": " << s.message();
  }
};

TEST_F(UntrustedText, ControlCharactersAreFoundAndNamedByCode) {
  EXPECT_FALSE(firstControlCharacter("mu r_2 \xC2\xB5").has_value());
  EXPECT_EQ(firstControlCharacter("ab\x7f"), 2u);
  EXPECT_EQ(checkNoControlCharacters("a\tb", "the name").message(),
            "the name: has a control character (0x09 at byte 2); names and paths must be "
            "printable");
}

TEST_F(UntrustedText, CsvHeaderWithAControlCharacterIsRefused) {
  for (const std::string& header : {std::string("x,a\tb,f"), std::string("x,a\x1b[2Jb,f")}) {
    auto t = readCsv(write("h.csv", header + "\n1,2,3\n"));
    ASSERT_FALSE(t.hasValue()) << header;
    expectRefused(t.status(), "h.csv: line 1 (header), column 2: the name", header);
  }
}

TEST_F(UntrustedText, JsonTableKeyWithAControlCharacterIsRefused) {
  nlohmann::json j = {{"columns", {{"x", {1, 2}}, {kInject, {3, 4}}}}};
  auto t = readJsonTable(write("t.json", j.dump()));
  ASSERT_FALSE(t.hasValue());
  expectRefused(t.status(), "t.json: /columns: the name of column", "JSON table key");
  // lgpd's inline tables go through the same parser.
  auto inline_table = parseJsonTable(j, "/data/table");
  ASSERT_FALSE(inline_table.hasValue());
  expectRefused(inline_table.status(), "/data/table: /columns", "inline table key");
  // A table built in memory (a scene, a test) is checked by validate().
  Table mem;
  mem.input_names = {"x"};
  mem.output_names = {"f\r"};
  mem.inputs = {{1, 2}};
  mem.outputs = {{3, 4}};
  expectRefused(mem.validate(), "a column name", "Table::validate");
}

TEST_F(UntrustedText, ConfigNamesAndPathsWithControlCharactersAreRefused) {
  const nlohmann::json base = {
      {"data", {{"path", "t.csv"}, {"inputs", {"x"}}, {"outputs", {"f"}}}}};
  ASSERT_TRUE(parseRunConfig(base, dir).hasValue()) << parseRunConfig(base, dir).error();
  for (const auto& [ptr, field] :
       {std::pair{"/data/path", "/data/path"}, std::pair{"/data/inputs/0", "/data/inputs/0"},
        std::pair{"/data/outputs/0", "/data/outputs/0"}}) {
    nlohmann::json cfg = base;
    cfg[nlohmann::json::json_pointer(ptr)] = kInject;
    auto c = parseRunConfig(cfg, dir);
    ASSERT_FALSE(c.hasValue()) << ptr;
    expectRefused(c.status(), field, ptr);
  }
}

TEST_F(UntrustedText, FrontWithControlCharactersIsRefused) {
  nlohmann::json front = {{"format", "lgp-front/1"},
                          {"table", {{"inputs", {"x", kInject}}, {"outputs", {"f"}}}},
                          {"members", nlohmann::json::array()}};
  auto f = readFrontJson(write("front.json", front.dump()));
  ASSERT_FALSE(f.hasValue());
  expectRefused(f.status(), "front.json: /table/inputs/1", "front input name");
  front["table"]["inputs"] = {"x", "y"};
  front["config"] = {{"data", {{"path", "/d/t.csv\n#define x 1"}}}};
  f = readFrontJson(write("front.json", front.dump()));
  ASSERT_FALSE(f.hasValue());
  EXPECT_TRUE(contains(f.error(), "front.json: /config/data/path")) << f.error();
  front["config"]["data"]["path"] = "/d/t.csv";
  EXPECT_TRUE(readFrontJson(write("front.json", front.dump())).hasValue());
}

}  // namespace
}  // namespace lgp
