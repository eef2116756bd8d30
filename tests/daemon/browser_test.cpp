// The inspection page in headless Chromium against a live lgpd: the run list and the Pareto
// plot render with the expected number of points, the selected member's panel and the
// residual heatmap fill in, and a screenshot is saved under the build directory
// (tests/daemon/lgpd-page.png). Skipped with a message when chromium is not installed.
#include <regex>

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

TEST(Browser, PageRendersRunsParetoMemberAndHeatmap) {
  const std::string chromium = findChromium();
  if (chromium.empty()) GTEST_SKIP() << "chromium not installed (scripts/lgp.sh deps installs it)";

  TempDir tmp("browser");
  fs::path table = writeGridTable(tmp.path(), 16);
  Daemon d(tmp.path() / "state");
  ASSERT_TRUE(d.start());
  json cfg = runConfig(table, 40, 64, 3);
  cfg["name"] = "browser demo";
  std::string id = d.submit(cfg);
  ASSERT_FALSE(id.empty());
  json run = d.waitDone(id);
  ASSERT_EQ(run.value("status", ""), "finished") << d.log();
  json front = d.get("/api/v1/runs/" + id + "/front").j();
  const size_t points = front["members"].size();
  ASSERT_GT(points, 0u);
  const size_t member = points - 1;
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
  size_t markers = 0;
  for (size_t p = dom.find("data-member=\""); p != std::string::npos;
       p = dom.find("data-member=\"", p + 1))
    ++markers;
  EXPECT_EQ(markers, points + 1) << "points plus the #member panel";

  // Screenshot for a human (and the report).
  fs::path png = fs::path(LGPD_TEST_OUT) / "lgpd-page.png";
  std::error_code ec;
  fs::remove(png, ec);
  args = chromiumArgs(chromium, tmp.path() / "profile-shot");
  args.insert(args.end(), {"--virtual-time-budget=5000", "--window-size=1400,1000",
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
