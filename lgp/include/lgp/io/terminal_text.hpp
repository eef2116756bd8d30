// Text from a file or a server on its way to a terminal. A front's names, a daemon's run names
// and messages may hold escape sequences that set the window title, clear the screen, write
// the clipboard (OSC 52) or hide a link; printed raw, the terminal would run them.
#pragma once

#include <string>
#include <string_view>

#include <nlohmann/json_fwd.hpp>

namespace lgp {

// `text` with every C0 control (newline and tab too), DEL and byte that is not part of valid
// UTF-8 written as \xNN, and every C1 control (U+0080..U+009F) as \u00NN; printable text,
// non-ASCII letters included, is unchanged. A backslash stays as it is.
std::string terminalSafe(std::string_view text);

// JSON for a terminal: indented by 2, every non-ASCII character and control written as a
// \uXXXX escape (still the same JSON value), invalid UTF-8 replaced.
std::string terminalJson(const nlohmann::json& j);

}  // namespace lgp
