// Strings from outside (file names, ids, messages, what a reader says) on
// their way into the log or an answer: control characters escaped, so a name
// with a newline cannot forge a log line, length capped, so one cannot flood
// it, and bytes that are not UTF-8 escaped where a proto3 string needs it.
#pragma once

#include <fmt/format.h>

#include <string>
#include <string_view>

namespace cinevol {

// `text` with every byte that is not part of a well-formed UTF-8 sequence
// written as \xNN: what a proto3 string (an answer to a client) may hold.
inline std::string ValidUtf8(std::string_view text) {
  std::string out;
  for (std::size_t i = 0; i < text.size();) {
    const auto c = static_cast<unsigned char>(text[i]);
    const std::size_t length = c < 0x80 ? 1 : (c >> 5) == 0x6 ? 2 : (c >> 4) == 0xe ? 3 : (c >> 3) == 0x1e ? 4 : 0;
    bool ok = length > 0 && i + length <= text.size() && !(length == 2 && c < 0xc2) && !(length == 4 && c > 0xf4);
    for (std::size_t k = 1; ok && k < length; ++k) ok = (static_cast<unsigned char>(text[i + k]) >> 6) == 0x2;
    if (ok && length == 3) {  // no overlong forms, no surrogates
      const auto c1 = static_cast<unsigned char>(text[i + 1]);
      ok = !(c == 0xe0 && c1 < 0xa0) && !(c == 0xed && c1 >= 0xa0);
    }
    if (ok && length == 4) {
      const auto c1 = static_cast<unsigned char>(text[i + 1]);
      ok = !(c == 0xf0 && c1 < 0x90) && !(c == 0xf4 && c1 >= 0x90);
    }
    if (!ok) {
      out += fmt::format("\\x{:02x}", c);
      ++i;
      continue;
    }
    out.append(text.substr(i, length));
    i += length;
  }
  return out;
}

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
