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

InputError::InputError(std::string file, int line, int column, const std::string& message)
    : std::runtime_error(formatLocation(file, line, column) + message),
      file_(std::move(file)),
      line_(line),
      column_(column),
      message_(message) {}

InputError::InputError(const std::string& message)
    : std::runtime_error(message), message_(message) {}

}  // namespace accura::calib
