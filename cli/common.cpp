#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include "accura/calib/errors.h"
#include "accura/calib/file_io.h"
#include "cli_util.h"
#include "commands.h"

namespace accura::cli {
namespace {
std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t") - b + 1);
}
}  // namespace

int& exitCode() {
  static int code = 0;
  return code;
}

void writeTextAtomically(const std::string& path, const std::string& text) {
  calib::writeFileAtomically(path, text);
}

std::vector<std::string> splitList(const std::string& text, const std::string& what) {
  std::vector<std::string> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    item = trim(item);
    if (item.empty()) throw calib::InputError(what + ": expected a comma-separated list, found an empty item in '" + text + "'");
    out.push_back(item);
  }
  if (out.empty()) throw calib::InputError(what + ": expected a comma-separated list, found nothing");
  // (getline does not give the empty item after a trailing comma)
  if (trim(text).back() == ',') throw calib::InputError(what + ": expected a comma-separated list, found an empty item in '" + text + "'");
  return out;
}

std::vector<double> parseNumbers(const std::string& text, const std::string& what, const NumberRange& r) {
  std::vector<double> v;
  for (const auto& item : splitList(text, what)) v.push_back(parseNumber(item, what, r));
  return v;
}

}  // namespace accura::cli
