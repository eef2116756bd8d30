// Column names and data paths come from files and requests written by others and end up in
// messages, logs and the comments of emitted code, where a newline would end the comment
// and start code. Every loader refuses them with a control character in them.
#pragma once

#include <optional>
#include <string>
#include <string_view>

#include "lgp/core/status.hpp"

namespace lgp {

// The offset of the first byte below 0x20 or equal to 0x7f (DEL); nullopt when none.
std::optional<size_t> firstControlCharacter(std::string_view text);

// "has a control character (0x0A at byte 3); names and paths must be printable", or empty
// when `text` has none. The text itself is not quoted.
std::string controlCharacterReason(std::string_view text);

// Ok, or "<what>: has a control character (0x0A at byte 3); names and paths must be
// printable". The text itself is not quoted.
Status checkNoControlCharacters(std::string_view text, const std::string& what);

}  // namespace lgp
