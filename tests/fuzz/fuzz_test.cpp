// Fuzz driver: deterministic mutation fuzzing of every parser that takes outside input (run
// configs, scenes, CSV and JSON tables, reference formulas) in-process, of `lgp run` as a
// child process, and of HTTP bodies and raw requests against a live lgpd. Seeds are fixed, so
// a failure reproduces; LGP_FUZZ_SCALE multiplies the case counts (scripts/fuzz-nightly.sh).
//
// The oracle is the one every input must meet: no crash, no exception escaping a parser, no
// case running past a deadline (a watchdog aborts and prints the input), exit status 0-2 from
// the CLI, a status below 500 from lgpd, and a daemon that still answers afterwards. Inputs
// that crashed or hung lgp and lgpd before are replayed as regression cases with the outcome
// they must have. Each test prints its counts: inputs tried, crashes, hangs, wrong codes.
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/time.h>

#include <atomic>
#include <mutex>
#include <random>

#include "../daemon/daemon_harness.hpp"
#include "../daemon/store_rows.hpp"
#include "lgp/config/config.hpp"
#include "lgp/config/json_reader.hpp"
#include "lgp/core/table.hpp"
#include "lgp/datasets/scene.hpp"
#include "lgp/emit/parser.hpp"
#include "lgp/search/exhaustive.hpp"

namespace {

using namespace lgpd_test;

int scaled(int base) {
  const char* s = std::getenv("LGP_FUZZ_SCALE");
  const double f = s ? std::atof(s) : 1.0;
  return std::max(1, static_cast<int>(base * (f > 0 ? f : 1.0)));
}

// Aborts the process when one case runs past its deadline, naming the target, the case and
// the start of the input: a hang must not pass as a slow test.
class Watchdog {
 public:
  Watchdog() : thread_([this] { loop(); }) {}
  ~Watchdog() {
    stop_ = true;
    thread_.join();
  }
  void arm(const std::string& what, const std::string& input, double seconds) {
    std::lock_guard<std::mutex> lock(mu_);
    what_ = what;
    input_ = input.substr(0, 300);
    deadline_ = std::chrono::steady_clock::now() +
                std::chrono::milliseconds(static_cast<int64_t>(seconds * 1000));
    armed_ = true;
  }
  void disarm() {
    std::lock_guard<std::mutex> lock(mu_);
    armed_ = false;
  }

 private:
  void loop() {
    while (!stop_) {
      {
        std::lock_guard<std::mutex> lock(mu_);
        if (armed_ && std::chrono::steady_clock::now() > deadline_) {
          std::fprintf(stderr, "fuzz: HANG in %s; input starts: %s\n", what_.c_str(),
                       input_.c_str());
          std::abort();
        }
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
  }
  std::mutex mu_;
  std::string what_, input_;
  std::chrono::steady_clock::time_point deadline_;
  bool armed_ = false;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

// Sanitizer builds are several times slower; the deadline is generous and still far below a
// hang.
constexpr double kCaseDeadlineS = 30;

Watchdog& watchdog() {
  static Watchdog w;
  return w;
}

class Mutator {
 public:
  explicit Mutator(uint64_t seed) : rng_(seed) {}

  size_t below(size_t n) {
    return n == 0 ? 0 : std::uniform_int_distribution<size_t>(0, n - 1)(rng_);
  }
  bool chance(double p) { return std::uniform_real_distribution<double>(0, 1)(rng_) < p; }

  // Tokens that have broken parsers: structure, escapes, numbers at the edges of double and
  // float32, index overflow, deep prefixes.
  std::string token() {
    static const std::vector<std::string> k = {"{",
                                               "}",
                                               "[",
                                               "]",
                                               "\"",
                                               ":",
                                               ",",
                                               "\\",
                                               "\\u0000",
                                               "\\ud800",
                                               "null",
                                               "true",
                                               "-",
                                               "1e999",
                                               "-1e999",
                                               "1e-310",
                                               "1e39",
                                               "-1e39",
                                               "1e308",
                                               "NaN",
                                               "Infinity",
                                               "-0",
                                               "2147483648",
                                               "-2147483649",
                                               "18446744073709551616",
                                               "99999999999999999999999999999999999999999",
                                               "0x10",
                                               "1.",
                                               ".5",
                                               "+1",
                                               "\xEF\xBB\xBF",
                                               "\xff\xfe",
                                               "\n",
                                               "\r\n",
                                               "\t",
                                               " ",
                                               "x2147483648",
                                               "x-1",
                                               "c99999",
                                               "abs(",
                                               "(",
                                               ")",
                                               "mu",
                                               "r",
                                               "NoV",
                                               "A =",
                                               "B =",
                                               ";",
                                               "/",
                                               "*",
                                               "mad(",
                                               "min(",
                                               "sqrt(",
                                               "exp2(",
                                               "log2(",
                                               "0/0",
                                               "1/0",
                                               "select(",
                                               "saturate(",
                                               "#",
                                               ",,",
                                               "e",
                                               "E+",
                                               "%",
                                               "\x01",
                                               "\"path\":",
                                               "\"seed_references\": true",
                                               "\"references\": [",
                                               "\"count\": 100000"};
    return k[below(k.size())];
  }

  // One random JSON value, sometimes deep or huge.
  nlohmann::json value(int depth = 0) {
    switch (below(depth > 3 ? 9 : 11)) {
      case 0:
        return nullptr;
      case 1:
        return chance(0.5);
      case 2:
        return static_cast<int64_t>(rng_()) >> below(64);
      case 3:
        return -static_cast<double>(below(1000)) / 7.0;
      case 4: {
        static const double specials[] = {0.0,    -0.0,         1e308, -1e308, 1e-310, 1e39,
                                          3.4e38, 2147483648.0, 1e-45, 4096,   65536,  1e9};
        return specials[below(std::size(specials))];
      }
      case 5:
        return std::string(below(4) == 0 ? 5000 : below(12), 'a' + below(26));
      case 6:
        return token();
      case 7:
        return static_cast<int>(below(10)) - 2;
      case 8:
        return "";
      case 9: {
        nlohmann::json a = nlohmann::json::array();
        for (size_t i = below(4); i > 0; --i) a.push_back(value(depth + 1));
        return a;
      }
      default: {
        nlohmann::json o = nlohmann::json::object();
        for (size_t i = below(3); i > 0; --i) o[token()] = value(depth + 1);
        return o;
      }
    }
  }

  // Replaces, removes or adds one member somewhere in the tree.
  void mutateJson(nlohmann::json& j) {
    nlohmann::json* node = &j;
    for (int hops = static_cast<int>(below(5)); hops > 0; --hops) {
      if (node->is_object() && !node->empty()) {
        auto it = node->begin();
        std::advance(it, below(node->size()));
        node = &it.value();
      } else if (node->is_array() && !node->empty()) {
        node = &(*node)[below(node->size())];
      } else {
        break;
      }
    }
    const size_t what = below(4);
    if (what == 0 && node->is_object() && !node->empty()) {
      auto it = node->begin();
      std::advance(it, below(node->size()));
      node->erase(it);
    } else if (what == 1 && node->is_object()) {
      (*node)[chance(0.5) ? token() : "extra"] = value();
    } else if (what == 2 && node->is_array()) {
      node->push_back(value());
    } else {
      *node = value();
    }
  }

  // Byte-level damage: flips, tokens, deletions, duplications, truncation, deep nesting.
  void mutateText(std::string& s) {
    for (int n = 1 + static_cast<int>(below(4)); n > 0; --n) {
      const size_t at = below(s.size() + 1);
      switch (below(7)) {
        case 0:
          if (!s.empty()) s[below(s.size())] = static_cast<char>(below(256));
          break;
        case 1:
          s.insert(at, token());
          break;
        case 2:
          s.erase(at, below(16));
          break;
        case 3:
          s.insert(at, s.substr(below(s.size() + 1), below(64)));
          break;
        case 4:
          s.resize(below(s.size() + 1));
          break;
        case 5: {
          const size_t depth = chance(0.1) ? 100000 : below(400);
          const char* open[] = {"[", "{\"a\":", "(", "-", "abs("};
          s.insert(at, [&] {
            std::string deep;
            const char* o = open[below(std::size(open))];
            for (size_t i = 0; i < depth; ++i) deep += o;
            return deep;
          }());
          break;
        }
        default:
          s.insert(at, std::to_string(static_cast<int64_t>(rng_())));
          break;
      }
    }
  }

  // Half the cases damage the structure of a valid document, half its bytes.
  std::string mutateDocument(const nlohmann::json& seed) {
    nlohmann::json j = seed;
    for (int n = 1 + static_cast<int>(below(3)); n > 0; --n) mutateJson(j);
    // Tokens may be invalid UTF-8 strings; a dump would throw, so they become U+FFFD here and
    // the byte-level pass below puts raw bytes back.
    std::string s = j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
    if (chance(0.5)) mutateText(s);
    return s;
  }

 private:
  std::mt19937_64 rng_;
};

struct Counts {
  int tried = 0, accepted = 0, rejected = 0, threw = 0, crashes = 0, hangs = 0, wrong = 0;
  std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now();
  void print(const char* what) const {
    const double s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::printf(
        "fuzz %-14s %6d inputs: %d accepted, %d rejected, %d exceptions, %d crashes, %d hangs, "
        "%d wrong codes (%.1f s)\n",
        what, tried, accepted, rejected, threw, crashes, hangs, wrong, s);
  }
};

// Runs one parser case under the watchdog; an escaping exception is a failure.
template <class Fn>
void oneCase(Counts& c, const char* what, const std::string& input, Fn&& fn) {
  ++c.tried;
  watchdog().arm(what, input, kCaseDeadlineS);
  try {
    if (fn()) {
      ++c.accepted;
    } else {
      ++c.rejected;
    }
  } catch (const std::exception& e) {
    ++c.threw;
    ADD_FAILURE() << what << ": exception " << e.what() << "\ninput: " << input.substr(0, 300);
  }
  watchdog().disarm();
}

std::string repeat(const std::string& s, size_t n) {
  std::string out;
  out.reserve(s.size() * n);
  for (size_t i = 0; i < n; ++i) out += s;
  return out;
}

std::string nestedObject(size_t depth) {
  return repeat("{\"a\":", depth) + "1" + std::string(depth, '}');
}

nlohmann::json seedConfig(const fs::path& table) {
  nlohmann::json c = runConfig(table, 2, 16, 3);
  c["program"] = {{"max_length", 12}, {"constants", 4}, {"ops", {"add", "mul", "mad", "exp2"}}};
  c["references"] = {{{"name", "guess"}, {"expr", "f = x*y + 0.5*x - y/(1 + x)"}}};
  return c;
}

std::string configError(const std::string& text, const fs::path& dir) {
  auto c = lgp::parseRunConfigText(text, dir / "fuzz.json");
  return c ? "" : c.error();
}

class Fuzz : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::make_unique<TempDir>("fuzz");
    table_ = writeGridTable(dir_->path(), 6);
  }
  fs::path file(const std::string& name, const std::string& text) const {
    fs::path p = dir_->path() / name;
    std::ofstream(p, std::ios::binary) << text;
    return p;
  }
  std::unique_ptr<TempDir> dir_;
  fs::path table_;
};

TEST_F(Fuzz, RunConfigs) {
  Counts c;
  Mutator m(101);
  const nlohmann::json seed = seedConfig(table_);
  for (int i = 0, n = scaled(1500); i < n; ++i) {
    const std::string text = m.mutateDocument(seed);
    oneCase(c, "run config", text, [&] {
      auto cfg = lgp::parseRunConfigText(text, dir_->path() / "fuzz.json");
      if (cfg) {
        EXPECT_TRUE(cfg->validate()) << text.substr(0, 300);
      }
      return bool(cfg);
    });
  }
  c.print("run config");
  EXPECT_GT(c.accepted, 0);  // the mutations keep some configs valid, so validation is reached
  EXPECT_GT(c.rejected, 0);
}

TEST_F(Fuzz, RunConfigRegressions) {
  const fs::path d = dir_->path();
  const std::string data = "\"data\": {\"path\": \"" + table_.string() +
                           "\", \"inputs\": [\"x\", \"y\"], \"outputs\": [\"f\"]}";
  // 100k deep, as an object and as an array in a field: refused by depth, not by the stack.
  EXPECT_NE(configError(nestedObject(100000), d).find("nested deeper"), std::string::npos);
  EXPECT_NE(configError("{" + data + ", \"references\": " + std::string(100000, '[') +
                            std::string(100000, ']') + "}",
                        d)
                .find("nested deeper"),
            std::string::npos);
  EXPECT_NE(configError("{" + data + ", \"search\": {\"seed\": 1e999}}", d).find("out of range"),
            std::string::npos);
  EXPECT_NE(configError("{" + data + ", \"search\": {\"seed\": " + std::string(400, '9') + "}}", d)
                .find("out of range"),
            std::string::npos);
  EXPECT_NE(configError("{" + data + ", " + data + "}", d).find("appears twice"),
            std::string::npos);
  EXPECT_EQ(configError("{" + data + "}", d), "");
}

TEST_F(Fuzz, Scenes) {
  Counts c;
  Mutator m(202);
  std::ifstream in(fs::path(LGP_SOURCE_DIR) / "examples/scenes/dfg_64.json");
  std::stringstream ss;
  ss << in.rdbuf();
  auto seed = lgp::parseJson(ss.str());
  ASSERT_TRUE(seed) << seed.error();
  for (int i = 0, n = scaled(800); i < n; ++i) {
    const std::string text = m.mutateDocument(*seed);
    oneCase(c, "scene", text, [&] {
      // Both ways in: the file reader (parseJson inside) and the parsed-value entry point.
      const fs::path p = file("scene.json", text);
      auto s = lgp::datasets::loadScene(p);
      if (auto j = lgp::parseJson(text)) {
        auto t = lgp::datasets::parseScene(*j, "fuzz");
        EXPECT_EQ(bool(s), bool(t)) << text.substr(0, 300);
        if (t) {
          EXPECT_LE(t->rows(), lgp::datasets::kMaxSceneCells);
        }
      }
      return bool(s);
    });
  }
  c.print("scene");
  EXPECT_GT(c.accepted, 0);
  EXPECT_GT(c.rejected, 0);
  // The grid that ended in a bare std::bad_alloc.
  nlohmann::json big = *seed;
  big["grid"]["mu"]["count"] = 100000;
  big["grid"]["r"]["count"] = 100000;
  auto s = lgp::datasets::parseScene(big, "big.json");
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().find("big.json"), std::string::npos) << s.error();
}

// A table file of the given kind, checked through the reader, column selection and validation.
bool tableCase(const fs::path& p) {
  auto raw = lgp::readTableFile(p);
  if (!raw) {
    EXPECT_FALSE(raw.error().empty());
    return false;
  }
  auto t = lgp::selectColumns(*raw, {}, {}, "", p.string());
  if (!t && raw->names.size() >= 2) {
    t = lgp::selectColumns(*raw, {raw->names.front()}, {raw->names.back()}, "", p.string());
  }
  if (t) {
    EXPECT_TRUE(t->validate()) << p;
  }
  return bool(t);
}

TEST_F(Fuzz, CsvTables) {
  Counts c;
  Mutator m(303);
  std::stringstream ss;
  ss << std::ifstream(table_).rdbuf();
  const std::string seed = ss.str();
  for (int i = 0, n = scaled(600); i < n; ++i) {
    std::string text = seed;
    m.mutateText(text);
    oneCase(c, "csv table", text, [&] { return tableCase(file("t.csv", text)); });
  }
  c.print("csv table");
  EXPECT_GT(c.accepted, 0);
  EXPECT_GT(c.rejected, 0);
}

TEST_F(Fuzz, JsonTables) {
  Counts c;
  Mutator m(404);
  auto raw = lgp::readTableFile(table_);
  ASSERT_TRUE(raw) << raw.error();
  auto t = lgp::selectColumns(*raw, {"x", "y"}, {"f"}, "", "seed");
  ASSERT_TRUE(t) << t.error();
  const nlohmann::json seed = lgp::toJson(*t);
  for (int i = 0, n = scaled(600); i < n; ++i) {
    const std::string text = m.mutateDocument(seed);
    oneCase(c, "json table", text, [&] { return tableCase(file("t.json", text)); });
  }
  c.print("json table");
  EXPECT_GT(c.accepted, 0);
  EXPECT_GT(c.rejected, 0);
}

TEST_F(Fuzz, TableRegressions) {
  // A UTF-8 byte-order mark before the header is not part of the first column's name.
  EXPECT_TRUE(tableCase(file("bom.csv", "\xEF\xBB\xBFx,y,f\n0.1,0.2,0.3\n0.4,0.5,0.6\n")));
  // A subnormal value is finite.
  EXPECT_TRUE(tableCase(file("sub.csv", "x,y,f\n1e-310,0.2,0.3\n0.4,0.5,0.6\n")));
  // Beyond float32, which the evaluation uses: refused, naming the column.
  auto big = lgp::readTableFile(file("big.csv", "x,y,f\n0.1,0.2,1e39\n0.4,0.5,0.6\n"));
  if (big) {
    auto t = lgp::selectColumns(*big, {"x", "y"}, {"f"}, "", "big.csv");
    const std::string why = t ? t->validate().message() : t.error();
    EXPECT_NE(why.find("f"), std::string::npos) << why;
  }
  // A directory and a FIFO: a message with the path, and no read that blocks.
  const fs::path sub = dir_->path() / "adir.csv";
  fs::create_directories(sub);
  auto d = lgp::readTableFile(sub);
  ASSERT_FALSE(d);
  EXPECT_NE(d.error().find(sub.string()), std::string::npos) << d.error();
  const fs::path fifo = dir_->path() / "fifo.csv";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  watchdog().arm("fifo table", fifo.string(), kCaseDeadlineS);
  auto f = lgp::readTableFile(fifo);
  watchdog().disarm();
  ASSERT_FALSE(f);
  EXPECT_NE(f.error().find(fifo.string()), std::string::npos) << f.error();
}

lgp::emit::ParseOptions formulaOptions(int outputs) {
  lgp::emit::ParseOptions o;
  o.input_names = {"mu", "r"};
  o.output_names =
      outputs == 1 ? std::vector<std::string>{"B"} : std::vector<std::string>{"A", "B"};
  o.aliases = {{"NoV", "mu"}};
  return o;
}

bool formulaCase(const std::string& text, int outputs) {
  auto p = lgp::emit::parseFormula({text}, formulaOptions(outputs));
  if (!p) {
    EXPECT_FALSE(p.error().empty());
    return false;
  }
  EXPECT_EQ(static_cast<int>(p->infix.size()), outputs) << text.substr(0, 300);
  return true;
}

TEST(FuzzFormula, References) {
  Counts c;
  Mutator m(505);
  const std::vector<std::string> seeds = {
      "B = exp2(-(7*NoV + 4*r*r))",
      "m = r*r; B = exp2(-(7*NoV + 4*m)); A = 1 - B - m*max(B, min(r, 0.739 + 0.323*NoV) - 0.434)",
      "qx = 1 - r; a = min(qx*qx, exp2(-9.28*NoV))*qx + 0.04; A = -1.04*a + 1; B = 1.04*a - 0.04",
      "B = saturate(mad(mu, 0.5, r)) / sqrt(abs(log2(r + 1e-3)))"};
  for (int i = 0, n = scaled(2000); i < n; ++i) {
    std::string text = seeds[m.below(seeds.size())];
    m.mutateText(text);
    const int outputs = text.find("A") != std::string::npos ? 2 : 1;
    oneCase(c, "formula", text, [&] { return formulaCase(text, outputs); });
  }
  c.print("formula");
  EXPECT_GT(c.accepted, 0);
  EXPECT_GT(c.rejected, 0);
}

TEST(FuzzFormula, Regressions) {
  // Each of these crashed `lgp run` (stack overflow, out-of-bounds index) or took seconds.
  const std::vector<std::string> crashers = {
      "B = " + std::string(3000, '(') + "mu" + std::string(3000, ')'),
      "B = " + std::string(5000, '-') + "mu",
      "B = " + repeat("abs(", 3000) + "mu" + std::string(3000, ')'),
      "B = x2147483648",
      "B = x18446744073709551617 + mu",
      "B = " + repeat("mu + ", 30000) + "r"};
  for (const auto& text : crashers) {
    watchdog().arm("formula regression", text, kCaseDeadlineS);
    EXPECT_FALSE(formulaCase(text, 1)) << text.substr(0, 80);
    watchdog().disarm();
  }
  EXPECT_TRUE(formulaCase("B = " + std::string(50, '(') + "mu" + std::string(50, ')'), 1));
}

TEST(FuzzFormula, AuditRefusals) {
  // Accepted silently before the hardening audit: hex numbers (read as 16 and 8), a constant
  // beyond float32, an output assigned twice (the first dropped).
  for (const std::string text : {"B = 0x10*mu", "B = 0x1p3 + r", "B = 1e39*mu", "B = mu; B = r"})
    EXPECT_FALSE(formulaCase(text, 1)) << text;
  EXPECT_TRUE(formulaCase("B = 16*mu + 8e-1", 1));
}

// `lgp run` as a user runs it: exit 0 with a non-empty front, or 1-2 with a message; never a
// signal.
TEST_F(Fuzz, CliRuns) {
  Counts c;
  Mutator m(606);
  const nlohmann::json seed = seedConfig(table_);
  const fs::path out = dir_->path() / "front.json";
  for (int i = 0, n = scaled(60); i < n; ++i) {
    nlohmann::json j = seed;
    m.mutateJson(j);
    // A bounded search (here and by --generations, for a mutation that drops "search"): the
    // case is about input handling, not search time.
    if (j.is_object() && j.contains("search") && j["search"].is_object()) {
      j["search"]["generations"] = 2;
      j["search"]["population"] = 16;
    }
    // The CSV front goes to the scratch directory, not to the working directory.
    if (j.is_object() && (!j.contains("output") || j["output"].is_object()))
      j["output"]["front_csv"] = (dir_->path() / "front.csv").string();
    std::string text = j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
    if (m.chance(0.3)) m.mutateText(text);
    const fs::path cfg = file("cli.json", text);
    std::error_code ec;
    fs::remove(out, ec);
    ++c.tried;
    const fs::path log = dir_->path() / "cli.log";
    const pid_t pid = Daemon::spawn(
        {LGP_CLI_BIN, "run", cfg.string(), "-q", "-o", out.string(), "--generations", "2"}, log);
    int st = 0;
    bool done = false;
    for (int w = 0; w < 1200 && !done; ++w) {  // ~60 s
      done = ::waitpid(pid, &st, WNOHANG) == pid;
      if (!done) sleepMs(50);
    }
    if (!done) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, &st, 0);
      ++c.hangs;
      ADD_FAILURE() << "lgp run hung on: " << text.substr(0, 300);
      continue;
    }
    if (WIFSIGNALED(st)) {
      ++c.crashes;
      ADD_FAILURE() << "lgp run died of signal " << WTERMSIG(st) << " on: " << text.substr(0, 300);
      continue;
    }
    const int code = WEXITSTATUS(st);
    if (code == 0) {
      ++c.accepted;
      std::ifstream f(out);
      auto front = lgp::parseJson(std::string(std::istreambuf_iterator<char>(f), {}));
      const bool members = front && front->contains("members") && !(*front)["members"].empty();
      if (!members) {
        ++c.wrong;
        ADD_FAILURE() << "exit 0 without a front on: " << text.substr(0, 300);
      }
    } else if (code == 1 || code == 2) {
      ++c.rejected;
    } else {
      ++c.wrong;
      ADD_FAILURE() << "lgp run exit " << code << " on: " << text.substr(0, 300);
    }
  }
  c.print("lgp run");
  EXPECT_GT(c.accepted, 0);
}

// One raw HTTP exchange: the status of the answer, 0 when the server closed without one.
// `cork`: the bytes and the end of stream leave in one segment (TCP_CORK until the
// shutdown), as when the server reads a connection only after the client has finished.
int rawRequest(int port, const std::string& bytes, int timeout_s = 10, bool cork = false) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) return -1;
  timeval tv{timeout_s, 0};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  ::setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(static_cast<uint16_t>(port));
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
    ::close(fd);
    return -1;
  }
  const int on = 1;
  if (cork) ::setsockopt(fd, IPPROTO_TCP, TCP_CORK, &on, sizeof on);
  size_t sent = 0;
  while (sent < bytes.size()) {
    const ssize_t k = ::send(fd, bytes.data() + sent, bytes.size() - sent, MSG_NOSIGNAL);
    if (k <= 0) break;  // the server may answer and close before reading everything
    sent += static_cast<size_t>(k);
  }
  // End of input: a truncated request is answered or dropped now, not at the read timeout.
  ::shutdown(fd, SHUT_WR);
  std::string reply;
  char buf[4096];
  for (;;) {
    const ssize_t k = ::recv(fd, buf, sizeof buf, 0);
    if (k <= 0) break;
    reply.append(buf, static_cast<size_t>(k));
    if (reply.find("\r\n") != std::string::npos) break;
  }
  ::close(fd);
  if (reply.rfind("HTTP/1.", 0) != 0 || reply.size() < 12) return 0;
  return std::atoi(reply.c_str() + 9);
}

class FuzzDaemon : public Fuzz {
 protected:
  void SetUp() override {
    Fuzz::SetUp();
    daemon_ = std::make_unique<Daemon>(dir_->path() / "lgpd");
    const fs::path cfg = file(
        "lgpd.json", R"({"max_body_bytes": 1048576, "max_jobs": 1, "max_run_memory_mb": 1024})");
    ASSERT_TRUE(daemon_->start({"--config", cfg.string(), "--init"}));
  }
  void TearDown() override {
    if (daemon_) {
      EXPECT_TRUE(daemon_->alive()) << daemon_->log();
    }
  }
  // A status lgpd may give a body: created, or a client error. Never 5xx, never silence.
  static bool fine(int status) { return status == 201 || (status >= 400 && status < 500); }
  std::unique_ptr<Daemon> daemon_;
};

TEST_F(FuzzDaemon, Bodies) {
  Counts c;
  Mutator m(707);
  const nlohmann::json seed = seedConfig(table_);
  for (int i = 0, n = scaled(600); i < n; ++i) {
    const std::string body = m.mutateDocument(seed);
    ++c.tried;
    watchdog().arm("lgpd body", body, kCaseDeadlineS * 2);
    const Reply r = daemon_->post("/api/v1/runs", body);
    watchdog().disarm();
    if (r.status == 0 && !daemon_->alive()) {
      ++c.crashes;
      c.print("lgpd body");
      FAIL() << "lgpd died on: " << body.substr(0, 300) << "\n" << daemon_->log();
    }
    if (!fine(r.status)) {
      ++c.wrong;
      ADD_FAILURE() << "status " << r.status << " for: " << body.substr(0, 300) << "\n"
                    << r.body.substr(0, 300);
    } else if (r.status == 201) {
      ++c.accepted;
      daemon_->del("/api/v1/runs/" + r.j().value("id", ""));  // no job of the fuzzer runs long
    } else {
      ++c.rejected;
      // Every refusal is a JSON error that says why.
      const auto j = r.j();
      EXPECT_TRUE(j.is_object() && j.contains("error")) << r.body.substr(0, 300);
    }
  }
  c.print("lgpd body");
  EXPECT_GT(c.accepted, 0);
  EXPECT_EQ(daemon_->get("/api/v1/runs").status, 200);
}

TEST_F(FuzzDaemon, BodyRegressions) {
  const nlohmann::json seed = seedConfig(table_);
  auto with = [&](const std::function<void(nlohmann::json&)>& f) {
    nlohmann::json j = seed;
    f(j);
    return j.dump();
  };
  const fs::path fifo = dir_->path() / "fifo.csv";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const fs::path adir = dir_->path() / "adir";
  fs::create_directories(adir);
  const std::vector<std::pair<std::string, std::string>> bodies = {
      {"100k-deep object", nestedObject(100000)},
      {"100k-deep array in a field",
       "{\"search\": " + std::string(100000, '[') + std::string(100000, ']') + "}"},
      {"1e999",
       with([](auto& j) { j["search"]["seed"] = 1; }).replace(0, 1, "{\"search_x\": 1e999, ")},
      {"400-digit integer", "{\"n\": " + std::string(400, '9') + "}"},
      {"bad reference seeded", with([](auto& j) {
         j["search"]["seed_references"] = true;
         j["references"] = {{{"name", "bad"}, {"expr", "f = x*y +"}}};
       })},
      {"deep reference", with([](auto& j) {
         j["references"] = {
             {{"name", "deep"},
              {"expr", "f = " + std::string(3000, '(') + "x" + std::string(3000, ')')}}};
       })},
      {"index overflow", with([](auto& j) {
         j["references"] = {{{"name", "idx"}, {"expr", "f = x2147483648"}}};
       })},
      {"FIFO as data", with([&](auto& j) { j["data"]["path"] = fifo.string(); })},
      {"directory as data", with([&](auto& j) { j["data"]["path"] = adir.string(); })},
      {"duplicate keys", "{\"data\": {}, \"data\": {}}"},
      {"population over the memory bound", with([](auto& j) {
         j["search"]["population"] = 1 << 20;
         j["program"] = {{"max_length", 255}, {"constants", 255}};
       })},
  };
  for (const auto& [what, body] : bodies) {
    watchdog().arm(what, body, kCaseDeadlineS);
    const Reply r = daemon_->post("/api/v1/runs", body);
    watchdog().disarm();
    EXPECT_EQ(r.status, 400) << what << ": " << r.body.substr(0, 300);
    ASSERT_TRUE(daemon_->alive()) << what << "\n" << daemon_->log();
  }
  // Nothing of the above was queued.
  EXPECT_EQ(daemon_->get("/api/v1/runs").j().value("runs", nlohmann::json::array()).size(), 0u);
}

TEST_F(FuzzDaemon, RawRequests) {
  Counts c;
  Mutator m(808);
  const std::string body = seedConfig(table_).dump();
  const std::vector<std::string> seeds = {
      "POST /api/v1/runs HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: "
      "application/json\r\nContent-Length: " +
          std::to_string(body.size()) + "\r\n\r\n" + body,
      "GET /api/v1/runs HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n",
      "GET /api/v1/runs/0123456789abcdef/front HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n",
      "DELETE /api/v1/runs/zz HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"};
  for (int i = 0, n = scaled(600); i < n; ++i) {
    std::string req = seeds[m.below(seeds.size())];
    m.mutateText(req);
    ++c.tried;
    watchdog().arm("lgpd raw request", req, kCaseDeadlineS * 2);
    const int status = rawRequest(daemon_->port(), req, 10);
    watchdog().disarm();
    if (!daemon_->alive()) {
      ++c.crashes;
      c.print("lgpd raw");
      FAIL() << "lgpd died on: " << req.substr(0, 300) << "\n" << daemon_->log();
    }
    // Garbage may get no answer (the server may just close), but never a 5xx.
    if (status >= 500) {
      ++c.wrong;
      ADD_FAILURE() << "status " << status << " for: " << req.substr(0, 300);
    } else if (status == 201 || (status >= 200 && status < 300)) {
      ++c.accepted;
    } else {
      ++c.rejected;
    }
  }
  c.print("lgpd raw");
  // The framing cases the audit found: each a 4xx, never a 5xx or a full read of a huge body.
  const std::string big(9000, ' ');
  const std::vector<std::pair<std::string, std::string>> framing = {
      {"negative length",
       "POST /api/v1/runs HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
       "Content-Length: -5\r\n\r\n{}"},
      {"no content type",
       "POST /api/v1/runs HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 9000\r\n\r\n" + big},
      {"chunked over the limit",
       "POST /api/v1/runs HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
       "Transfer-Encoding: chunked\r\n\r\n" +
           repeat("4000\r\n" + std::string(0x4000, ' ') + "\r\n", 80) + "0\r\n\r\n"},
      {"request target over 8 KiB",
       "GET /api/v1/runs/" + std::string(9000, 'a') + " HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"},
      {"headers over 80 KiB", "GET /api/v1/runs HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Big: " +
                                  std::string(100000, 'b') + "\r\n\r\n"},
  };
  for (const auto& [what, req] : framing) {
    const int status = rawRequest(daemon_->port(), req, 10);
    EXPECT_GE(status, 400) << what;
    EXPECT_LT(status, 500) << what;
  }
  EXPECT_EQ(daemon_->get("/api/v1/runs").status, 200);
}

TEST_F(FuzzDaemon, CutShortRequestsAreDroppedAtOnce) {
  // A request cut short by the client's end of stream can never complete: it is dropped at
  // once, not at the idle timeout (libmicrohttpd alone waited 5 s for each).
  for (const std::string& cut : {std::string("GET /api/v1/runs HTTP/1.1\r\nHost: 127.0.0.1\r\n"),
                                 std::string("DELETE /api/v1/r"), std::string("GET ")}) {
    const auto t0 = std::chrono::steady_clock::now();
    EXPECT_EQ(rawRequest(daemon_->port(), cut, 10, true), 0) << cut;
    EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(3)) << cut;
  }
  EXPECT_EQ(daemon_->get("/api/v1/runs").status, 200);
}

// --- Hardening round 3: each finding's input, replayed with the outcome it must have. -------
// (F6, F7, F10 and lgp.fit(seconds=inf) are the Python package's: tests/python.)

// `lgp` with `args` (no shell): exit code, stdout and stderr together.
int cli(const std::vector<std::string>& args, const fs::path& scratch, std::string* out) {
  std::vector<std::string> argv = {LGP_CLI_BIN};
  argv.insert(argv.end(), args.begin(), args.end());
  const fs::path log = scratch / "cli-err.log";
  std::error_code ec;
  fs::remove(log, ec);
  const int code = runProgram(argv, out, log, 300);
  std::ifstream err(log);
  *out += std::string(std::istreambuf_iterator<char>(err), {});
  return code;
}

std::vector<std::string> inputNames(int n) {
  std::vector<std::string> v;
  for (int i = 0; i < n; ++i) v.push_back("x" + std::to_string(i));
  return v;
}

TEST_F(Fuzz, RoundThreeCliRegressions) {
  const fs::path d = dir_->path();
  std::string out;
  // F1: a 66-term formula and a 100-input table ran past the interpreter's operand table
  // (SIGABRT, SIGSEGV).
  std::string expr = "B = mu*1.5";
  for (int k = 1; k < 66; ++k) expr += (k % 2 ? " + r*" : " + mu*") + std::to_string(k) + ".25";
  EXPECT_EQ(cli({"score", (fs::path(LGP_SOURCE_DIR) / "examples/quickstart.csv").string(),
                 "--inputs", "mu,r", "--outputs", "B", "--no-measure", "--expr", expr},
                d, &out),
            0)
      << out;
  std::ofstream(d / "wide.json") << jsonTable(inputNames(100), 64).dump();
  nlohmann::json wide = {
      {"data", {{"path", (d / "wide.json").string()}}},
      {"search", {{"population", 16}, {"generations", 2}, {"threads", 1}}},
      {"output", {{"front_json", (d / "wide-front.json").string()}, {"front_csv", ""}}}};
  EXPECT_EQ(cli({"run", file("wide-run.json", wide.dump()).string(), "-q"}, d, &out), 0) << out;
  // F2: a checkpoint with an island emptied (SIGSEGV on --resume: bred from an empty island).
  nlohmann::json run = seedConfig(table_);
  run["search"]["generations"] = 3;
  run["search"]["population"] = 16;
  run["output"] = {{"front_json", (d / "front.json").string()}, {"front_csv", ""}};
  const fs::path cfg = file("run.json", run.dump());
  const std::string ck = (d / "ck.json").string();
  ASSERT_EQ(cli({"run", cfg.string(), "-q", "--checkpoint", ck}, d, &out), 0) << out;
  std::ifstream ck_in(ck);
  nlohmann::json state = nlohmann::json::parse(ck_in);
  for (const char* key : {"population", "rank", "crowd"})
    state["islands"][0][key] = nlohmann::json::array();
  std::ofstream(ck) << state.dump();
  EXPECT_EQ(cli({"run", cfg.string(), "-q", "--checkpoint", ck, "--resume", "--generations", "6"},
                d, &out),
            2)
      << out;
  EXPECT_NE(out.find("checkpoint: island 0 holds 0 programs"), std::string::npos) << out;
  // F5: a front whose texts are escape sequences (title, OSC 52), printed raw.
  std::ifstream front_in(d / "front.json");
  nlohmann::json front = nlohmann::json::parse(front_in);
  front["cost_model"] = "\x1b]0;pwned\x07";
  front["members"][0]["program"]["code"][0][0] = "\x1b]52;c;cHduZWQ=\x07";
  const fs::path hostile = file("hostile.json", front.dump());
  EXPECT_EQ(cli({"front", hostile.string()}, d, &out), 0) << out;
  EXPECT_EQ(out.find('\x1b'), std::string::npos) << out;
  EXPECT_EQ(cli({"emit", hostile.string(), "--member", "0", "--no-measure"}, d, &out), 2) << out;
  EXPECT_EQ(out.find('\x1b'), std::string::npos) << out;
  // A 300-opcode program: refused naming the bound, not "max_length is 300".
  nlohmann::json code = nlohmann::json::array({{"add", "x0", "x1"}});
  for (int i = 1; i < 300; ++i) code.push_back({"mul", "r" + std::to_string((i - 1) % 255), "x0"});
  front = nlohmann::json::parse(std::ifstream(d / "front.json"));
  front["members"][0]["program"]["code"] = code;
  EXPECT_EQ(cli({"emit", file("long.json", front.dump()).string(), "--member", "0", "--no-measure"},
                d, &out),
            2)
      << out;
  EXPECT_NE(out.find("program has 300 opcodes, at most 255 are allowed"), std::string::npos) << out;
}

// F13: the enumeration had no memory bound (a bare std::bad_alloc after 2.1 GB).
TEST(FuzzRoundThree, ExhaustiveStopsAtItsMemoryBound) {
  lgp::Table t;
  t.input_names = {"x", "y"};
  t.output_names = {"f"};
  t.inputs.resize(2);
  t.outputs.resize(1);
  for (int i = 0; i < 64; ++i) {
    t.inputs[0].push_back((i % 8) / 8.0);
    t.inputs[1].push_back((i / 8) / 8.0);
    t.outputs[0].push_back(t.inputs[0].back() * t.inputs[1].back());
  }
  lgp::RunConfig c;
  c.data.path = "t.csv";
  c.search.threads = 2;
  c.search.exhaustive.max_ops = 8;
  c.search.exhaustive.seconds = 600;
  c.search.exhaustive.ops = {lgp::Op::Add, lgp::Op::Mul, lgp::Op::Sub, lgp::Op::Div, lgp::Op::Exp2};
  watchdog().arm("exhaustive memory bound", "", kCaseDeadlineS * 4);
  auto r = lgp::exhaustiveSearch(c, t, size_t{16} << 20);
  watchdog().disarm();
  ASSERT_TRUE(r) << r.error();
  EXPECT_EQ(r->stopped, "memory");
}

TEST_F(FuzzDaemon, RoundThreeBodyRegressions) {
  const nlohmann::json seed = seedConfig(table_);
  // F4: a semantic cache beyond the run memory bound (1 GiB here): 9 GiB allocated at start.
  nlohmann::json cache = seed;
  cache["search"]["semantic_cache"] = 1 << 26;
  Reply r = daemon_->post("/api/v1/runs", cache.dump());
  EXPECT_EQ(r.status, 400) << r.body;
  EXPECT_EQ(r.j().value("field", ""), "/search/semantic_cache") << r.body;
  // F12: search.exhaustive was accepted and never run.
  nlohmann::json exhaustive = seed;
  exhaustive["search"]["exhaustive"] = {{"max_ops", 3}};
  r = daemon_->post("/api/v1/runs", exhaustive.dump());
  EXPECT_EQ(r.status, 400) << r.body;
  EXPECT_EQ(r.j().value("field", ""), "/search/exhaustive") << r.body;
  // F1: an inline table of 100 inputs and a 131-operation reference: 201, then lgpd died when
  // the job started. Now they run to the end.
  nlohmann::json wide = {{"data", {{"table", jsonTable(inputNames(100), 32)}}},
                         {"search", {{"population", 16}, {"generations", 2}, {"threads", 1}}}};
  nlohmann::json long_ref = seed;
  std::string expr = "f = x";
  for (int k = 0; k < 65; ++k) expr += " + y*" + std::to_string(k + 2);
  long_ref["references"] = {{{"name", "long"}, {"expr", expr}}};
  long_ref["search"]["generations"] = 2;
  for (const auto& body : {wide, long_ref}) {
    const std::string id = daemon_->submit(body, &r);
    ASSERT_FALSE(id.empty()) << r.body;
    EXPECT_EQ(daemon_->waitDone(id, 120).value("status", ""), "finished") << daemon_->log();
    ASSERT_TRUE(daemon_->alive()) << daemon_->log();
  }
}

// F3 and F8: what lgpd reads back from a run's data file and its own store.
TEST_F(FuzzDaemon, RoundThreeStoredStateRegressions) {
  const fs::path state = dir_->path() / "lgpd";
  const fs::path cfg = dir_->path() / "lgpd.json";
  const fs::path table = dir_->path() / "roles.json";
  std::ofstream(table) << jsonTable(inputNames(30)).dump();
  const nlohmann::json body = {
      {"data", {{"path", table.string()}}},
      {"search", {{"population", 16}, {"generations", 2}, {"threads", 1}}}};
  const std::string a = daemon_->submit(body), b = daemon_->submit(body);
  ASSERT_FALSE(a.empty() || b.empty());
  ASSERT_EQ(daemon_->waitDone(a).value("status", ""), "finished");
  ASSERT_EQ(daemon_->waitDone(b).value("status", ""), "finished");
  daemon_->stop();
  // F3: the table rewritten with one input (the front's programs read 30).
  std::ofstream(table) << jsonTable(inputNames(1)).dump();
  // F8: a front row 100k deep; a status that is no status.
  ASSERT_TRUE(
      execSql(state, "UPDATE fronts SET front = ?1 WHERE run_id = ?2", deepCbor(), b, true));
  ASSERT_TRUE(execSql(state, "UPDATE runs SET status = ?1 WHERE id = ?2", "nope", b));
  ASSERT_TRUE(daemon_->start({"--config", cfg.string()}));
  Reply r;
  for (int i = 0; i < 100; ++i) {
    r = daemon_->get("/api/v1/runs/" + a + "/front/0/residuals");
    if (r.status != 503) break;
    sleepMs(50);
  }
  EXPECT_EQ(r.status, 409) << r.body;
  EXPECT_EQ(daemon_->get("/api/v1/runs/" + b + "/front").status, 500);
  r = daemon_->get("/api/v1/runs");
  EXPECT_EQ(r.status, 200) << r.body;
  EXPECT_EQ(r.j()["runs"].size(), 1u) << r.body;
}

// --- Hardening round 4: each finding's input, replayed with the outcome it must have. --------
// (F2 and lgp.fit's cache_dir "-" are also Python's and the daemon's own tests; F5's needs a
// Vulkan driver: tests/emit/vulkan_run_test.cpp.)

// A table of `outputs` outputs y0.. over inputs x, y (lgp-table/1).
nlohmann::json wideOutputs(int outputs, int rows = 32) {
  nlohmann::json t = jsonTable({"x", "y"}, rows);
  t["outputs"] = nlohmann::json::array();
  for (int k = 0; k < outputs; ++k) {
    const std::string n = "y" + std::to_string(k);
    t["outputs"].push_back(n);
    t["columns"][n] = t["columns"]["f"];
  }
  t["columns"].erase("f");
  return t;
}

TEST_F(Fuzz, RoundFourCliRegressions) {
  const fs::path d = dir_->path();
  std::string out;
  // F3: 17 outputs x 16 genes with the outputs unlisted: a misleading float32 error, or exit 0
  // with a member whose claimed error was not its own. Refused, naming program.genes.
  std::ofstream(d / "wide17.json") << wideOutputs(17).dump();
  nlohmann::json genes = {{"data", {{"path", (d / "wide17.json").string()}}},
                          {"program", {{"genes", 16}, {"max_length", 8}, {"constants", 0}}},
                          {"search",
                           {{"population", 16}, {"generations", 2}, {"threads", 1},
                            {"linear_scaling", true}}},
                          {"output", {{"front_json", (d / "g.json").string()}, {"front_csv", ""}}}};
  EXPECT_EQ(cli({"run", file("genes.json", genes.dump()).string(), "-q"}, d, &out), 2) << out;
  EXPECT_NE(out.find("/program/genes: outputs * genes must be <= 255 (17 outputs x 16 genes)"),
            std::string::npos)
      << out;
  // F7, F8, F9: generated values at the domain's edges.
  std::ofstream(d / "edges.json") << R"({"material": {"fresnel": {"model": "dielectric"}},
    "outputs": ["F_dielectric"], "grid": {"mu": {"values": [0, 1e-12, 1e-9, 1e-8, 0.5]},
    "eta": {"values": [1]}}})";
  ASSERT_EQ(cli({"data", (d / "edges.json").string(), "-o", (d / "edges.t.json").string(),
                 "--no-cache", "-q"},
                d, &out),
            0)
      << out;
  auto edges = nlohmann::json::parse(std::ifstream(d / "edges.t.json"));
  for (const auto& v : edges["columns"]["F_dielectric"]) EXPECT_EQ(v.get<double>(), 0.0) << out;
  std::ofstream(d / "sheen0.json") << R"({"material": {"roughness": "linear"},
    "outputs": ["E_sheen"], "grid": {"mu": {"values": [0, 0.5]}, "r": {"values": [1e-30, 0.5]}}})";
  ASSERT_EQ(cli({"data", (d / "sheen0.json").string(), "-o", (d / "sheen0.t.json").string(),
                 "--no-cache", "-q"},
                d, &out),
            0)
      << out;
  auto sheen = nlohmann::json::parse(std::ifstream(d / "sheen0.t.json"));
  EXPECT_GT(sheen["columns"]["E_sheen"][0].get<double>(), 1e14) << out;  // ~1/sqrt(2 pi 1e-30)
  std::ofstream(d / "tiny.json") << R"({"material": {"roughness": "linear"},
    "outputs": ["E_sheen"], "grid": {"mu": {"values": [5e-324, 0.5]},
    "r": {"values": [5e-324, 0.5]}}})";
  EXPECT_EQ(cli({"data", (d / "tiny.json").string(), "-o", (d / "tiny.t.json").string(),
                 "--no-cache", "-q"},
                d, &out),
            1)
      << out;
  EXPECT_NE(out.find("E_sheen at mu=5e-324, r=5e-324 (row 1)"), std::string::npos) << out;
  // F11: thousands of threads under an address-space limit ended the process.
  const std::string limited = "ulimit -v 4000000; '" + std::string(LGP_CLI_BIN) + "' data '" +
                              (d / "edges.json").string() + "' -o '" +
                              (d / "edges.t2.json").string() + "' --no-cache -q --threads 3000";
  EXPECT_EQ(runProgram({"/bin/sh", "-c", limited}, &out, d / "sh.log", 120), 0) << out;
  // F12: a checkpoint whose archive claims an error its program does not score.
  nlohmann::json run = seedConfig(table_);
  run["search"]["generations"] = 3;
  run["search"]["population"] = 16;
  run["output"] = {{"front_json", (d / "front.json").string()}, {"front_csv", ""}};
  const fs::path cfg = file("run4.json", run.dump());
  const std::string ck = (d / "ck4.json").string();
  ASSERT_EQ(cli({"run", cfg.string(), "-q", "--checkpoint", ck}, d, &out), 0) << out;
  nlohmann::json state = nlohmann::json::parse(std::ifstream(ck));
  state["archive"][0]["obj"][0] = 1e-12;
  std::ofstream(ck) << state.dump();
  EXPECT_EQ(cli({"run", cfg.string(), "-q", "--checkpoint", ck, "--resume", "--generations", "6"},
                d, &out),
            2)
      << out;
  EXPECT_NE(out.find("archive member 0 claims error 1e-12"), std::string::npos) << out;
  // F13: a member without its float32 metrics (a raw JSON exception), an output index of 2^32
  // (read as 0).
  nlohmann::json front = nlohmann::json::parse(std::ifstream(d / "front.json"));
  nlohmann::json bad = front;
  bad["members"][0]["outputs"][0].erase("float32");
  EXPECT_EQ(cli({"front", file("nof32.json", bad.dump()).string()}, d, &out), 2) << out;
  EXPECT_NE(out.find("/members/0/outputs/0/float32: must be an object"), std::string::npos)
      << out;
  EXPECT_EQ(out.find("json.exception"), std::string::npos) << out;
  bad = front;
  bad["members"][0]["program"]["outputs"] = {4294967296ULL};
  EXPECT_EQ(cli({"emit", file("out32.json", bad.dump()).string(), "--member", "0", "--no-measure"},
                d, &out),
            2)
      << out;
  EXPECT_NE(out.find("(got 4294967296)"), std::string::npos) << out;
  // F6: a front's config named where its scene's table is cached, and its scene was generated
  // before its columns were checked.
  std::ofstream(d / "qs_scene.json") << R"({"outputs": ["A", "B"],
    "material": {"fresnel": {"model": "schlick", "f90": 1}},
    "grid": {"mu": {"count": 6}, "r": {"count": 6}}})";
  nlohmann::json sfront = front;
  sfront["config"]["data"] = {{"scene", (d / "qs_scene.json").string()},
                              {"cache_dir", (d / "named" / "by" / "front").string()}};
  EXPECT_EQ(cli({"emit", file("sfront.json", sfront.dump()).string(), "--member", "0", "--snap",
                 "--no-measure"},
                d, &out),
            2)
      << out;
  EXPECT_NE(out.find("no column named 'x' (input)"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(d / "named"));
}

TEST_F(FuzzDaemon, RoundFourBodyRegressions) {
  const nlohmann::json seed = seedConfig(table_);
  // F1: a cache directory named by the request.
  nlohmann::json cache = seed;
  std::ofstream(dir_->path() / "favg.json") << R"({"material": {"fresnel": {"model": "dielectric"}},
    "outputs": ["F_avg"], "grid": {"eta": {"count": 8, "range": [1, 2]}}})";
  cache["data"] = {{"scene", (dir_->path() / "favg.json").string()},
                   {"cache_dir", (dir_->path() / "outside" / "created").string()}};
  Reply r = daemon_->post("/api/v1/runs", cache.dump());
  EXPECT_EQ(r.status, 400) << r.body;
  EXPECT_EQ(r.j().value("field", ""), "/data/cache_dir") << r.body;
  EXPECT_FALSE(fs::exists(dir_->path() / "outside"));
  // F3: an inline table of 17 outputs with 16 genes each.
  nlohmann::json genes = {{"data", {{"table", wideOutputs(17)}}},
                          {"program", {{"genes", 16}, {"max_length", 8}, {"constants", 0}}},
                          {"search",
                           {{"population", 16}, {"generations", 2}, {"threads", 1},
                            {"linear_scaling", true}}}};
  r = daemon_->post("/api/v1/runs", genes.dump());
  EXPECT_EQ(r.status, 400) << r.body;
  EXPECT_EQ(r.j().value("field", ""), "/program/genes") << r.body;
  // F4: 15 outputs x 16 genes priced at max_length (15 opcodes) instead of the shape's 255:
  // 100,000 programs over the 1 GiB bound were accepted.
  nlohmann::json memory = {{"data", {{"table", wideOutputs(15)}}},
                           {"program", {{"genes", 16}, {"max_length", 15}, {"constants", 0}}},
                           {"search",
                            {{"population", 100000}, {"generations", 1}, {"threads", 1},
                             {"linear_scaling", true}}}};
  r = daemon_->post("/api/v1/runs", memory.dump());
  EXPECT_EQ(r.status, 400) << r.body;
  EXPECT_EQ(r.j().value("field", ""), "/search/population") << r.body;
  EXPECT_NE(r.body.find("programs of up to 255 opcodes"), std::string::npos) << r.body;
  // F2: a scene that takes minutes, deleted while it is generated: the daemon is idle again
  // at once (the next run finishes within its own seconds, not after the scene).
  std::ofstream(dir_->path() / "slow.json") << R"({"material": {"fresnel": {"model": "dielectric"}},
    "outputs": ["E_dielectric"],
    "grid": {"mu": {"count": 40}, "r": {"count": 40}, "eta": {"count": 40, "range": [1.1, 2.5]}}})";
  nlohmann::json slow = {{"data", {{"scene", (dir_->path() / "slow.json").string()}}},
                         {"search", {{"population", 16}, {"generations", 2}, {"threads", 1}}}};
  const std::string id = daemon_->submit(slow, &r);
  ASSERT_FALSE(id.empty()) << r.body;
  for (int i = 0; i < 200 && daemon_->log().find("run " + id + ": loading") == std::string::npos;
       ++i)
    sleepMs(50);
  EXPECT_EQ(daemon_->del("/api/v1/runs/" + id).status, 200);
  nlohmann::json quick = seed;
  quick["search"]["generations"] = 2;
  const std::string next = daemon_->submit(quick, &r);
  ASSERT_FALSE(next.empty()) << r.body;
  EXPECT_EQ(daemon_->waitDone(next, 30).value("status", ""), "finished") << daemon_->log();
}

}  // namespace
