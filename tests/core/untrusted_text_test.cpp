// Text from tables, configs and fronts that reaches messages, emitted code and spreadsheets
// (issue 21): a control character in a column name or a data path is refused at every
// loader, with a message that names the field and does not quote the text; an error about a
// data file names its path, line and column but quotes none of it (it may be a symlink to a
// secret); CSV is read and written as RFC 4180 says, with decimal numbers only, and a front
// CSV never starts a cell with a formula.
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "lgp/config/config.hpp"
#include "lgp/config/json_reader.hpp"
#include "lgp/core/csv.hpp"
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

TEST_F(UntrustedText, QuotedHeaderNameWithANewlineIsRefused) {
  auto t = readCsv(write("q.csv", "x,\"" + kInject + "\",f\n1,2,3\n"));
  ASSERT_FALSE(t.hasValue());
  expectRefused(t.status(), "q.csv: line 1 (header), column 2: the name", "quoted newline");
}

// --- errors quote nothing of the file -----------------------------------------------------

TEST_F(UntrustedText, ErrorsAboutADataFileNameLineAndColumnButQuoteNothing) {
  const std::string secret = "root:SECRET-7f3a9c:19000:0:99999:7:::";
  const fs::path shadow = write("shadow", secret + "\ndaemon:SECRET-b2:19000::::::\n");
  fs::create_symlink(shadow, dir / "data.csv");
  fs::create_symlink(shadow, dir / "data.json");
  for (const fs::path& p : {dir / "data.csv", dir / "data.json"}) {
    auto t = readTableFile(p);
    ASSERT_FALSE(t.hasValue()) << p;
    EXPECT_TRUE(contains(t.error(), p.string() + ": ")) << t.error();
    EXPECT_TRUE(contains(t.error(), "line ")) << t.error();
    EXPECT_TRUE(contains(t.error(), "column ")) << t.error();
    EXPECT_FALSE(contains(t.error(), "SECRET")) << t.error();
    EXPECT_FALSE(contains(t.error(), "root")) << t.error();
    EXPECT_FALSE(contains(t.error(), "last read")) << t.error();
  }
  auto csv = readCsv(dir / "data.csv");
  EXPECT_EQ(csv.error(), (dir / "data.csv").string() + ": line 2, column 1: not a decimal number");
  // A CSV whose header is fine and whose cell is not a number: no name, no value.
  auto cell = readCsv(write("cell.csv", "x,f\n1,2\n3,SECRET\n"));
  ASSERT_FALSE(cell.hasValue());
  EXPECT_EQ(cell.error(), (dir / "cell.csv").string() + ": line 3, column 2: not a decimal number");
  auto dup = readCsv(write("dup.csv", "SECRET,SECRET\n1,2\n"));
  ASSERT_FALSE(dup.hasValue());
  EXPECT_EQ(dup.error(),
            (dir / "dup.csv").string() + ": line 1 (header), column 2: the same name as column 1");
  // The JSON reader's messages: line and column, not the text.
  for (const std::string& text :
       {std::string("SECRET"), std::string("{\"a\": SECRET}"), std::string("{\"a\": \"SECRET\n\"}"),
        std::string("[1e999, \"SECRET\"]")}) {
    auto j = parseJson(text);
    ASSERT_FALSE(j.hasValue()) << text;
    EXPECT_FALSE(contains(j.error(), "SECRET")) << j.error();
    EXPECT_FALSE(contains(j.error(), "1e999")) << j.error();
  }
  EXPECT_TRUE(contains(parseJson("{\n \"a\": SECRET}").error(), "line 2, column "))
      << parseJson("{\n \"a\": SECRET}").error();
}

// --- RFC 4180 and numbers -----------------------------------------------------------------

TEST_F(UntrustedText, QuotedCsvFieldsFollowRfc4180) {
  auto t = readCsv(write("q.csv",
                         "\"x\", \"y, z\" ,\"a \"\"q\"\"\"\r\n"
                         "\"1.5\",2,3\r\n"
                         "# a comment\n"
                         "  4 , \"5\",\"6\"\n"));
  ASSERT_TRUE(t.hasValue()) << t.error();
  EXPECT_EQ(t->names, (std::vector<std::string>{"x", "y, z", "a \"q\""}));
  EXPECT_EQ(t->columns[0], (std::vector<double>{1.5, 4}));
  EXPECT_EQ(t->columns[1], (std::vector<double>{2, 5}));
  // "1,5" is one field (not a number), not two.
  auto one = readCsv(write("one.csv", "x,f\n\"1,5\",2\n"));
  ASSERT_FALSE(one.hasValue());
  EXPECT_TRUE(contains(one.error(), "line 2, column 1: not a decimal number")) << one.error();
  auto open = readCsv(write("open.csv", "x,f\n1,2\n3,\"4\n5,6\n"));
  ASSERT_FALSE(open.hasValue());
  EXPECT_TRUE(contains(open.error(), "line 3, column 2: a quoted field is not closed"))
      << open.error();
  auto stray = readCsv(write("stray.csv", "x,f\n1,2\"3\n"));
  ASSERT_FALSE(stray.hasValue());
  EXPECT_TRUE(contains(stray.error(), "line 2, column 2: a double quote inside an unquoted field"))
      << stray.error();
  auto after = readCsv(write("after.csv", "x,f\n1,\"2\"3\n"));
  ASSERT_FALSE(after.hasValue());
  EXPECT_TRUE(contains(after.error(), "line 2, column 2: text after the closing quote"))
      << after.error();
}

TEST_F(UntrustedText, HexInfAndNanAreRefusedWithLineAndColumn) {
  const char* const accepted = nullptr;
  const std::vector<std::pair<const char*, const char*>> cases = {
      {"0x10", "a hexadecimal number"},
      {"-0X1p3", "a hexadecimal number"},
      {"inf", "inf or nan"},
      {"-Infinity", "inf or nan"},
      {"nan", "inf or nan"},
      {"NAN(1)", "inf or nan"},
      {"1e999", "outside the range of double"},
      {"", "empty cell"},
      {"1.", accepted},
      {".5e-3", accepted},
      {"+2E+2", accepted},
      {"1e", "not a decimal number"},
      {"1 2", "not a decimal number"}};
  for (const auto& [cell, why] : cases) {
    auto t = readCsv(write("n.csv", std::string("x,f\n1,2\n3,") + cell + "\n"));
    if (!why) {
      EXPECT_TRUE(t.hasValue()) << cell << ": " << (t ? "" : t.error());
      continue;
    }
    ASSERT_FALSE(t.hasValue()) << cell;
    EXPECT_TRUE(contains(t.error(), "n.csv: line 3, column 2: " + std::string(why))) << t.error();
  }
}

TEST_F(UntrustedText, CsvOutputQuotesFieldsAndNeutralisesFormulas) {
  EXPECT_EQ(csvField("plain"), "plain");
  EXPECT_EQ(csvField("a,b"), "\"a,b\"");
  EXPECT_EQ(csvField("say \"hi\""), "\"say \"\"hi\"\"\"");
  EXPECT_EQ(csvField("two\nlines"), "\"two\nlines\"");
  EXPECT_EQ(csvSpreadsheetField("=HYPERLINK(1)"), "'=HYPERLINK(1)");
  EXPECT_EQ(csvSpreadsheetField("@SUM(A1)"), "'@SUM(A1)");
  EXPECT_EQ(csvSpreadsheetField("+x*y"), "'+x*y");
  EXPECT_EQ(csvSpreadsheetField("-x, y"), "\"'-x, y\"");
  EXPECT_EQ(csvSpreadsheetField("-0.5"), "-0.5");
  EXPECT_EQ(csvSpreadsheetField("+1e-3"), "+1e-3");
  EXPECT_EQ(csvSpreadsheetField("x*y - 1"), "x*y - 1");
  // A front CSV with an output named like a formula and an expression starting with '-'.
  nlohmann::json front = {{"members",
                           {{{"index", 0},
                             {"error", -0.5},
                             {"cost", 3},
                             {"formula", "=HYPERLINK(\"http://x\")"},
                             {"outputs",
                              {{{"name", "=HYPERLINK(1)"},
                                {"expression", "-x*y, 2"},
                                {"float32", {{"rmse", 0.1}}}}}}}}}};
  ASSERT_TRUE(writeFrontCsv(front, dir / "front.csv").isOk());
  std::ifstream in(dir / "front.csv");
  std::string header, row;
  std::getline(in, header);
  std::getline(in, row);
  EXPECT_TRUE(contains(row, "0,'=HYPERLINK(1),-0.5,3,")) << row;
  EXPECT_TRUE(contains(row, ",\"'-x*y, 2\",\"'=HYPERLINK(\"\"http://x\"\")\"")) << row;
  // Read back as CSV: the same number of fields as the header.
  const std::string text = header + "\n" + row + "\n";
  CsvReader r(text, "front.csv");
  std::vector<std::string> h, f;
  ASSERT_TRUE(*r.next(h));
  ASSERT_TRUE(*r.next(f));
  EXPECT_EQ(h.size(), f.size());
  // A table CSV with such names reads back with the same names.
  Table t;
  t.input_names = {"a,b", "q\"x"};
  t.output_names = {"f"};
  t.inputs = {{1, 2}, {3, 4}};
  t.outputs = {{5, 6}};
  ASSERT_TRUE(writeCsv(t, dir / "t.csv").isOk());
  auto back = readCsv(dir / "t.csv");
  ASSERT_TRUE(back.hasValue()) << back.error();
  EXPECT_EQ(back->names, (std::vector<std::string>{"a,b", "q\"x", "f"}));
}

}  // namespace
}  // namespace lgp
