#include "accura/calib/errors.h"

namespace accura::calib {

std::string formatLocation(const std::string& file, int line, int column) {
  std::string out;
  if (!file.empty()) out += file;
  if (line > 0) out += (out.empty() ? "" : ":") + std::to_string(line);
  if (line > 0 && column > 0) out += ":" + std::to_string(column);
  if (!out.empty()) out += ": ";
  return out;
}

namespace {
// A NUL byte from a file (a binary or corrupted one) would end the message where what() is
// printed as a C string: shown as \0.
std::string withoutNul(std::string s) {
  for (size_t p = s.find('\0'); p != std::string::npos; p = s.find('\0', p + 2)) s.replace(p, 1, "\\0");
  return s;
}
}  // namespace

InputError::InputError(std::string file, int line, int column, const std::string& message)
    : std::runtime_error(withoutNul(formatLocation(file, line, column) + message)),
      file_(std::move(file)),
      line_(line),
      column_(column),
      message_(withoutNul(message)) {}

InputError::InputError(const std::string& message)
    : std::runtime_error(withoutNul(message)), message_(withoutNul(message)) {}

}  // namespace accura::calib
