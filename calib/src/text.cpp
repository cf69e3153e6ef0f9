#include "accura/calib/text.h"

#include <cmath>
#include <cstdio>
#include <vector>

#include "accura/calib/errors.h"

namespace accura::calib {

std::string xmlEscape(const std::string& s) {
  std::string o;
  o.reserve(s.size());
  for (char c : s) {
    switch (c) {
      case '&': o += "&amp;"; break;
      case '<': o += "&lt;"; break;
      case '>': o += "&gt;"; break;
      case '"': o += "&quot;"; break;
      default: o += c;
    }
  }
  return o;
}

std::string formatNumber(const char* format, double v) {
  char buf[64];
  const int n = std::snprintf(buf, sizeof buf, format, v);
  if (n < 0) return "";
  if (static_cast<size_t>(n) < sizeof buf) return buf;
  std::vector<char> big(static_cast<size_t>(n) + 1);  // "%.4f" of 1e300: about 300 characters
  std::snprintf(big.data(), big.size(), format, v);
  return big.data();
}

std::string formatFixed(double v, int decimals) {
  if (!std::isfinite(v)) throw ArgumentError("formatFixed: not a finite number");
  if (decimals < 0 || decimals > 17) throw ArgumentError("formatFixed: decimals must be in 0..17");
  char format[8];
  std::snprintf(format, sizeof format, "%%.%df", decimals);
  std::string s = formatNumber(format, v);
  // Never "-0.0000": a value that rounds to zero is written without a sign.
  if (!s.empty() && s[0] == '-' && s.find_first_not_of("0.", 1) == std::string::npos) s.erase(0, 1);
  return s;
}

bool isPlainText(const std::string& s) {
  size_t i = 0;
  while (i < s.size()) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    if ((c < 0x20 && c != '\t') || c == 0x7F) return false;
    size_t n = 0;  // continuation bytes
    if (c < 0x80) n = 0;
    else if ((c >> 5) == 0x6) n = 1;
    else if ((c >> 4) == 0xE) n = 2;
    else if ((c >> 3) == 0x1E) n = 3;
    else return false;
    for (size_t k = 1; k <= n; ++k)
      if (i + k >= s.size() || (static_cast<unsigned char>(s[i + k]) >> 6) != 0x2) return false;
    i += n + 1;
  }
  return true;
}

std::string upperAscii(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

std::string trimBlanks(const std::string& s) {
  const size_t first = s.find_first_not_of(" \t\r");
  if (first == std::string::npos) return "";
  return s.substr(first, s.find_last_not_of(" \t\r") - first + 1);
}

std::string printableBytes(const std::string& s) {
  static const char* const kHex = "0123456789ABCDEF";
  std::string out;
  for (char ch : s) {
    const unsigned char c = static_cast<unsigned char>(ch);
    if (c < 0x20 || c >= 0x7F) out += std::string("\\x") + kHex[c >> 4] + kHex[c & 0xF];
    else out += ch;
  }
  return out;
}

}  // namespace accura::calib
