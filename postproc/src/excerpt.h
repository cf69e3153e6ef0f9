// accura post-processor (internal): the excerpt of a program's text that a reader's message
// quotes. A statement of 40 KB (20000 nested brackets, a runaway string) is named by its start:
// the message stays a line that a terminal, a log and the JSON report can hold.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

namespace accura::postproc::detail {

/// The longest text a reader's message quotes (bytes, the ellipsis included).
constexpr size_t kMaxQuoted = 80;

/// `s` when it has at most kMaxQuoted bytes; else its start, cut before a UTF-8 character that
/// would not fit, and "...", kMaxQuoted bytes at most.
inline std::string excerpt(std::string_view s) {
  if (s.size() <= kMaxQuoted) return std::string(s);
  size_t n = kMaxQuoted - 3;
  while (n > 0 && (static_cast<unsigned char>(s[n]) & 0xC0) == 0x80) --n;  // s[n] continues a character
  return std::string(s.substr(0, n)) + "...";
}

}  // namespace accura::postproc::detail
