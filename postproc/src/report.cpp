// The JSON reports (see report.h).
#include "accura/calib/json_text.h"
#include "accura/postproc/report.h"

#include <cmath>
#include <filesystem>

namespace fs = std::filesystem;

namespace accura::postproc {
namespace {

using nlohmann::ordered_json;

std::string fileFor(const std::string& file, const std::string& relative_to) {
  if (relative_to.empty() || file.empty()) return file;
  std::error_code ec;
  const fs::path rel = fs::relative(file, relative_to, ec);
  return ec || rel.empty() ? file : rel.generic_string();
}

void where(ordered_json& j, const SourceLocation& w, const std::string& relative_to) {
  j["file"] = fileFor(w.file, relative_to);
  j["line"] = w.line;
  j["column"] = w.column;
}

ordered_json pose(const calib::XyzAbc& p) {
  return {{"x_mm", reportNumber(p.x_mm)},   {"y_mm", reportNumber(p.y_mm)},   {"z_mm", reportNumber(p.z_mm)},
          {"a_deg", reportNumber(p.a_deg)}, {"b_deg", reportNumber(p.b_deg)}, {"c_deg", reportNumber(p.c_deg)}};
}

}  // namespace

ordered_json reportNumber(double v) {
  if (!std::isfinite(v)) return nullptr;
  const double r = std::round(v * 1e6) / 1e6;
  return r == 0 ? 0.0 : r;
}

ordered_json jobReportJson(const JobReport& r, const std::string& relative_to) {
  ordered_json j;
  j["frames"] = {{"nominal_base_in_world", pose(r.robroot_in_world)}, {"calibrated_base_in_world", pose(r.calibrated_base_in_world)}};
  ordered_json targets = ordered_json::array();
  for (const auto& t : r.targets) {
    ordered_json x;
    where(x, t.where, relative_to);
    x["motion_line"] = t.motion.line;
    x["motion"] = t.motion_type;
    x["instruction"] = t.instruction;
    x["name"] = t.name;
    x["role"] = t.role;
    x["correction_mm"] = reportNumber(t.correction_mm);
    x["correction_deg"] = reportNumber(t.correction_deg);
    x["dx_mm"] = reportNumber(t.dx_mm);
    x["dy_mm"] = reportNumber(t.dy_mm);
    x["dz_mm"] = reportNumber(t.dz_mm);
    x["tool"] = t.calibrated_tool ? "calibrated" : "program";
    if (!t.new_point_replaces.empty()) x["new_point_replaces"] = t.new_point_replaces;
    targets.push_back(x);
  }
  j["targets"] = targets;
  ordered_json segments = ordered_json::array();
  for (const auto& s : r.segments) {
    ordered_json x;
    where(x, s.motion, relative_to);
    x["motion"] = s.motion_type;
    x["instruction"] = s.instruction;
    x["length_mm"] = reportNumber(s.length_mm);
    x["max_error_uncompensated_mm"] = reportNumber(s.max_error_uncompensated_mm);
    x["max_error_before_mm"] = reportNumber(s.max_error_before_mm);
    x["max_error_after_mm"] = reportNumber(s.max_error_after_mm);
    x["points_added"] = s.points_added;
    if (!s.note.empty()) x["note"] = s.note;
    segments.push_back(x);
  }
  j["segments"] = segments;
  ordered_json warnings = ordered_json::array();
  for (const auto& w : r.warnings) {
    ordered_json x;
    where(x, w.where, relative_to);
    x["message"] = w.message;
    warnings.push_back(x);
  }
  j["warnings"] = warnings;
  j["totals"] = {{"targets_corrected", r.targets_corrected},
                 {"max_correction_mm", reportNumber(r.max_correction_mm)},
                 {"rms_correction_mm", reportNumber(r.rms_correction_mm)},
                 {"max_correction_deg", reportNumber(r.max_correction_deg)},
                 {"segments", r.segments.size()},
                 {"points_added", r.points_added},
                 {"max_error_uncompensated_mm", reportNumber(r.max_error_uncompensated_mm)},
                 {"max_error_before_mm", reportNumber(r.max_error_before_mm)},
                 {"max_error_after_mm", reportNumber(r.max_error_after_mm)}};
  return j;
}

ordered_json checkReportJson(const CheckReport& r, const std::string& relative_to) {
  ordered_json j;
  j["passed"] = r.passed();
  j["mode"] = toString(r.mode);
  j["thresholds"] = {{"joint_margin_deg", reportNumber(r.thresholds.joint_margin_deg)},
                     {"singular_threshold", reportNumber(r.thresholds.singular_threshold)},
                     {"min_clearance_mm", reportNumber(r.thresholds.min_clearance_mm)}};
  ordered_json v = ordered_json::array();
  for (const auto& x : r.violations) {
    ordered_json e;
    e["check"] = toString(x.kind);
    e["motion_index"] = x.motion_index;
    e["file"] = fileFor(x.where.file, relative_to);
    e["line"] = x.where.line;
    e["motion"] = x.motion_type;
    e["on_path"] = x.on_path;
    e["s"] = reportNumber(x.s);
    e["arc_mm"] = reportNumber(x.arc_mm);
    e["tcp_world_mm"] = {reportNumber(x.p_world_tcp_mm.x()), reportNumber(x.p_world_tcp_mm.y()), reportNumber(x.p_world_tcp_mm.z())};
    ordered_json q = ordered_json::array();
    for (int i = 0; i < x.q.size(); ++i) q.push_back(reportNumber(x.q[i]));
    e["joints"] = q;
    e["value"] = reportNumber(x.value);
    e["limit"] = reportNumber(x.limit);
    e["excess"] = reportNumber(x.excess);
    e["unit"] = x.unit;
    if (x.joint >= 0) e["joint"] = x.joint + 1;
    if (!x.robot_part.empty()) e["robot_part"] = x.robot_part;
    if (!x.obstacle.empty()) e["obstacle"] = x.obstacle;
    e["message"] = x.message;
    v.push_back(e);
  }
  j["violations"] = v;
  ordered_json m = ordered_json::array();
  for (const auto& x : r.motions) {
    ordered_json e;
    e["motion_index"] = x.motion_index;
    e["line"] = x.where.line;
    e["motion"] = x.motion_type;
    e["checked"] = x.checked;
    if (!x.note.empty()) e["note"] = x.note;
    e["samples"] = x.samples;
    e["length_mm"] = reportNumber(x.length_mm);
    e["min_clearance_mm"] = reportNumber(x.min_clearance_mm);
    e["min_sigma"] = reportNumber(x.min_sigma);
    e["min_joint_margin"] = reportNumber(x.min_joint_margin);
    m.push_back(e);
  }
  j["motions"] = m;
  auto issues = [&](const std::vector<ProgramIssue>& list) {
    ordered_json a = ordered_json::array();
    for (const auto& w : list) a.push_back({{"file", fileFor(w.where.file, relative_to)}, {"line", w.where.line}, {"message", w.message}});
    return a;
  };
  j["unchecked"] = issues(r.unchecked);
  j["warnings"] = issues(r.warnings);
  j["totals"] = {{"samples", r.samples},
                 {"distance_queries", r.distance_queries},
                 {"min_clearance_mm", reportNumber(r.min_clearance_mm)},
                 {"min_sigma", reportNumber(r.min_sigma)},
                 {"min_joint_margin", reportNumber(r.min_joint_margin)}};
  return j;
}

std::string compensationReportText(const CompensationReport& r) {
  ordered_json j;
  j["program"] = r.program;
  j["outputs"] = r.outputs;
  j["robot"] = r.robot;
  j["tol_mm"] = reportNumber(r.tol_mm);
  j.update(jobReportJson(r.job, ""));
  if (!r.compensation_error.empty()) j["compensation_error"] = r.compensation_error;
  if (r.check) j["check"] = checkReportJson(*r.check);
  return calib::jsonText(j);
}

}  // namespace accura::postproc
