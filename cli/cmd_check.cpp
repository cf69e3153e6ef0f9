// accura check: reach, joint-limit, singularity and clearance checks of a program in its cell
// (docs/checks.md), and the --cell options accura compensate shares.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <iostream>
#include <memory>
#include <optional>

#include "accura/calib/json_text.h"
#include "accura/calib/errors.h"
#include "accura/postproc/batch.h"
#include "accura/postproc/cell.h"
#include "accura/postproc/check.h"
#include "accura/postproc/job.h"
#include "accura/postproc/program_io.h"
#include "accura/postproc/report.h"
#include "cli_util.h"
#include "cmd_check.h"
#include "commands.h"

namespace fs = std::filesystem;

namespace accura::cli {

namespace {

struct CellArgs {
  std::string cell;
  double joint_margin_deg = 0, singular_threshold = 0, min_clearance_mm = 0;
  bool as_written = false;
  CLI::Option* o_margin = nullptr;
  CLI::Option* o_singular = nullptr;
  CLI::Option* o_clearance = nullptr;
};

}  // namespace

std::vector<std::string> CellCheck::files() const {
  std::vector<std::string> out = {cell_path};
  const auto add = [&](const postproc::CellShape& s) {
    if (s.mesh && !s.mesh->file.empty() && std::find(out.begin(), out.end(), s.mesh->file) == out.end()) out.push_back(s.mesh->file);
  };
  for (const auto& s : cell.objects) add(s);
  for (const auto& [joint, s] : cell.link_shapes) add(s);
  for (const auto& s : cell.tool_shapes) add(s);
  return out;
}

namespace {

std::optional<CellCheck> cellCheck(const CellArgs& a) {
  if (a.cell.empty()) {
    // a threshold of a check that does not run (the checks run in a cell) is refused, like
    // --warn-only without --cell, rather than dropped without a word
    for (const CLI::Option* o : {a.o_margin, a.o_singular, a.o_clearance})
      if (o->count())
        throw calib::InputError(o->get_name() + ": expected together with --cell (a threshold of the checks, which run in a "
                                "cell), found it without");
    return std::nullopt;
  }
  CellCheck c;
  c.cell_path = a.cell;
  c.cell = postproc::readCellFile(a.cell);
  c.options.thresholds = c.cell.thresholds;
  if (a.o_margin->count()) {
    if (!(a.joint_margin_deg >= 0) || !std::isfinite(a.joint_margin_deg))
      throw calib::InputError("--joint-margin-deg: expected a margin >= 0 (deg), found " + fmt("%g", a.joint_margin_deg));
    c.options.thresholds.joint_margin_deg = a.joint_margin_deg;
  }
  if (a.o_singular->count()) {
    if (!(a.singular_threshold >= 0) || !std::isfinite(a.singular_threshold))
      throw calib::InputError("--singular-threshold: expected a value >= 0, found " + fmt("%g", a.singular_threshold));
    c.options.thresholds.singular_threshold = a.singular_threshold;
  }
  if (a.o_clearance->count()) {
    if (!(a.min_clearance_mm >= 0) || !std::isfinite(a.min_clearance_mm))
      throw calib::InputError("--min-clearance-mm: expected a distance >= 0 (mm), found " + fmt("%g", a.min_clearance_mm));
    c.options.thresholds.min_clearance_mm = a.min_clearance_mm;
  }
  c.options.mode = a.as_written ? postproc::CheckMode::kAsWritten : postproc::CheckMode::kIntended;
  return c;
}

struct CheckArgs {
  std::function<postproc::JobSettings()> settings;
  std::function<std::vector<std::string>()> model_files;  // --robot, --controller files (never overwritten)
  std::function<std::optional<CellCheck>()> cell;
  std::string in, dat, json;
  std::vector<std::string> config;  // --config, once or more (RAPID: the task's other modules)
};

int runCheck(const CheckArgs& a) {
  using namespace postproc;
  const JobSettings settings = a.settings();
  const std::optional<CellCheck> cc = a.cell();
  postproc::ProgramReadOptions read;
  read.dat_path = a.dat;
  setConfigPaths(read, a.config);
  const Program program = readProgram(a.in, read);
  if (!a.json.empty()) {
    std::vector<std::string> inputs = {a.in, a.dat, program.krl ? program.krl->dat_path : std::string()};
    inputs.insert(inputs.end(), a.config.begin(), a.config.end());
    for (const std::string& f : cc->files()) inputs.push_back(f);
    for (const std::string& f : a.model_files()) inputs.push_back(f);
    calib::refuseToOverwrite({{a.json, ""}}, inputs, "--json");
  }
  const CheckReport r = checkProgram(program, settings, cc->cell, cc->options);
  printCheckReport(r, a.in);
  if (!a.json.empty()) {
    nlohmann::ordered_json j;
    j["program"] = a.in;
    j["cell"] = cc->cell_path;
    j["robot"] = settings.calibrated.nominal.name;
    j.update(checkReportJson(r));
    calib::writeFilesAtomically({{a.json, calib::jsonText(j)}});
    std::printf("wrote %s\n", a.json.c_str());
  }
  return r.passed() ? 0 : kCheckFailed;
}

}  // namespace

std::function<std::optional<CellCheck>()> addCellOptions(CLI::App* c, bool required, bool as_written_flag) {
  auto args = std::make_shared<CellArgs>();
  CellArgs& a = *args;
  auto* o = c->add_option("--cell", a.cell, "cell file (docs/cell-format.md): meshes, robot placement, link and tool geometry, thresholds");
  if (required) o->required();
  a.o_margin = addNumberOption(c, "--joint-margin-deg", a.joint_margin_deg, "required distance of every joint from its limits (deg; mm for prismatic); default: the cell file's, else 1",
                               NumberRange{0, 180, false, "deg"});
  a.o_singular = addNumberOption(c, "--singular-threshold", a.singular_threshold,
                               "smallest allowed sigma_min of the scaled joint Jacobian (dimensionless, docs/checks.md); default: the cell file's, else 0.005",
                                 NumberRange{0, 1, false, ""});
  a.o_clearance = addNumberOption(c, "--min-clearance-mm", a.min_clearance_mm, "required distance robot <-> cell meshes (mm); default: the cell file's, else 5",
                                  NumberRange{0, 10000, false, "mm"});
  if (as_written_flag)
    c->add_flag("--as-written", a.as_written,
              "the program runs as written (already compensated): joints from the controller's nominal IK; default: its targets are where the tool must go (IK of the calibrated model)");
  return [args]() { return cellCheck(*args); };
}

void printCheckReport(const postproc::CheckReport& r, const std::string& program) {
  for (const auto& w : r.warnings) std::cerr << "accura: warning: " << w.where.str() << ": " << w.message << "\n";
  std::printf("accura check: %s (%s; joint margin >= %.3f deg, sigma_min >= %.6f, clearance >= %.3f mm; TCP positions "
              "in the model's world frame)\n", program.c_str(), postproc::toString(r.mode), r.thresholds.joint_margin_deg, r.thresholds.singular_threshold, r.thresholds.min_clearance_mm);
  for (const auto& v : r.violations) {
    // the first violation is where the clearance gets short: how short it gets on the motion
    std::string deepest;
    if (v.kind == postproc::CheckKind::kClearance)
      for (const auto& m : r.motions)
        if (m.motion_index == v.motion_index && m.min_clearance_mm < v.value)
          deepest = fmt(" (smallest clearance on this motion %.3f mm)", m.min_clearance_mm);
    std::printf("  VIOLATION %s: motion %d (%s): %s%s\n", v.where.str().c_str(), v.motion_index + 1, v.motion_type.c_str(),
                v.message.c_str(), deepest.c_str());
  }
  for (const auto& u : r.unchecked) std::printf("  NOT CHECKED %s: %s\n", u.where.str().c_str(), u.message.c_str());
  auto val = [](double v) { return std::isfinite(v) ? fmt("%.3f", v) : std::string("-"); };
  std::printf("%zu motion(s), %d configuration(s) evaluated, %lld distance queries; smallest clearance %s mm, sigma_min %s, joint margin %s deg\n",
              r.motions.size(), r.samples, r.distance_queries, val(r.min_clearance_mm).c_str(),
              std::isfinite(r.min_sigma) ? fmt("%.6f", r.min_sigma).c_str() : "-", val(r.min_joint_margin).c_str());
  std::printf("%s: %zu violation(s), %zu motion(s) not checked\n", r.passed() ? "PASSED" : "FAILED", r.violations.size(), r.unchecked.size());
}

void addCheckCommand(CLI::App& app) {
  auto args = std::make_shared<CheckArgs>();
  auto* c = app.add_subcommand("check", "check a program in its cell: reach, joint limits, singularities, clearance (exit 2 on a violation)");
  args->settings = addJobOptions(c, &args->model_files);
  c->remove_option(c->get_option("--tol"));  // the compensation's path tolerance: not used by the checks
  args->cell = addCellOptions(c, true, true);
  c->add_option("--in", args->in, "program: PROG.src (KRL, with PROG.dat next to it), PROG.xml, PROG.script (URScript) or PROG.mod/.modx/.sys/.sysx/.prg (ABB RAPID)")->required();
  c->add_option("--dat", args->dat, "the KRL .dat (default: the .src's name with .dat)");
  addConfigOption(c, args->config, "$config.dat: TOOL_DATA, BASE_DATA and global points such as XHOME; for a RAPID module: a module of its task that "
                "declares its tooldata, wobjdata or robtargets (CalibData.mod, user.sys; once per module)");
  c->add_option("--json", args->json, "report: every violation (where, joints, which check, by how much) and per motion the margins");
  c->callback([=]() { exitCode() = runCheck(*args); });
}

}  // namespace accura::cli
