// Escape sequences that make a terminal act (hardening round 3, F5), and the check that text
// printed from a file or a server holds none of them. Shared by the CLI tests of core/ and
// daemon/.
#pragma once

#include <string>

namespace lgp_test {

// Title, clear-screen, OSC 52 clipboard write, OSC 8 hyperlink, and a C1 CSI (U+009B).
inline const std::string kTitle = "\x1b]0;pwned\x07";
inline const std::string kClear = "\x1b[2J";
inline const std::string kClipboard = "\x1b]52;c;ZWNobyBwd25lZA==\x07";
inline const std::string kLink = "\x1b]8;;http://evil.example\x1b\\click\x1b]8;;\x1b\\";
inline const std::string kCsi =
    "\xc2\x9b"
    "31m";

// Whether `s` holds anything a terminal acts on: C0 controls other than newline, DEL, or a C1
// control (U+0080..U+009F as UTF-8).
inline bool actsOnTerminal(const std::string& s) {
  for (size_t i = 0; i < s.size(); ++i) {
    const auto c = static_cast<unsigned char>(s[i]);
    if ((c < 0x20 && c != '\n') || c == 0x7f) return true;
    if (c == 0xc2 && i + 1 < s.size() && static_cast<unsigned char>(s[i + 1]) >= 0x80 &&
        static_cast<unsigned char>(s[i + 1]) <= 0x9f)
      return true;
  }
  return false;
}

}  // namespace lgp_test
