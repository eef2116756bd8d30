#include "lgp/core/text_check.hpp"

#include <cstdio>

namespace lgp {

std::optional<size_t> firstControlCharacter(std::string_view text) {
  for (size_t i = 0; i < text.size(); ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c < 0x20 || c == 0x7f) return i;
  }
  return std::nullopt;
}

std::string controlCharacterReason(std::string_view text) {
  const auto at = firstControlCharacter(text);
  if (!at) return "";
  char code[8];
  std::snprintf(code, sizeof code, "0x%02X", static_cast<unsigned char>(text[*at]));
  return std::string("has a control character (") + code + " at byte " + std::to_string(*at + 1) +
         "); names and paths must be printable";
}

Status checkNoControlCharacters(std::string_view text, const std::string& what) {
  const std::string why = controlCharacterReason(text);
  return why.empty() ? Status::ok() : Status::error(what + ": " + why);
}

}  // namespace lgp
