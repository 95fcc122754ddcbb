// Strings from outside (file names, ids, messages, what a reader says) on
// their way into the log or an answer: control characters escaped, so a name
// with a newline cannot forge a log line, length capped, so one cannot flood
// it, and bytes that are not UTF-8 escaped where a proto3 string needs it.
#pragma once

#include <fmt/format.h>

#include <string>
#include <string_view>

namespace cinevol {

// The length of the well-formed UTF-8 sequence that starts `text` (1 to 4),
// or 0 where none does: a stray continuation byte, an overlong form, a
// surrogate, a code point past U+10FFFF, a sequence cut short.
inline std::size_t Utf8SequenceLength(std::string_view text) {
  if (text.empty()) return 0;
  const auto byte = [&](std::size_t k) { return static_cast<unsigned char>(text[k]); };
  const unsigned char c = byte(0);
  const std::size_t length = c < 0x80 ? 1 : (c >> 5) == 0x6 ? 2 : (c >> 4) == 0xe ? 3 : (c >> 3) == 0x1e ? 4 : 0;
  if (length == 0 || length > text.size() || (length == 2 && c < 0xc2) || (length == 4 && c > 0xf4)) return 0;
  for (std::size_t k = 1; k < length; ++k) {
    if ((byte(k) >> 6) != 0x2) return 0;
  }
  if (length == 3 && ((c == 0xe0 && byte(1) < 0xa0) || (c == 0xed && byte(1) >= 0xa0))) return 0;
  if (length == 4 && ((c == 0xf0 && byte(1) < 0x90) || (c == 0xf4 && byte(1) >= 0x90))) return 0;
  return length;
}

// `text` with every byte that is not part of a well-formed UTF-8 sequence
// written as \xNN: what a proto3 string (an answer to a client) may hold.
inline std::string ValidUtf8(std::string_view text) {
  std::string out;
  for (std::size_t i = 0; i < text.size();) {
    const std::size_t length = Utf8SequenceLength(text.substr(i));
    if (length == 0) {
      out += fmt::format("\\x{:02x}", static_cast<unsigned char>(text[i]));
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
