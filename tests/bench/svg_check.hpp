// Checks shared by the tests of SVG output (tests/bench/svg_plot_test.cpp for the plotter,
// tests/datasets/plot_test.cpp for `lgp data --plot`).
#pragma once

#include <gtest/gtest.h>

#include <cctype>
#include <cstring>
#include <locale>
#include <set>
#include <string>
#include <vector>

namespace lgp::svg_check {

inline size_t count(const std::string& s, const std::string& what) {
  size_t n = 0;
  for (size_t i = s.find(what); i != std::string::npos; i = s.find(what, i + what.size())) ++n;
  return n;
}

inline bool entityAt(const std::string& s, size_t i) {
  for (const char* e : {"&amp;", "&lt;", "&gt;", "&quot;", "&apos;"})
    if (s.compare(i, std::strlen(e), e) == 0) return true;
  return false;
}

// A small XML well-formedness check: one root element, tags nest, attributes are single-quoted
// and unique, text and values hold no raw '<', '>' or unknown entity, no NaN/Inf leaks into a
// value. Also the shape asked of every plot: starts with <svg, ends with "</svg>\n".
inline ::testing::AssertionResult wellFormed(const std::string& s) {
  if (s.rfind("<svg", 0) != 0) return ::testing::AssertionFailure() << "does not start with <svg";
  if (s.size() < 7 || s.compare(s.size() - 7, 7, "</svg>\n") != 0)
    return ::testing::AssertionFailure() << "does not end with </svg>\\n";
  std::vector<std::string> open;
  bool rootClosed = false;
  for (size_t i = 0; i < s.size();) {
    if (s[i] == '&') {
      if (!entityAt(s, i)) return ::testing::AssertionFailure() << "bad entity at " << i;
      ++i;
      continue;
    }
    if (s[i] == '>') return ::testing::AssertionFailure() << "raw > at " << i;
    if (s[i] != '<') {
      if (rootClosed && !std::isspace(static_cast<unsigned char>(s[i])))
        return ::testing::AssertionFailure() << "text after the root at " << i;
      ++i;
      continue;
    }
    if (s.compare(i, 4, "<!--") == 0) {
      const size_t e = s.find("-->", i);
      if (e == std::string::npos) return ::testing::AssertionFailure() << "open comment";
      i = e + 3;
      continue;
    }
    const size_t e = s.find('>', i);
    if (e == std::string::npos) return ::testing::AssertionFailure() << "open tag at " << i;
    std::string tag = s.substr(i + 1, e - i - 1);
    if (tag.find('<') != std::string::npos)
      return ::testing::AssertionFailure() << "'<' inside tag at " << i;
    if (rootClosed) return ::testing::AssertionFailure() << "second root at " << i;
    if (tag[0] == '/') {
      if (open.empty() || open.back() != tag.substr(1))
        return ::testing::AssertionFailure() << "mismatched </" << tag.substr(1) << "> at " << i;
      open.pop_back();
      rootClosed = open.empty();
    } else {
      const bool self = tag.back() == '/';
      if (self) tag.pop_back();
      size_t p = tag.find_first_of(" \n");
      const std::string name = tag.substr(0, p);
      std::set<std::string> attrs;
      while (p != std::string::npos && p < tag.size()) {
        p = tag.find_first_not_of(" \n", p);
        if (p == std::string::npos) break;
        const size_t eq = tag.find("='", p);
        if (eq == std::string::npos)
          return ::testing::AssertionFailure() << "bad attribute in <" << tag;
        const size_t q = tag.find('\'', eq + 2);
        if (q == std::string::npos) return ::testing::AssertionFailure() << "unquoted in <" << tag;
        const std::string attr = tag.substr(p, eq - p), value = tag.substr(eq + 2, q - eq - 2);
        if (!attrs.insert(attr).second)
          return ::testing::AssertionFailure() << "duplicate " << attr << " in <" << tag;
        if (value.find('>') != std::string::npos || value.find("nan") != std::string::npos ||
            value.find("inf") != std::string::npos)
          return ::testing::AssertionFailure() << "bad value '" << value << "' in <" << tag;
        for (size_t a = value.find('&'); a != std::string::npos; a = value.find('&', a + 1))
          if (!entityAt(value, a)) return ::testing::AssertionFailure() << "entity in " << value;
        p = q + 1;
      }
      if (open.empty() && name != "svg") return ::testing::AssertionFailure() << "root " << name;
      if (!self) open.push_back(name);
      if (self && open.empty()) rootClosed = true;
    }
    i = e + 1;
  }
  if (!open.empty()) return ::testing::AssertionFailure() << "unclosed <" << open.back() << ">";
  if (count(s, "<g ") + count(s, "<g>") != count(s, "</g>"))
    return ::testing::AssertionFailure() << "unbalanced <g>";
  return ::testing::AssertionSuccess();
}

// What de_DE gives a C++ stream: a decimal comma and '.' between thousands. Needs no installed
// locale, so the locale tests always run.
struct CommaDecimal : std::numpunct<char> {
  char do_decimal_point() const override { return ','; }
  char do_thousands_sep() const override { return '.'; }
  std::string do_grouping() const override { return "\3"; }
};

}  // namespace lgp::svg_check
