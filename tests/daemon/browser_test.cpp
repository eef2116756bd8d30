// The inspection page in headless Chromium against a live lgpd: the run list and the Pareto
// plot render with the expected number of points; the config's references are scored and
// drawn inside the plot area even when they lie outside the members' cost range, and one
// without a finite error (it overflows float32) leaves the plot intact; the member list shows each
// member's formula with a copy button and its cancellation flag; the selected member's panel and
// the residual heatmap fill in; and a screenshot is saved under the build directory
// (tests/daemon/lgpd-page.png). Skipped with a message when chromium is not installed.
#include <algorithm>
#include <regex>

#include "../skip.hpp"
#include "daemon_harness.hpp"

namespace lgpd_test {
namespace {

std::string findChromium() {
  for (const char* p : {"/usr/bin/chromium", "/usr/bin/chromium-browser",
                        "/usr/lib/chromium/chromium", "/usr/bin/google-chrome"})
    if (access(p, X_OK) == 0) return p;
  return "";
}

std::vector<std::string> chromiumArgs(const std::string& bin, const fs::path& profile) {
  return {bin,
          "--headless",
          "--no-sandbox",
          "--disable-gpu",
          "--disable-background-networking",
          "--disable-dev-shm-usage",
          "--disable-extensions",
          "--disable-sync",
          "--disable-component-update",
          "--no-first-run",
          "--no-default-browser-check",
          "--user-data-dir=" + profile.string()};
}

// The value of attribute `attr` on the element with id `id` in dumped HTML.
std::string attrOf(const std::string& html, const std::string& id, const std::string& attr) {
  auto tag_start = html.rfind('<', html.find("id=\"" + id + "\""));
  if (tag_start == std::string::npos || html.find("id=\"" + id + "\"") == std::string::npos)
    return "";
  auto tag_end = html.find('>', tag_start);
  std::string tag = html.substr(tag_start, tag_end - tag_start);
  std::smatch m;
  if (std::regex_search(tag, m, std::regex(attr + "=\"([^\"]*)\""))) return m[1];
  return "";
}

// Text as Chromium's --dump-dom serialises it: in text (&, <, >) and in attribute values (&, ").
std::string escapeText(const std::string& s) {
  std::string o;
  for (char c : s)
    o += c == '&' ? "&amp;" : c == '<' ? "&lt;" : c == '>' ? "&gt;" : std::string(1, c);
  return o;
}
std::string escapeAttr(const std::string& s) {
  std::string o;
  for (char c : s) o += c == '&' ? "&amp;" : c == '"' ? "&quot;" : std::string(1, c);
  return o;
}

size_t countOf(const std::string& hay, const std::string& needle) {
  size_t n = 0;
  for (size_t p = hay.find(needle); p != std::string::npos; p = hay.find(needle, p + 1)) ++n;
  return n;
}

// The member's formula as the page shows it: "formula", else "A = expr; B = expr".
std::string formulaOf(const json& m) {
  if (m.contains("formula") && m["formula"].is_string() && !m["formula"].get<std::string>().empty())
    return m["formula"];
  std::string s;
  for (const auto& o : m["outputs"])
    s += (s.empty() ? "" : "; ") + o.value("name", "") + " = " + o.value("expression", "");
  return s;
}

struct RefMark {
  std::string name;
  double x = 0, y = 0;            // data-x, data-y
  double path_x = 0, path_y = 0;  // the diamond's top vertex, from its path
};

// The reference markers of the plot: <g class="refmark" data-x data-y data-name><path d=...>.
std::vector<RefMark> refMarks(const std::string& dom) {
  std::vector<RefMark> out;
  for (size_t p = dom.find("class=\"refmark\""); p != std::string::npos;
       p = dom.find("class=\"refmark\"", p + 1)) {
    const size_t end = dom.find("</g>", p);
    const std::string g = dom.substr(p, end - p);
    std::smatch m;
    RefMark r;
    if (std::regex_search(g, m, std::regex("data-x=\"([-0-9.e]+)\""))) r.x = std::stod(m[1]);
    if (std::regex_search(g, m, std::regex("data-y=\"([-0-9.e]+)\""))) r.y = std::stod(m[1]);
    if (std::regex_search(g, m, std::regex("data-name=\"([^\"]*)\""))) r.name = m[1];
    if (std::regex_search(g, m, std::regex("d=\"M([-0-9.e]+) ([-0-9.e]+)"))) {
      r.path_x = std::stod(m[1]);
      r.path_y = std::stod(m[2]);
    }
    out.push_back(r);
  }
  return out;
}

TEST(Browser, PageRendersRunsParetoMemberAndHeatmap) {
  const std::string chromium = findChromium();
  if (chromium.empty())
    LGP_SKIP_UNLESS_REQUIRED() << "chromium not installed (scripts/lgp.sh deps installs it)";

  TempDir tmp("browser");
  fs::path table = writeGridTable(tmp.path(), 16);
  Daemon d(tmp.path() / "state");
  ASSERT_TRUE(d.start());
  json cfg = runConfig(table, 40, 64, 3);
  cfg["name"] = "browser demo";
  // References, scored by lgpd beside the front: the target itself (error near 0, below the
  // members), one far costlier than any member, and one whose value overflows float32 (no
  // finite error). One that does not parse is refused at submit.
  cfg["references"] = {
      {{"name", "exact"}, {"expr", "x*y + 0.5*x - y/(1 + x)"}},
      {{"name", "costly"},
       {"expr",
        "x*y + 0.5*x - y/(1 + x) + 0.001*(sin(exp(x)*cos(y)) + sin(exp(y)*cos(x)) + "
        "sqrt(x + y)*log(1 + x*y) + pow(x, y)*exp(-x*y) + sin(x*y)/(1 + y) + cos(x + y)*exp(y) "
        "+ sin(exp(x + y)) + cos(exp(x*y)) + sqrt(exp(x))*sin(y) + log(2 + sin(x))*cos(y))"}},
      {{"name", "overflow"}, {"expr", "(1e38*x)*(1e38*y)"}}};
#ifdef LGPD_TEST_HAVE_EMIT
  {
    json bad = cfg;
    bad["references"][2]["expr"] = "nosuchcolumn*2";
    Reply r;
    EXPECT_TRUE(d.submit(bad, &r).empty());
    EXPECT_EQ(r.status, 400) << r.body;
    EXPECT_EQ(r.j().value("field", ""), "/references/2/expr") << r.body;
  }
#endif
  std::string id = d.submit(cfg);
  ASSERT_FALSE(id.empty());
  json run = d.waitDone(id);
  ASSERT_EQ(run.value("status", ""), "finished") << d.log();
  json front = d.get("/api/v1/runs/" + id + "/front").j();
  const size_t points = front["members"].size();
  ASSERT_GT(points, 0u);
  const size_t member = points - 1;
#ifdef LGPD_TEST_HAVE_EMIT
  // The references come back scored (by the job, stored with the front); the overflowing
  // one has no finite error.
  ASSERT_TRUE(front["references"].is_array()) << front.dump().substr(0, 2000);
  ASSERT_EQ(front["references"].size(), 3u) << front["references"].dump();
  const json& costly = front["references"][1];
  ASSERT_TRUE(costly["cost"].is_number()) << costly.dump();
  ASSERT_TRUE(front["references"][0]["error"].is_number()) << front["references"][0].dump();
  EXPECT_TRUE(front["references"][2].contains("error") && front["references"][2]["error"].is_null())
      << front["references"][2].dump();
  for (const auto& r : front["references"]) EXPECT_FALSE(r.contains("pending")) << r.dump();
  double max_cost = 0;
  for (const auto& m : front["members"]) max_cost = std::max(max_cost, m["cost"].get<double>());
  ASSERT_GT(costly["cost"].get<double>(), max_cost)
      << "the costly reference must lie outside the members' cost range";
  const size_t drawn_refs = 2;
#else
  const size_t drawn_refs = 0;  // not scored without the parser: listed, not drawn
#endif
  size_t flagged = 0;
  for (const auto& m : front["members"])
    if (m.contains("cancellation") && m["cancellation"].value("flagged", false)) ++flagged;
  const std::string url = d.url() + "/?run=" + id + "&member=" + std::to_string(member);

  // DOM after the page's scripts ran.
  auto args = chromiumArgs(chromium, tmp.path() / "profile-dom");
  args.insert(args.end(), {"--virtual-time-budget=5000", "--dump-dom", url});
  std::string dom;
  int code = runProgram(args, &dom, tmp.path() / "chromium.log", 120);
  ASSERT_EQ(code, 0) << "chromium failed; see " << (tmp.path() / "chromium.log");
  ASSERT_FALSE(dom.empty());
  EXPECT_EQ(attrOf(dom, "runs", "data-count"), "1") << dom.substr(0, 2000);
  EXPECT_EQ(attrOf(dom, "pareto", "data-points"), std::to_string(points));
  EXPECT_EQ(attrOf(dom, "pareto", "data-run"), id);
  EXPECT_EQ(attrOf(dom, "member", "data-member"), std::to_string(member));
  EXPECT_EQ(attrOf(dom, "heatmap", "data-cells"), "256") << "16 x 16 grid";
  EXPECT_NE(dom.find("browser demo"), std::string::npos);
  // Each front member is one clickable marker.
  EXPECT_EQ(countOf(dom, "data-member=\""), points + 1) << "points plus the #member panel";

  // References are drawn inside the plot area (the axes include them).
  EXPECT_EQ(attrOf(dom, "pareto", "data-references"), std::to_string(drawn_refs));
  std::istringstream plot(attrOf(dom, "pareto", "data-plot"));
  double left = NAN, top = NAN, right = NAN, bottom = NAN;
  plot >> left >> top >> right >> bottom;
  ASSERT_TRUE(plot && left < right && top < bottom) << attrOf(dom, "pareto", "data-plot");
  auto refs = refMarks(dom);
  ASSERT_EQ(refs.size(), drawn_refs);
  for (const auto& r : refs) {
    EXPECT_GE(r.x, left) << r.name;
    EXPECT_LE(r.x, right) << r.name;
    EXPECT_GE(r.y, top) << r.name;
    EXPECT_LE(r.y, bottom) << r.name;
    EXPECT_NEAR(r.path_x, r.x, 0.01) << r.name << ": the diamond sits at the marker";
    EXPECT_NEAR(r.path_y, r.y - 6, 0.01) << r.name;
  }
  if (drawn_refs) {
    EXPECT_EQ(refs[0].name, "exact");
    EXPECT_EQ(refs[1].name, "costly");
    EXPECT_GT(refs[1].x, refs[0].x) << "the costly reference lies right of the exact one";
    EXPECT_NE(dom.find("1 reference not drawn"), std::string::npos) << "the overflowing one";
  }

  // The member list: one row per member with its formula, a copy button and its flag.
  EXPECT_EQ(attrOf(dom, "members", "data-rows"), std::to_string(points));
  const std::string formula = formulaOf(front["members"][member]);
  ASSERT_FALSE(formula.empty());
  EXPECT_NE(dom.find("data-formula=\"" + escapeAttr(formula) + "\">" + escapeText(formula) + "<"),
            std::string::npos)
      << "member " << member << "'s formula in the list: " << formula;
  EXPECT_EQ(attrOf(dom, "formula", "data-formula"), escapeAttr(formula)) << "the member panel";
  EXPECT_EQ(countOf(dom, "<button type=\"button\" class=\"copy\""), points + 1)
      << "a copy button per member and one in the panel";
  EXPECT_NE(dom.find("aria-label=\"copy the formula of member " + std::to_string(member) + "\""),
            std::string::npos);
  const bool member_flagged = front["members"][member].contains("cancellation") &&
                              front["members"][member]["cancellation"].value("flagged", false);
  EXPECT_EQ(countOf(dom, "class=\"badge cancel\""), flagged + (member_flagged ? 1 : 0))
      << "a cancellation badge per flagged member (list and panel)";
  EXPECT_EQ(countOf(dom, "class=\"cancring\""), flagged) << "and a ring on the plot";

  // Screenshot for a human (and the report).
  fs::path png = fs::path(LGPD_TEST_OUT) / "lgpd-page.png";
  std::error_code ec;
  fs::remove(png, ec);
  args = chromiumArgs(chromium, tmp.path() / "profile-shot");
  args.insert(args.end(), {"--virtual-time-budget=5000", "--window-size=1400,1400",
                           "--hide-scrollbars", "--screenshot=" + png.string(), url});
  std::string out;
  code = runProgram(args, &out, tmp.path() / "chromium.log", 120);
  EXPECT_EQ(code, 0);
  ASSERT_TRUE(fs::exists(png)) << "no screenshot at " << png;
  EXPECT_GT(fs::file_size(png), 10000u);
  std::printf("screenshot: %s\n", png.c_str());
  EXPECT_EQ(d.stop(), 0);
}

}  // namespace
}  // namespace lgpd_test
