// accura post-processor: the JSON reports, written once for every caller. `accura compensate
// --json`, the plug-in's accura_compensate_program (json_report_path), `accura batch --json`
// (per file) and `accura check --json` all build their JSON here, so that a host that parses
// one parses the others (docs/program-formats.md, "Report"; docs/checks.md, "Report").
//
// Numbers are rounded to 1e-6 (nm, udeg): the report is the same bytes on every machine.
// NaN / infinity are written as null (JSON has neither).
#pragma once

#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "accura/postproc/check.h"
#include "accura/postproc/job.h"

namespace accura::postproc {

/// A number of a report: rounded to 1e-6 (-0 written as 0), null when not finite.
nlohmann::ordered_json reportNumber(double v);

/// The per-program part of the compensation report: frames, targets, segments, warnings,
/// totals. File names relative to `relative_to` when it is not empty (accura batch: the
/// input tree).
nlohmann::ordered_json jobReportJson(const JobReport& r, const std::string& relative_to = "");

/// The JSON of a check report (docs/checks.md, "Report"), file names as jobReportJson.
nlohmann::ordered_json checkReportJson(const CheckReport& r, const std::string& relative_to = "");

/// Everything the report of one compensated program says.
struct CompensationReport {
  std::string program;               ///< the input program as given
  std::vector<std::string> outputs;  ///< the files written (empty when none was)
  std::string robot;                 ///< the calibrated model's robot name
  double tol_mm = 0;                 ///< the path tolerance (mm)
  JobReport job;
  std::string compensation_error;    ///< with a failed check: why it could not be compensated
  std::optional<CheckReport> check;  ///< with a cell
};

/// The report of `accura compensate --json` (and of the plug-in): the text of the file,
/// two-space indented JSON ending in a newline.
std::string compensationReportText(const CompensationReport& r);

}  // namespace accura::postproc
