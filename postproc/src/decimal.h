// accura post-processor (internal): the strict decimal numbers of the cell file and the mesh
// readers. strtod alone also takes hex ("0x1p3"), "inf", "nan", leading blanks and nothing at
// all (" " reads as 0 when only the end pointer is checked after skipping blanks).
#pragma once

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <string>
#include <string_view>

#include "excerpt.h"

namespace accura::postproc::detail {

/// A decimal number [+-]digits[.digits][(e|E)[+-]digits] (digits on at least one side of the
/// point), nothing before or after it. False for anything else, and for a value that
/// overflows to infinity or underflows (ERANGE: denormals are not a coordinate).
inline bool parseDecimal(std::string_view s, double* v) {
  size_t i = 0;
  const auto digits = [&]() {
    size_t n = 0;
    while (i < s.size() && std::isdigit(static_cast<unsigned char>(s[i]))) ++i, ++n;
    return n;
  };
  if (i < s.size() && (s[i] == '+' || s[i] == '-')) ++i;
  size_t mantissa = digits();
  if (i < s.size() && s[i] == '.') {
    ++i;
    mantissa += digits();
  }
  if (mantissa == 0) return false;
  if (i < s.size() && (s[i] == 'e' || s[i] == 'E')) {
    ++i;
    if (i < s.size() && (s[i] == '+' || s[i] == '-')) ++i;
    if (digits() == 0) return false;
  }
  if (i != s.size()) return false;
  const std::string text(s);
  errno = 0;
  const double x = std::strtod(text.c_str(), nullptr);
  if (errno == ERANGE || !std::isfinite(x)) return false;
  *v = x;
  return true;
}

/// The end of the decimal number token that starts at s[i] (a digit, or '.' before a digit):
/// digits[.digits][(e|E)[+-]digits], for the program lexers (URScript, RAPID). An 'e' without
/// exponent digits sets *bad_exponent to the index of the 'e' and returns the index where the
/// digits were expected; otherwise *bad_exponent is npos.
inline size_t scanDecimal(std::string_view s, size_t i, size_t* bad_exponent) {
  const auto digit = [&](size_t k) { return k < s.size() && std::isdigit(static_cast<unsigned char>(s[k])); };
  *bad_exponent = std::string_view::npos;
  size_t j = i;
  while (digit(j)) ++j;
  if (j < s.size() && s[j] == '.') ++j;
  while (digit(j)) ++j;
  if (j < s.size() && (s[j] == 'e' || s[j] == 'E')) {
    size_t k = j + 1;
    if (k < s.size() && (s[k] == '+' || s[k] == '-')) ++k;
    if (!digit(k)) {
      *bad_exponent = j;
      return k;
    }
    while (digit(k)) ++k;
    j = k;
  }
  return j;
}

/// A program lexer's number token at s[i] (a digit, or '.' before a digit; scanDecimal): where it
/// ends, its text and value. A bad exponent or a value beyond a double's range sets `error` (what
/// was expected and found) and `error_at` (the offset it is said at); the lexer fails there.
struct LexedNumber {
  size_t end = 0;
  std::string text;
  double value = 0;
  std::string error;
  size_t error_at = 0;
};
inline LexedNumber lexNumber(std::string_view s, size_t i) {
  LexedNumber n;
  size_t e = 0;
  n.end = scanDecimal(s, i, &e);
  n.text = std::string(s.substr(i, n.end - i));
  if (e != std::string_view::npos) {
    n.error_at = e;
    n.error = "expected the digits of an exponent, found '" + std::string(s.substr(e, std::min(n.end + 1, s.size()) - e)) + "'" +
              (n.end >= s.size() ? " and then the end of the file" : "");  // (a file cut short in the number)
    return n;
  }
  n.value = std::strtod(n.text.c_str(), nullptr);
  if (!std::isfinite(n.value)) {
    n.error_at = i;
    n.error = "expected a finite number, found '" + excerpt(n.text) + "'";
  }
  return n;
}

/// A decimal integer [+-]digits of at most 18 digits (no overflow), nothing before or after.
inline bool parseDecimalInteger(std::string_view s, long long* v) {
  size_t i = 0;
  bool negative = false;
  if (i < s.size() && (s[i] == '+' || s[i] == '-')) negative = s[i++] == '-';
  if (i == s.size() || s.size() - i > 18) return false;
  long long x = 0;
  for (; i < s.size(); ++i) {
    if (!std::isdigit(static_cast<unsigned char>(s[i]))) return false;
    x = x * 10 + (s[i] - '0');
  }
  *v = negative ? -x : x;
  return true;
}

}  // namespace accura::postproc::detail
