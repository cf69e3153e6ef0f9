// accura: small text helpers shared by the writers of every layer, and the one number
// formatter (calib, postproc, the command line and the plug-in format numbers here).
#pragma once

#include <string>

namespace accura::calib {

/// `s` with & < > " replaced by their entities: safe in XML and HTML text and in
/// double-quoted attribute values.
std::string xmlEscape(const std::string& s);

/// True when `s` is valid UTF-8 and holds no control character other than a tab (no NUL, CR,
/// LF, DEL): text that an XML reader gives back as it is. Never throws.
bool isPlainText(const std::string& s);

/// `s` for a message: every byte below 0x20, 0x7F and every byte of 0x80 and above as \xNN
/// (upper-case hex), the rest as it is. Never throws but std::bad_alloc.
std::string printableBytes(const std::string& s);

/// `s` with its ASCII letters in upper case, every other byte as it is (the names of the
/// case-insensitive program languages: KRL, RAPID).
std::string upperAscii(std::string s);

/// `s` without its leading and trailing blanks (space, tab, CR); "" when it is all blanks.
std::string trimBlanks(const std::string& s);

/// A number with a fixed count of decimals ("%.*f"), never "-0.000" (a value that rounds to
/// zero is written without a sign): the same text on every machine. Throws ArgumentError for a
/// NaN or infinity (the writers must not write one) and for decimals outside 0..17.
std::string formatFixed(double v, int decimals);

/// "{v0, v1, ...}": every value formatFixed(v, decimals), ", " between them (joint values in
/// messages). `values`: anything with size() and operator[] (std::vector<double>,
/// Eigen::VectorXd). Throws as formatFixed.
template <class Values>
std::string formatList(const Values& values, int decimals) {
  std::string s = "{";
  for (decltype(values.size()) i = 0; i < values.size(); ++i) s += (i ? ", " : "") + formatFixed(values[i], decimals);
  return s + "}";
}

/// One number formatted printf-style: `format` holds exactly one conversion of a double (e.g.
/// "%.4f", "%g", "%8.3f mm"). For messages and tables; NaN and infinity as printf writes them.
std::string formatNumber(const char* format, double v);

}  // namespace accura::calib
