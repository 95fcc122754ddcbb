// Client-supplied strings (file names, ids, messages) on their way into the
// log: control characters escaped, so a name with a newline cannot forge a
// log line, and length capped, so one cannot flood it.
#pragma once

#include <fmt/format.h>

#include <string>
#include <string_view>

namespace cinevol {

inline std::string LogSafe(std::string_view text, std::size_t max_length = 200) {
  std::string out;
  for (std::size_t i = 0; i < text.size() && i < max_length; ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c < 0x20 || c == 0x7f || c == '\\') {
      out += c == '\\' ? std::string("\\\\") : fmt::format("\\x{:02x}", c);
    } else {
      out += char(c);
    }
  }
  if (text.size() > max_length) out += fmt::format("...({} bytes)", text.size());
  return out;
}

}  // namespace cinevol
