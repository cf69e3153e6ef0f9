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

}  // namespace accura::calib
