#include "cli_util.h"

#include <cmath>
#include <cstdio>
#include <iostream>

#include "accura/calib/errors.h"
#include "accura/calib/import.h"
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

calib::RobotModel loadRobot(const std::string& name) {
  const std::string path = calib::resolveRobotPath(name);
  const std::string& chain = robotChainOption();
  if (chain.empty()) return calib::readRobotFile(path);  // a .urdf with its default chain
  if (path.size() < 5 || path.compare(path.size() - 5, 5, ".urdf") != 0)
    throw calib::InputError("--chain " + chain + ": expected a URDF robot (.urdf) with --robot, found '" + name + "'");
  return calib::readUrdfRobot(path, chain);
}

void warnUnknownColumns(const calib::MeasurementSet& set) {
  if (set.unknown_columns.empty()) return;
  std::string list;
  for (const auto& c : set.unknown_columns) list += (list.empty() ? "" : ", ") + c;
  std::cerr << "accura: warning: " << set.file << ": columns not used by accura: " << list << "\n";
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
