// accura compensate: one program (KRL .src/.dat, XML, URScript or ABB RAPID) compensated with a calibrated model.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <iostream>
#include <memory>

#include "accura/calib/errors.h"
#include "accura/calib/joint_map.h"
#include "accura/calib/robot_io.h"
#include "accura/postproc/batch.h"
#include "accura/postproc/job.h"
#include "accura/postproc/program_io.h"
#include "accura/postproc/report.h"
#include "accura/postproc/check.h"
#include "cli_util.h"
#include "cmd_check.h"
#include "commands.h"

namespace fs = std::filesystem;

namespace accura::cli {

namespace {

struct JobArgs {
  std::string robot;
  double tol_mm = 0.05;
  std::string base;
  std::string robroot;
  double payload_kg = 0;
  double temp_c = calib::kThermalReferenceC;
  std::string program_tool;
  std::string program_base;
  std::string controller;
};

struct CompensateArgs {
  std::function<postproc::JobSettings()> settings;
  std::function<std::vector<std::string>()> model_files;  // --robot, --controller files (never overwritten)
  std::string in;
  std::string dat;
  std::vector<std::string> config;  // --config, once or more (RAPID: the task's other modules)
  std::string out;
  std::string json;
  std::function<std::optional<CellCheck>()> cell;  // --cell: checks before writing (cmd_check.cpp)
  bool warn_only = false;
};

int runCompensate(const CompensateArgs& a) {
  using namespace postproc;
  // a directory of programs given to compensate (one program): said with the command that does it
  std::error_code ec;
  if (fs::is_directory(a.in, ec))
    throw calib::InputError(a.in + ": expected a program file (--in), found a directory; every program of a directory tree: accura batch --in " +
                            a.in + " --out DIR");
  const JobSettings settings = a.settings();
  // --cell: the program is checked in its cell before anything is written (the shared logic
  // of compensate --cell and batch --cell: compensateAndCheckFile); its robot placement is
  // where the OLP placed the robot (unless --base says it)
  const std::optional<CellCheck> cell = a.cell();
  if (a.warn_only && !cell) throw calib::InputError("--warn-only: expected together with --cell, found it without");
  std::optional<CellCheckSettings> cell_settings;
  if (cell) cell_settings = CellCheckSettings{cell->cell, cell->options, a.warn_only, nullptr};
  ProgramFileRequest request;
  request.in_path = a.in;
  request.read.dat_path = a.dat;
  setConfigPaths(request.read, a.config);
  request.out_dir = a.out;
  request.json_path = a.json;
  request.cell = cell_settings ? &*cell_settings : nullptr;
  for (const std::string& f : a.model_files()) request.other_inputs.push_back(f);
  if (cell)
    for (const std::string& f : cell->files()) request.other_inputs.push_back(f);
  calib::installInterruptCleanup();
  const ProgramFileResult result = compensateProgramFile(request, settings);
  const JobReport& report = result.report;
  const std::vector<calib::OutputFile>& files = result.checked.files;
  // a violation keeps the program off the disk (exit kCheckFailed, report printed and in
  // --json) unless --warn-only.
  const std::optional<postproc::CheckReport>& check = result.checked.check;
  const bool blocked = !result.written;
  for (const auto& w : report.warnings) std::cerr << "accura: warning: " << w.where.str() << ": " << w.message << "\n";
  std::printf("accura compensate: %s, tol %.4f mm\n", a.in.c_str(), settings.tol_mm);
  for (const auto& s : report.segments) {
    std::printf("  %-28s %-5s %9.1f mm  path error %.4f mm as programmed, %.4f mm endpoints compensated, %.4f mm written (%d point(s) added)%s\n",
                s.motion.str().c_str(), s.motion_type.c_str(), s.length_mm, s.max_error_uncompensated_mm, s.max_error_before_mm,
                s.max_error_after_mm, s.points_added, s.note.empty() ? "" : ("; " + s.note).c_str());
  }
  std::printf("targets corrected: %d (max %.4f mm, RMS %.4f mm, max %.5f deg); auxiliary points added: %d\n", report.targets_corrected,
              report.max_correction_mm, report.rms_correction_mm, report.max_correction_deg, report.points_added);
  if (report.motions_left_unchanged > 0)
    std::printf("motions left unchanged (what accura cannot evaluate or does not model, such as run-time values; see the warnings): %d\n", report.motions_left_unchanged);
  if (!report.segments.empty())
    std::printf("largest path error: %.4f mm as programmed -> %.4f mm endpoints compensated -> %.4f mm written\n",
                report.max_error_uncompensated_mm, report.max_error_before_mm, report.max_error_after_mm);
  if (check) printCheckReport(*check, a.in);
  if (!result.checked.compensation_error.empty())
    std::printf("not written: the program failed the checks of %s and cannot be compensated (so not even with --warn-only): %s\n",
                cell->cell_path.c_str(), result.checked.compensation_error.c_str());
  else if (blocked) std::printf("not written: the program failed the checks of %s (--warn-only writes it anyway)\n", cell->cell_path.c_str());
  else if (check && !check->passed()) std::fprintf(stderr, "accura: warning: the program failed the checks of %s; written because of --warn-only\n", cell->cell_path.c_str());
  if (!blocked)
    for (const auto& f : files) std::printf("wrote %s\n", f.path.c_str());
  if (!a.json.empty()) std::printf("wrote %s\n", a.json.c_str());
  return blocked ? kCheckFailed : 0;
}

postproc::JobSettings jobSettings(const JobArgs& a) {
  postproc::JobSettings s;
  s.calibrated = loadRobot(a.robot);
  if (!(a.tol_mm > 0) || !std::isfinite(a.tol_mm)) throw calib::InputError("--tol: expected a positive distance (mm), found " + fmt("%g", a.tol_mm));
  s.tol_mm = a.tol_mm;
  if (!a.base.empty()) s.robroot_in_world = parsePose6(a.base, "--base");
  if (!a.robroot.empty()) s.robroot_in_kukaworld = parsePose6(a.robroot, "--robroot");
  if (!(a.payload_kg >= 0) || !std::isfinite(a.payload_kg)) throw calib::InputError("--payload-kg: expected a mass >= 0, found " + fmt("%g", a.payload_kg));
  if (!std::isfinite(a.temp_c)) throw calib::InputError("--temp-c: expected a temperature (deg C)");
  s.context.payload_kg = a.payload_kg;
  s.context.temp_c = a.temp_c;
  if (!a.program_tool.empty()) s.initial_tool = parsePose6(a.program_tool, "--program-tool");
  if (!a.program_base.empty()) s.initial_base = parsePose6(a.program_base, "--program-base");
  if (!a.controller.empty()) s.controller_kinematics = loadRobot(a.controller, "--controller");
  return s;
}

}  // namespace

std::function<postproc::JobSettings()> addJobOptions(CLI::App* c, std::function<std::vector<std::string>()>* model_files) {
  auto args = std::make_shared<JobArgs>();
  if (model_files)
    *model_files = [args]() {
      std::vector<std::string> files;
      std::error_code ec;
      for (const std::string& f : {args->robot, args->controller})
        if (!f.empty() && std::filesystem::is_regular_file(f, ec)) files.push_back(f);
      return files;
    };
  JobArgs& a = *args;
  c->add_option("--robot", a.robot, "calibrated model (written by accura identify), file or bundled name")->required();
  addNumberOption(c, "--tol", a.tol_mm, "bound on the predicted path error of LIN/CIRC motions (mm)", NumberRange{postproc::kMinTolMm, postproc::kMaxTolMm, false, "mm"})->capture_default_str();
  c->add_option("--base", a.base, "where the OLP placed the robot in the model's world: x,y,z,A,B,C (mm, deg); default: the robot file's <base>");
  c->add_option("--robroot", a.robroot, "the controller's $ROBROOT (robot base in its $WORLD) x,y,z,A,B,C; default: identity");
  addNumberOption(c, "--payload-kg", a.payload_kg, "payload while the program runs (kg), for compliance models", kPayloadRange)->capture_default_str();
  addNumberOption(c, "--temp-c", a.temp_c, "arm temperature while the program runs (deg C), for thermal models", NumberRange{postproc::kMinTempC, postproc::kMaxTempC, false, "deg C"})->capture_default_str();
  c->add_option("--program-tool", a.program_tool, "$TOOL x,y,z,A,B,C for motions before the program sets one (the controller's active tool)");
  c->add_option("--program-base", a.program_base, "$BASE x,y,z,A,B,C for motions before the program sets one (the controller's active base)");
  c->add_option("--controller", a.controller,
                "the kinematics the robot's controller runs when they are not the nominal robot's: a UR controller runs its "
                "factory calibration (the model accura export makes of its calibration.conf); default: the nominal robot");
  return [args]() { return jobSettings(*args); };
}

void addCompensateCommand(CLI::App& app) {
  auto args = std::make_shared<CompensateArgs>();
  auto* c = app.add_subcommand("compensate", "compensate a robot program (KRL .src/.dat, XML, URScript or ABB RAPID) with a calibrated model");
  args->settings = addJobOptions(c, &args->model_files);
  c->add_option("--in", args->in, "program: PROG.src (KRL, with PROG.dat next to it), PROG.xml, PROG.script (URScript) or PROG.mod/.modx/.sys/.sysx/.prg (ABB RAPID)")->required();
  c->add_option("--dat", args->dat, "the KRL .dat (default: the .src's name with .dat)");
  addConfigOption(c, args->config, "$config.dat: TOOL_DATA, BASE_DATA and global points such as XHOME; for a RAPID module: a module of its task that "
                "declares its tooldata, wobjdata or robtargets (CalibData.mod, user.sys; once per module)");
  c->add_option("--out", args->out, "output directory (the program keeps its file names)")->required();
  c->add_option("--json", args->json, "report: per target its correction, per segment the path error before and after");
  args->cell = addCellOptions(c, false, false);
  c->add_flag("--warn-only", args->warn_only, "with --cell: write the program even when a check fails (exit 0, warnings)");
  c->callback([=]() { exitCode() = runCompensate(*args); });
}

}  // namespace accura::cli
