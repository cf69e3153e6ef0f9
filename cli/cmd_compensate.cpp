// accura compensate: one program (KRL .src/.dat or XML) compensated with a calibrated model.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "accura/calib/errors.h"
#include "accura/calib/robot_io.h"
#include "accura/postproc/batch.h"
#include "accura/postproc/job.h"
#include "accura/postproc/program_io.h"
#include "accura/postproc/check.h"
#include "cli_util.h"
#include "cmd_check.h"
#include "commands.h"

namespace fs = std::filesystem;

namespace accura::cli {

// Shared with cmd_batch.cpp (declared there): the options that make a JobSettings, and the
// JSON of a JobReport (file names relative to `relative_to` when not empty).
std::function<postproc::JobSettings()> addJobOptions(CLI::App* c);
nlohmann::ordered_json jobReportJson(const postproc::JobReport& r, const std::string& relative_to);

namespace {

struct JobArgs {
  std::string robot;
  double tol_mm = 0.05;
  std::string base;
  std::string robroot;
  double payload_kg = 0;
  double temp_c = kThermalReferenceC;
  std::string program_tool;
  std::string program_base;
};

struct CompensateArgs {
  std::function<postproc::JobSettings()> settings;
  std::string in;
  std::string dat;
  std::string config;
  std::string out;
  std::string json;
  std::function<std::optional<CellCheck>()> cell;  // --cell: checks before writing (cmd_check.cpp)
  bool warn_only = false;
};

// Rounded to 1e-6 (nm, udeg): the report is the same on every machine.
nlohmann::ordered_json rounded(double v) {
  if (!std::isfinite(v)) return nullptr;
  const double r = std::round(v * 1e6) / 1e6;
  return r == 0 ? 0.0 : r;
}

std::string fileFor(const std::string& file, const std::string& relative_to) {
  if (relative_to.empty() || file.empty()) return file;
  std::error_code ec;
  const fs::path rel = fs::relative(file, relative_to, ec);
  return ec || rel.empty() ? file : rel.generic_string();
}

void where(nlohmann::ordered_json& j, const postproc::SourceLocation& w, const std::string& relative_to) {
  j["file"] = fileFor(w.file, relative_to);
  j["line"] = w.line;
  j["column"] = w.column;
}

nlohmann::ordered_json pose(const XyzAbc& p) {
  return {{"x_mm", rounded(p.x_mm)}, {"y_mm", rounded(p.y_mm)}, {"z_mm", rounded(p.z_mm)},
          {"a_deg", rounded(p.a_deg)}, {"b_deg", rounded(p.b_deg)}, {"c_deg", rounded(p.c_deg)}};
}

bool sameFile(const std::string& a, const std::string& b) {
  std::error_code ec;
  if (fs::exists(a, ec) && fs::exists(b, ec)) return fs::equivalent(a, b, ec);
  return fs::weakly_canonical(fs::absolute(a), ec) == fs::weakly_canonical(fs::absolute(b), ec);
}

int runCompensate(const CompensateArgs& a) {
  using namespace postproc;
  const JobSettings settings = a.settings();
  // --cell: the program is checked in its cell before anything is written (the shared logic
  // of compensate --cell and batch --cell: compensateAndCheckFile); its robot placement is
  // where the OLP placed the robot (unless --base says it)
  const std::optional<CellCheck> cell = a.cell();
  if (a.warn_only && !cell) throw InputError("--warn-only: expected together with --cell, found it without");
  std::optional<CellCheckSettings> cell_settings;
  if (cell) cell_settings = CellCheckSettings{cell->cell, cell->options, a.warn_only, nullptr};
  ProgramReadOptions read;
  read.dat_path = a.dat;
  read.config_path = a.config;
  programFormat(a.in);  // a clear error for another extension before anything else
  std::error_code ec;
  if (fs::exists(a.out, ec) && !fs::is_directory(a.out, ec))
    throw InputError("--out: expected a directory, found the file " + a.out);
  const std::string out_path = (fs::path(a.out) / fs::path(a.in).filename()).string();
  JobReport report;
  CheckedProgram checked = compensateAndCheckFile(a.in, out_path, read, settings, cell_settings ? &*cell_settings : nullptr, &report);
  const std::vector<OutputFile>& files = checked.files;
  std::vector<std::string> inputs = {a.in};
  if (!a.dat.empty()) inputs.push_back(a.dat);
  if (!a.config.empty()) inputs.push_back(a.config);
  for (const auto& f : files) {
    const std::string dat_guess = fs::path(a.in).replace_extension(".dat").string();
    for (const auto& in : inputs)
      if (sameFile(f.path, in)) throw InputError(f.path + ": the output would overwrite the input " + in + ": choose another --out");
    if (fs::exists(dat_guess, ec) && sameFile(f.path, dat_guess))
      throw InputError(f.path + ": the output would overwrite the input " + dat_guess + ": choose another --out");
  }
  if (!a.json.empty())
    for (const auto& in : inputs)
      if (sameFile(a.json, in)) throw InputError("--json: " + a.json + " would overwrite the input " + in);
  // a violation keeps the program off the disk (exit kCheckFailed, report printed and in
  // --json) unless --warn-only.
  const std::optional<postproc::CheckReport>& check = checked.check;
  const bool blocked = !checked.write;
  installInterruptCleanup();
  if (!blocked) {
    fs::create_directories(a.out);
    writeFilesAtomically(files);
  }
  for (const auto& w : report.warnings) std::cerr << "accura: warning: " << w.where.str() << ": " << w.message << "\n";
  std::printf("accura compensate: %s, tol %.4f mm\n", a.in.c_str(), settings.tol_mm);
  for (const auto& s : report.segments) {
    std::printf("  %-28s %-5s %9.1f mm  path error %.4f mm as programmed, %.4f mm endpoints compensated, %.4f mm written (%d point(s) added)%s\n",
                s.motion.str().c_str(), s.motion_type.c_str(), s.length_mm, s.max_error_uncompensated_mm, s.max_error_before_mm,
                s.max_error_after_mm, s.points_added, s.note.empty() ? "" : ("; " + s.note).c_str());
  }
  std::printf("targets corrected: %d (max %.4f mm, RMS %.4f mm, max %.5f deg); auxiliary points added: %d\n", report.targets_corrected,
              report.max_correction_mm, report.rms_correction_mm, report.max_correction_deg, report.points_added);
  if (!report.segments.empty())
    std::printf("largest path error: %.4f mm as programmed -> %.4f mm endpoints compensated -> %.4f mm written\n",
                report.max_error_uncompensated_mm, report.max_error_before_mm, report.max_error_after_mm);
  if (check) printCheckReport(*check, a.in);
  if (!checked.compensation_error.empty())
    std::printf("not written: the program failed the checks of %s and cannot be compensated (so not even with --warn-only): %s\n",
                cell->cell_path.c_str(), checked.compensation_error.c_str());
  else if (blocked) std::printf("not written: the program failed the checks of %s (--warn-only writes it anyway)\n", cell->cell_path.c_str());
  else if (check && !check->passed()) std::fprintf(stderr, "accura: warning: the program failed the checks of %s; written because of --warn-only\n", cell->cell_path.c_str());
  if (!blocked)
    for (const auto& f : files) std::printf("wrote %s\n", f.path.c_str());
  if (!a.json.empty()) {
    nlohmann::ordered_json j;
    j["program"] = a.in;
    nlohmann::ordered_json outs = nlohmann::ordered_json::array();
    if (!blocked)
      for (const auto& f : files) outs.push_back(f.path);
    j["outputs"] = outs;
    j["robot"] = settings.calibrated.nominal.name;
    j["tol_mm"] = rounded(settings.tol_mm);
    j.update(jobReportJson(report, ""));
    if (!checked.compensation_error.empty()) j["compensation_error"] = checked.compensation_error;
    if (check) j["check"] = checkReportJson(*check);
    writeFilesAtomically({{a.json, j.dump(2) + "\n"}});
    std::printf("wrote %s\n", a.json.c_str());
  }
  return blocked ? kCheckFailed : 0;
}

postproc::JobSettings jobSettings(const JobArgs& a) {
  postproc::JobSettings s;
  s.calibrated = loadRobot(a.robot);
  if (!(a.tol_mm > 0) || !std::isfinite(a.tol_mm)) throw InputError("--tol: expected a positive distance (mm), found " + fmt("%g", a.tol_mm));
  s.tol_mm = a.tol_mm;
  if (!a.base.empty()) s.robroot_in_world = parseXyzAbc(a.base, "--base");
  if (!a.robroot.empty()) s.robroot_in_kukaworld = parseXyzAbc(a.robroot, "--robroot");
  if (!(a.payload_kg >= 0) || !std::isfinite(a.payload_kg)) throw InputError("--payload-kg: expected a mass >= 0, found " + fmt("%g", a.payload_kg));
  if (!std::isfinite(a.temp_c)) throw InputError("--temp-c: expected a temperature (deg C)");
  s.context.payload_kg = a.payload_kg;
  s.context.temp_c = a.temp_c;
  if (!a.program_tool.empty()) s.initial_tool = parseXyzAbc(a.program_tool, "--program-tool");
  if (!a.program_base.empty()) s.initial_base = parseXyzAbc(a.program_base, "--program-base");
  return s;
}

}  // namespace

std::function<postproc::JobSettings()> addJobOptions(CLI::App* c) {
  auto args = std::make_shared<JobArgs>();
  JobArgs& a = *args;
  c->add_option("--robot", a.robot, "calibrated model (written by accura identify), file or bundled name")->required();
  c->add_option("--tol", a.tol_mm, "bound on the predicted path error of LIN/CIRC motions (mm)")->capture_default_str();
  c->add_option("--base", a.base, "where the OLP placed the robot in the model's world: x,y,z,A,B,C (mm, deg); default: the robot file's <base>");
  c->add_option("--robroot", a.robroot, "the controller's $ROBROOT (robot base in its $WORLD) x,y,z,A,B,C; default: identity");
  c->add_option("--payload-kg", a.payload_kg, "payload while the program runs (kg), for compliance models")->capture_default_str();
  c->add_option("--temp-c", a.temp_c, "arm temperature while the program runs (deg C), for thermal models")->capture_default_str();
  c->add_option("--program-tool", a.program_tool, "$TOOL x,y,z,A,B,C for motions before the program sets one (the controller's active tool)");
  c->add_option("--program-base", a.program_base, "$BASE x,y,z,A,B,C for motions before the program sets one (the controller's active base)");
  return [args]() { return jobSettings(*args); };
}

nlohmann::ordered_json jobReportJson(const postproc::JobReport& r, const std::string& relative_to) {
  using nlohmann::ordered_json;
  ordered_json j;
  j["frames"] = {{"nominal_base_in_world", pose(r.robroot_in_world)}, {"calibrated_base_in_world", pose(r.calibrated_base_in_world)}};
  ordered_json targets = ordered_json::array();
  for (const auto& t : r.targets) {
    ordered_json x;
    where(x, t.where, relative_to);
    x["motion_line"] = t.motion.line;
    x["motion"] = t.motion_type;
    x["name"] = t.name;
    x["role"] = t.role;
    x["correction_mm"] = rounded(t.correction_mm);
    x["correction_deg"] = rounded(t.correction_deg);
    x["dx_mm"] = rounded(t.dx_mm);
    x["dy_mm"] = rounded(t.dy_mm);
    x["dz_mm"] = rounded(t.dz_mm);
    x["tool"] = t.calibrated_tool ? "calibrated" : "program";
    targets.push_back(x);
  }
  j["targets"] = targets;
  ordered_json segments = ordered_json::array();
  for (const auto& s : r.segments) {
    ordered_json x;
    where(x, s.motion, relative_to);
    x["motion"] = s.motion_type;
    x["length_mm"] = rounded(s.length_mm);
    x["max_error_uncompensated_mm"] = rounded(s.max_error_uncompensated_mm);
    x["max_error_before_mm"] = rounded(s.max_error_before_mm);
    x["max_error_after_mm"] = rounded(s.max_error_after_mm);
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
                 {"max_correction_mm", rounded(r.max_correction_mm)},
                 {"rms_correction_mm", rounded(r.rms_correction_mm)},
                 {"max_correction_deg", rounded(r.max_correction_deg)},
                 {"segments", r.segments.size()},
                 {"points_added", r.points_added},
                 {"max_error_uncompensated_mm", rounded(r.max_error_uncompensated_mm)},
                 {"max_error_before_mm", rounded(r.max_error_before_mm)},
                 {"max_error_after_mm", rounded(r.max_error_after_mm)}};
  return j;
}

void addCompensateCommand(CLI::App& app) {
  auto args = std::make_shared<CompensateArgs>();
  auto* c = app.add_subcommand("compensate", "compensate a robot program (KRL .src/.dat or XML) with a calibrated model");
  args->settings = addJobOptions(c);
  c->add_option("--in", args->in, "program: PROG.src (KRL, with PROG.dat next to it) or PROG.xml")->required();
  c->add_option("--dat", args->dat, "the KRL .dat (default: the .src's name with .dat)");
  c->add_option("--config", args->config, "$config.dat: TOOL_DATA, BASE_DATA and global points such as XHOME");
  c->add_option("--out", args->out, "output directory (the program keeps its file names)")->required();
  c->add_option("--json", args->json, "report: per target its correction, per segment the path error before and after");
  args->cell = addCellOptions(c, false, false);
  c->add_flag("--warn-only", args->warn_only, "with --cell: write the program even when a check fails (exit 0, warnings)");
  c->callback([=]() { exitCode() = runCompensate(*args); });
}

}  // namespace accura::cli
