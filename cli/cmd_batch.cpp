// accura batch: every program of a tree compensated, in parallel, into a mirrored tree.
#include <algorithm>
#include <thread>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <functional>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "accura/calib/json_text.h"
#include "accura/calib/errors.h"
#include "accura/postproc/batch.h"
#include "accura/postproc/job.h"
#include "accura/postproc/report.h"
#include "cli_util.h"
#include "cmd_check.h"
#include "commands.h"

namespace fs = std::filesystem;

namespace accura::cli {

namespace {

/// Exit status of a batch in which some programs were not compensated.
constexpr int kSomeFailed = 2;
/// Exit status of an interrupted batch (SIGINT / SIGTERM: 128 + 2, the shell's convention).
constexpr int kInterrupted = 130;

struct BatchArgs {
  std::function<postproc::JobSettings()> settings;
  std::function<std::vector<std::string>()> model_files;  // --robot, --controller files (never overwritten)
  std::string in;
  std::string out;
  std::vector<std::string> config;  // --config, once or more (RAPID: the task's other modules)
  int jobs = std::max(1u, std::thread::hardware_concurrency());  // the outputs do not depend on it
  std::string json;
  std::function<std::optional<CellCheck>()> cell;  // --cell: every program checked before it is written (cmd_check.cpp)
  bool warn_only = false;
};

std::string statusWord(const postproc::BatchFileResult& r) {
  switch (r.status) {
    case postproc::BatchFileResult::Status::kConverted: return "compensated";
    case postproc::BatchFileResult::Status::kSkipped: return "skipped";
    case postproc::BatchFileResult::Status::kFailed: return "FAILED";
    case postproc::BatchFileResult::Status::kNotStarted: return "not started";
  }
  return "?";
}

int runBatch(const BatchArgs& a) {
  using namespace postproc;
  BatchOptions o;
  o.job = a.settings();
  o.config_path = a.config.empty() ? std::string() : a.config.front();
  if (a.config.size() > 1) o.more_config_paths.assign(a.config.begin() + 1, a.config.end());
  o.jobs = a.jobs;
  const std::optional<CellCheck> cell = a.cell();
  if (a.warn_only && !cell) throw calib::InputError("--warn-only: expected together with --cell, found it without");
  if (cell) o.cell = CellCheckSettings{cell->cell, cell->options, a.warn_only, nullptr};
  if (a.jobs < 1) throw calib::InputError("--jobs: expected at least 1, found " + std::to_string(a.jobs));
  if (!a.json.empty()) {
    // (a path that does not resolve, e.g. /dev/stdout on a pipe, is no file of the tree)
    std::error_code ec_j, ec_in;
    const fs::path j = fs::weakly_canonical(fs::absolute(a.json), ec_j);
    const fs::path in = fs::weakly_canonical(fs::absolute(a.in), ec_in);
    if (!ec_j && !ec_in && j.string().rfind(in.string() + "/", 0) == 0) throw calib::InputError("--json: " + a.json + " is inside the input tree, which is never modified");
    std::vector<std::string> inputs = a.model_files();
    inputs.insert(inputs.end(), a.config.begin(), a.config.end());
    if (cell)
      for (const std::string& f : cell->files()) inputs.push_back(f);
    calib::refuseToOverwrite({{a.json, ""}}, inputs, "--json");
  }
  // Ctrl-C / SIGTERM: the programs in progress are finished, the others not started, and the
  // report of the run says so (a process engineer needs to know which programs of the tree are
  // this run's); a second signal stops at once, without the report. Either way no file is
  // half-written.
  calib::installInterruptStop("\naccura batch: interrupted: finishing the programs in progress, then the report "
                              "(interrupt again to stop at once, without it)\n");
  const bool tty = ::isatty(2) != 0;
  const auto progress = [&](const BatchFileResult& r, int done, int total) {
    if (tty) {
      const int width = 30;
      const int filled = total ? done * width / total : width;
      if (r.status == BatchFileResult::Status::kFailed)
        std::fprintf(stderr, "\r\033[KFAILED %s: %s\n", r.input.c_str(), r.message.c_str());
      std::fprintf(stderr, "\r\033[K[%s%s] %d/%d %s", std::string(static_cast<size_t>(filled), '#').c_str(),
                   std::string(static_cast<size_t>(width - filled), '.').c_str(), done, total, r.input.c_str());
      if (done == total) std::fprintf(stderr, "\n");
    } else {
      std::fprintf(stderr, "accura batch: [%d/%d] %s %s%s\n", done, total, statusWord(r).c_str(), r.input.c_str(),
                   r.message.empty() ? "" : (": " + r.message).c_str());
    }
    std::fflush(stderr);
  };
  const BatchResult res = postproc::runBatch(a.in, a.out, o, progress);
  int warnings = 0;
  const BatchFileResult* first_not_started = nullptr;
  for (const auto& r : res.files) {
    if (r.status == BatchFileResult::Status::kNotStarted) {  // one line for them all (the report lists each)
      if (!first_not_started) first_not_started = &r;
      continue;
    }
    if (r.status == BatchFileResult::Status::kConverted) {
      std::printf("compensated %s: %d targets corrected (max %.4f mm), %d point(s) added, path error %.4f -> %.4f mm%s\n", r.input.c_str(),
                  r.report.targets_corrected, r.report.max_correction_mm, r.report.points_added, r.report.max_error_uncompensated_mm,
                  r.report.max_error_after_mm, r.check ? (r.check->passed() ? "; checks passed" : "; checks FAILED, written because of --warn-only") : "");
      if (r.report.motions_left_unchanged > 0)
        std::printf("  %s: %d motion(s) left unchanged (targets accura cannot evaluate; see the warnings)\n", r.input.c_str(),
                    r.report.motions_left_unchanged);
      if (!r.message.empty()) std::fprintf(stderr, "accura: warning: %s: %s\n", r.input.c_str(), r.message.c_str());
      // the program's warnings, as compensate prints them (a T changed, a point read elsewhere, ..)
      for (const auto& w : r.report.warnings) std::fprintf(stderr, "accura: warning: %s: %s\n", w.where.str().c_str(), w.message.c_str());
      warnings += static_cast<int>(r.report.warnings.size());
    } else {
      std::printf("%s %s: %s\n", statusWord(r).c_str(), r.input.c_str(), r.message.c_str());
    }
  }
  // (the tree's other entries, a directory that cannot be listed or a link not followed, are
  // counted in failed / skipped and named above, but they are no programs)
  const size_t others = res.files.size() - static_cast<size_t>(res.programs);
  const std::string other_entries =
      others ? " and " + std::to_string(others) + " other entr" + (others == 1 ? "y" : "ies") + " of the tree" : std::string();
  if (first_not_started)
    std::printf("not started: %d program(s), from %s on in sorted order: the run was interrupted\n", res.not_started,
                first_not_started->input.c_str());
  const std::string not_started = res.interrupted ? ", " + std::to_string(res.not_started) + " not started" : std::string();
  std::printf("accura batch: %s%d compensated, %d failed, %d skipped%s, %d programs%s in %s%s\n", res.interrupted ? "interrupted: " : "",
              res.converted, res.failed, res.skipped, not_started.c_str(), res.programs, other_entries.c_str(), a.in.c_str(),
              warnings ? ("; " + std::to_string(warnings) + " warning(s), on stderr").c_str() : "");
  if (!a.json.empty()) {
    // the report must not replace a program the run wrote
    for (const auto& r : res.files)
      for (const auto& output : r.outputs)
        if (calib::sameFile(a.json, (fs::path(a.out) / output).string()))
          throw calib::InputError("--json: " + a.json + " is the output of " + r.input + ": choose another path for the report");
    nlohmann::ordered_json j;
    j["in"] = a.in;
    j["out"] = a.out;
    j["robot"] = o.job.calibrated.nominal.name;
    if (cell) {
      j["cell"] = cell->cell_path;
      j["warn_only"] = a.warn_only;
    }
    j["compensated"] = res.converted;
    j["failed"] = res.failed;
    j["skipped"] = res.skipped;
    j["interrupted"] = res.interrupted;    // (the programs no worker had taken: "not started")
    j["not_started"] = res.not_started;
    j["programs"] = res.programs;  // (the entries of "files" beyond them: the tree's other entries)
    nlohmann::ordered_json files = nlohmann::ordered_json::array();
    for (const auto& r : res.files) {
      nlohmann::ordered_json f;
      f["input"] = r.input;
      f["status"] = r.status == BatchFileResult::Status::kFailed ? "failed"
                    : r.status == BatchFileResult::Status::kNotStarted ? "not_started" : statusWord(r);
      f["outputs"] = r.outputs;
      if (!r.message.empty()) f["message"] = r.message;
      if (r.status == BatchFileResult::Status::kConverted || r.check) f.update(jobReportJson(r.report, a.in));
      if (r.check) f["check"] = checkReportJson(*r.check, a.in);
      files.push_back(f);
    }
    j["files"] = files;
    calib::writeFilesAtomically({{a.json, calib::jsonText(j)}});
    std::printf("wrote %s\n", a.json.c_str());
  }
  if (res.interrupted) return kInterrupted;
  return res.failed == 0 ? 0 : kSomeFailed;
}

}  // namespace

void addBatchCommand(CLI::App& app) {
  auto args = std::make_shared<BatchArgs>();
  auto* c = app.add_subcommand("batch",
                               "compensate every program (*.src, *.xml, *.script, *.mod, *.modx, *.prg) of a directory tree into a mirrored tree (with --cell: each checked "
                               "in the cell before it is written)");
  args->settings = addJobOptions(c, &args->model_files);
  c->add_option("--in", args->in, "directory of programs (read only)")->required();
  c->add_option("--out", args->out, "output directory (the same relative paths); not inside --in")->required();
  addConfigOption(c, args->config, "$config.dat for every KRL and XML program: TOOL_DATA, BASE_DATA, global points; or, for every RAPID module, a "
                "module of the task that declares tooldata, wobjdata or robtargets (CalibData.mod, user.sys; once per module)");
  addIntegerOption(c, "--jobs", args->jobs, "programs compensated in parallel (default: the number of cores)", 1, 1024)->capture_default_str();
  c->add_option("--json", args->json, "report of every program (with --cell: its check)");
  args->cell = addCellOptions(c, false, false);
  c->add_flag("--warn-only", args->warn_only, "with --cell: write the programs that fail a check anyway (their report says so)");
  c->callback([=]() { exitCode() = runBatch(*args); });
}

}  // namespace accura::cli
