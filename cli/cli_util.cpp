#include "cli_util.h"

#include "accura/postproc/job.h"

#include "commands.h"

#include <cctype>
#include <cerrno>
#include <cmath>
#include <filesystem>
#include <cstdio>
#include <iostream>
#include <type_traits>

#include "accura/calib/errors.h"
#include "accura/calib/import.h"
#include "accura/calib/kinematic_core.h"
#include "accura/calib/robot_io.h"
#include "accura/calib/text.h"
#include "accura/calib/urdf.h"

namespace accura::cli {
std::string fmt(const char* f, double v) { return calib::formatNumber(f, v); }

nlohmann::ordered_json num(double v) { return std::isfinite(v) ? nlohmann::ordered_json(v) : nlohmann::ordered_json(nullptr); }

nlohmann::ordered_json statsJson(const calib::ErrorStats& s) {
  nlohmann::ordered_json j;
  j["n"] = s.n;
  j["rms_mm"] = num(s.rms_mm);
  j["mean_mm"] = num(s.mean_mm);
  j["max_mm"] = num(s.max_mm);
  j["p95_mm"] = num(s.p95_mm);
  if (s.has_orientation) {
    j["rot_rms_deg"] = num(s.rot_rms_deg);
    j["rot_mean_deg"] = num(s.rot_mean_deg);
    j["rot_max_deg"] = num(s.rot_max_deg);
    j["rot_p95_deg"] = num(s.rot_p95_deg);
  }
  return j;
}

std::string& robotChainOption() {
  static std::string chain;
  return chain;
}

calib::RobotModel loadRobot(const std::string& name, const std::string& option) {
  std::string path;
  try {
    path = calib::resolveRobotPath(name);
  } catch (const calib::InputError& e) {
    throw calib::InputError(option + ": " + e.what());
  }
  const std::string& chain = robotChainOption();
  if (!chain.empty() && (path.size() < 5 || path.compare(path.size() - 5, 5, ".urdf") != 0))
    throw calib::InputError("--chain " + chain + ": expected a URDF robot (.urdf) with --robot, found '" + name + "'");
  // (no --chain: a .urdf with its default chain)
  calib::RobotModel model = chain.empty() ? calib::readRobotFile(path) : calib::readUrdfRobot(path, chain);
  // the kinematics take at most kMaxDof joints: said with the file, as the plug-in says it
  // (before: "kinematic model: at most 12 joints, got 13" at the first use, without the file)
  if (model.dof() > calib::kMaxDof)
    throw calib::InputError(option + " " + path + ": expected at most " + std::to_string(calib::kMaxDof) + " joints, found " +
                            std::to_string(model.dof()));
  return model;
}

void refuseRepeatedDataFiles(const std::vector<std::string>& files, const std::string& option) {
  for (size_t k = 1; k < files.size(); ++k)
    for (size_t i = 0; i < k; ++i) {
      std::error_code ec;
      if (std::filesystem::equivalent(files[i], files[k], ec) && !ec)
        throw calib::InputError(option + " " + files[k] + ": expected each measurement file once, found the same file as " + option + " " +
                                files[i] + ": its measurements would count twice, as if measured twice (the parameters' sigmas "
                                "too small, every test too significant); give it once");
    }
}

void warnUnknownColumns(const calib::MeasurementSet& set) {
  auto joined = [](const std::vector<std::string>& names) {
    std::string list;
    for (const auto& c : names) list += (list.empty() ? "" : ", ") + c;
    return list;
  };
  if (!set.unknown_columns.empty())
    std::cerr << "accura: warning: " << set.file << ": columns not used by accura: " << joined(set.unknown_columns) << "\n";
  if (!set.ignored_absent_columns.empty())
    std::cerr << "accura: warning: " << set.file << ": columns the mapping lists under 'ignore' that this file does not have: "
              << joined(set.ignored_absent_columns) << "\n";
}

void printStatsRow(const std::string& label, const calib::ErrorStats& s) {
  std::printf("  %-12s %9.4f %9.4f %9.4f %9.4f", label.c_str(), s.rms_mm, s.mean_mm, s.p95_mm, s.max_mm);
  if (s.has_orientation)
    std::printf("   %8.5f %8.5f %8.5f %8.5f", s.rot_rms_deg, s.rot_mean_deg, s.rot_p95_deg, s.rot_max_deg);
  std::printf("\n");
}

calib::MeasurementSet readMeasurements(const std::string& path, const std::string& map_path, const calib::RobotDefinition& robot) {
  calib::MeasurementSet set = map_path.empty()
                           ? calib::readMeasurementsCsv(path, robot)
                           : calib::readMappedMeasurements(path, calib::readMeasurementMapping(map_path, robot), robot);
  warnUnknownColumns(set);
  return set;
}

}  // namespace accura::cli

namespace accura::cli {
namespace {
std::string numberText(double v) { return calib::formatNumber("%g", v); }

std::string expectedNumber(const NumberRange& r) {
  std::string s = "a number ";
  if (std::isinf(r.hi))
    s += (r.lo_open ? "> " : ">= ") + numberText(r.lo);
  else
    s += std::string("in ") + (r.lo_open ? "(" : "[") + numberText(r.lo) + ", " + numberText(r.hi) + "]";
  if (!r.unit.empty()) s += " (" + r.unit + ")";
  return s;
}

// A plain decimal number: digits, one point, an exponent; no hex, no inf/nan, no spaces.
bool plainDecimal(const std::string& t) {
  if (t.empty()) return false;
  for (char ch : t)
    if (!(std::isdigit(static_cast<unsigned char>(ch)) || ch == '.' || ch == '-' || ch == '+' || ch == 'e' || ch == 'E'))
      return false;
  return true;
}

// empty: accepted; else the reason (without the option's name, CLI11 puts it in front)
std::string checkNumber(const std::string& text, const NumberRange& r, double* out) {
  const std::string found = ", found '" + text + "'";
  char* end = nullptr;
  errno = 0;
  const double x = plainDecimal(text) ? std::strtod(text.c_str(), &end) : 0.0;
  if (!plainDecimal(text) || end == text.c_str() || *end != '\0' || !std::isfinite(x) || errno == ERANGE)
    return "expected " + expectedNumber(r) + found;
  const bool inside = (r.lo_open ? x > r.lo : x >= r.lo) && x <= r.hi;
  if (!inside) return "expected " + expectedNumber(r) + found;
  if (out) *out = x;
  return "";
}

template <class Int>
std::string checkInteger(const std::string& text, Int lo, Int hi) {
  const std::string expected =
      "expected an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], found '" + text + "'";
  if (text.empty() || text.size() > 20) return expected;
  for (size_t i = 0; i < text.size(); ++i)
    if (!std::isdigit(static_cast<unsigned char>(text[i])) && !(i == 0 && text[i] == '-' && text.size() > 1))
      return expected;
  errno = 0;
  if (text[0] == '-') {
    if constexpr (std::is_signed<Int>::value) {
      const long long v = std::strtoll(text.c_str(), nullptr, 10);
      if (errno == ERANGE || v < static_cast<long long>(lo) || v > static_cast<long long>(hi)) return expected;
      return "";
    } else {
      return expected;
    }
  }
  const unsigned long long v = std::strtoull(text.c_str(), nullptr, 10);
  if (errno == ERANGE || v > static_cast<unsigned long long>(hi) ||
      (lo > 0 && v < static_cast<unsigned long long>(lo)))
    return expected;
  return "";
}

template <class Int>
CLI::Option* addInteger(CLI::App* c, const std::string& name, Int& value, const std::string& help, Int lo, Int hi) {
  auto* o = c->add_option(name, value, help);
  o->type_name("INTEGER");
  o->check(CLI::Validator([lo, hi](std::string& text) { return checkInteger<Int>(text, lo, hi); },
                          "in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]"));
  return o;
}

const NumberRange kPositionRange{-postproc::kMaxFrameMm, postproc::kMaxFrameMm, false, "mm"};  // 100 m: no robot cell is larger
const NumberRange kAngleRange{-postproc::kMaxFrameDeg, postproc::kMaxFrameDeg, false, "deg"};

calib::XyzAbc parsePose(const std::string& text, const std::string& what, bool three_allowed) {
  const std::vector<std::string> items = splitList(text, what);
  if (items.size() != 6 && !(three_allowed && items.size() == 3))
    throw calib::InputError(what + ": expected " + (three_allowed ? "x,y,z or x,y,z,A,B,C" : "six values x,y,z,A,B,C") +
                     " (mm, deg), found " + std::to_string(items.size()) + " value" + (items.size() == 1 ? "" : "s") +
                     " in '" + text + "'");
  double v[6] = {0, 0, 0, 0, 0, 0};
  for (size_t i = 0; i < items.size(); ++i)
    v[i] = parseNumber(items[i], what + " (" + "xyzABC"[i] + ")", i < 3 ? kPositionRange : kAngleRange);
  return calib::XyzAbc{v[0], v[1], v[2], v[3], v[4], v[5]};
}
}  // namespace

double parseNumber(const std::string& text, const std::string& what, const NumberRange& r) {
  double x = 0;
  const std::string why = checkNumber(text, r, &x);
  if (!why.empty()) throw calib::InputError(what + ": " + why);
  return x;
}

CLI::Option* addNumberOption(CLI::App* c, const std::string& name, double& value, const std::string& help,
                             const NumberRange& r) {
  auto* o = c->add_option(name, value, help);
  std::string range = expectedNumber(r).substr(std::string("a number ").size());
  o->type_name("NUMBER");
  o->check(CLI::Validator([r](std::string& text) { return checkNumber(text, r, nullptr); }, range));
  return o;
}

CLI::Option* addIntegerOption(CLI::App* c, const std::string& name, int& value, const std::string& help, long long lo,
                              long long hi) {
  return addInteger<int>(c, name, value, help, static_cast<int>(lo), static_cast<int>(hi));
}

CLI::Option* addIntegerOption(CLI::App* c, const std::string& name, unsigned long long& value, const std::string& help,
                              unsigned long long lo, unsigned long long hi) {
  return addInteger<unsigned long long>(c, name, value, help, lo, hi);
}

CLI::Option* addConfigOption(CLI::App* c, std::vector<std::string>& paths, const std::string& help) {
  return c->add_option("--config", paths, help)->expected(1)->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
}

calib::XyzAbc parsePose6(const std::string& text, const std::string& what) { return parsePose(text, what, false); }
calib::XyzAbc parseTool(const std::string& text, const std::string& what) { return parsePose(text, what, true); }

}  // namespace accura::cli
