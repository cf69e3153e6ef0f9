// accura post-processor: one program file compensated (and checked) into a directory, and batch
// compensation of a tree of programs. Every output goes through calib's one writer
// (accura/calib/file_io.h): an interrupted run leaves every output either complete or absent,
// never half-written.
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "accura/calib/file_io.h"
#include "accura/postproc/cell.h"
#include "accura/postproc/check.h"
#include "accura/postproc/job.h"
#include "accura/postproc/placement.h"
#include "accura/postproc/program_io.h"

namespace accura::postproc {

// The atomic writing every post-processor command uses is calib's one writer (file_io.h).

/// The checks of a program in its cell before it is written (accura compensate --cell and
/// accura batch --cell; docs/checks.md).
struct CellCheckSettings {
  Cell cell;
  CheckOptions options;
  /// Write a program that fails the checks anyway (its report still says it failed).
  bool warn_only = false;
  /// CellGeometry(cell, job.calibrated), prepared once and shared by every program and thread
  /// (the BVHs of the cell's meshes are built once); null: built for each program. runBatch
  /// prepares it when it is null.
  std::shared_ptr<const CellGeometry> geometry;
};

/// A compensated program, rendered but not written, and its check.
struct CheckedProgram {
  std::vector<calib::OutputFile> files;     ///< the rendered output (.src and .dat, or .xml)
  std::optional<CheckReport> check;  ///< with a cell: the check of the program
  /// False when the program failed its check (a violation or a motion that could not be
  /// checked) and warn_only is not set, or when it could not be compensated: it must not be
  /// written.
  bool write = true;
  /// Not empty when the compensation failed where the check failed too
  /// (compensationFailureExplained): its error (files is then empty and write false, even
  /// with warn_only: there is nothing to write).
  std::string compensation_error;
};

/// True when the check failed and every error of the compensation (report.errors) is at a
/// motion (file and line) that the check reports: a violation or a motion it could not check
/// (an unreachable target is a reach violation, a joint beyond its limit a joint_limit one).
bool compensationFailureExplained(const CheckReport& check, const JobReport& report);

/// Compensates one program file as compensateFile does and, with `cell` (may be null), checks
/// the program read from the file in the cell (checkProgram, CheckMode of cell->options, with
/// cell->geometry when set) with the job placed in the cell (placedInCell) — what accura
/// compensate --cell and accura batch --cell both do. Nothing is written. The check runs
/// first; when the compensation then fails and the check explains it
/// (compensationFailureExplained), the result has the check, no files, write false and the
/// compensation's error (accura reports the check: exit 2, not 1). Throws like compensateFile
/// (a compensation failure the check does not explain, or without a cell) and checkProgram
/// (InputError when the cell's placement and job.robroot_in_world disagree).
CheckedProgram compensateAndCheckFile(const std::string& in_path, const std::string& out_path, const ProgramReadOptions& read,
                                      const JobSettings& job, const CellCheckSettings* cell, JobReport* report);

/// One program file compensated into a directory: what accura compensate and the plug-in's
/// accura_compensate_program both do.
struct ProgramFileRequest {
  std::string in_path;          ///< the program (.src with its .dat, or .xml)
  ProgramReadOptions read;      ///< --dat, --config
  std::string out_dir;          ///< the output directory (created); the program keeps its file name
  std::string json_path;        ///< the report (report.h, compensationReportText); empty: none
  const CellCheckSettings* cell = nullptr;  ///< checks before writing (compensateAndCheckFile)
  /// The other files the run read (the robot model, the cell): never overwritten either.
  std::vector<std::string> other_inputs;
  /// How the caller names the output directory and the report in messages ("--out" /
  /// "out_dir", "--json" / "json_report_path").
  std::string out_name = "--out", json_name = "--json";
};

struct ProgramFileResult {
  CheckedProgram checked;  ///< the rendered files, the check
  JobReport report;        ///< the compensation's report
  bool written = false;    ///< the files were written (false: a check failed, see checked.write)
};

/// Compensates (and with request.cell checks) the program as compensateAndCheckFile does and
/// writes its files into request.out_dir through writeFilesAtomically, unless the check says
/// not to; then the report to request.json_path (when set; its outputs empty when nothing was
/// written). Never modifies an input: throws InputError when out_dir is a file, or when an
/// output or the report would overwrite the program, its .dat (given or next to it), the
/// $config.dat or one of request.other_inputs, or when the report is one of the program's
/// outputs (nothing is written then); otherwise throws like compensateAndCheckFile.
ProgramFileResult compensateProgramFile(const ProgramFileRequest& request, const JobSettings& job);

/// One line for people: the first violation of a failed check ("file:line:column: check:
/// ... (short by ...)"; for a clearance, the smallest clearance at the samples of that motion
/// when it is smaller) or, without violations, the first motion that could not be checked,
/// and how many there are; empty when the check passed.
std::string firstCheckProblem(const CheckReport& check);

struct BatchOptions {
  JobSettings job;
  std::string config_path;  ///< $config.dat for every program (empty: none)
  /// --config given again: every RAPID module among config_path and these serves the RAPID
  /// modules of the tree (the task's other modules, readRapid); one $config.dat among them
  /// serves the KRL and XML programs (two: an InputError, KUKA's controller has one)
  std::vector<std::string> more_config_paths;
  int jobs = 1;             ///< worker threads (>= 1)
  /// Every program is checked in this cell before it is written (compensateAndCheckFile): a
  /// program that fails is reported as kFailed with its first violation and not written
  /// (unless warn_only: then it is written, kConverted, its check saying it failed).
  std::optional<CellCheckSettings> cell;
};

struct BatchFileResult {
  std::string input;                 ///< path relative to the input directory ('/' separated)
  std::vector<std::string> outputs;  ///< paths written (relative to the output directory)
  /// kNotStarted: the run was interrupted (calib::interruptRequested()) before a worker took
  /// this program; nothing of it was written.
  enum class Status { kConverted, kFailed, kSkipped, kNotStarted } status = Status::kFailed;
  /// The error (kFailed: firstCheckProblem when the check failed), why it was skipped, or
  /// (kConverted with warn_only) the check's first problem.
  std::string message;
  JobReport report;                  ///< kConverted, and kFailed by the check
  std::optional<CheckReport> check;  ///< with a cell, once the program was compensated
};

struct BatchResult {
  /// in the order of findPrograms, then its TreeProblems (a directory that cannot be listed:
  /// kFailed, a symbolic link to a directory: kSkipped)
  std::vector<BatchFileResult> files;
  int converted = 0, failed = 0, skipped = 0, not_started = 0;
  /// The run was interrupted: the programs in progress were finished (and written), the others
  /// are kNotStarted.
  bool interrupted = false;
  /// How many of `files` are programs (the first ones); the rest are TreeProblems.
  int programs = 0;
};

/// What a tree holds that is not a program read: a directory that cannot be listed, a program
/// name that is a symbolic link to nothing (or in a loop) or not a regular file (failed), a
/// symbolic link to a directory, which is not followed (skipped).
struct TreeProblem {
  std::string path;  ///< relative to the input directory ('/' separated)
  bool failed = true;
  std::string message;
};

/// The programs of a tree: every *.src, *.xml, *.script, *.mod, *.modx, *.prg (any case; not the
/// RAPID system modules *.sys, *.sysx: the controller's, compensate takes one with --in), relative
/// paths sorted byte-wise ('/' separated). Hidden entries (starting with '.') are skipped; a
/// symbolic link to a file is a program by its own name, one to a directory is not followed.
/// Every TreeProblem goes to `problems` (sorted by path) and the walk goes on; with `problems`
/// null the first one that fails is an InputError. Throws InputError when `in_dir` cannot be
/// listed.
std::vector<std::string> findPrograms(const std::string& in_dir, std::vector<TreeProblem>* problems);
std::vector<std::string> findPrograms(const std::string& in_dir);

/// Compensates every program of `in_dir` into the same relative path under `out_dir` (created
/// as needed), `options.jobs` at a time (the outputs do not depend on it). A file that fails
/// (reading, compensation, or the check in options.cell) is reported in its result and not
/// written; the others go on. With options.cell, the cell's geometry is prepared once (an
/// InputError when its link shapes do not fit the robot). An .xml file whose root element is not <program> is skipped.
/// The input tree is only read, and never written through a symbolic link under `out_dir` that
/// leads back into it (that program fails). A program that is not written while its output path
/// holds a file (an earlier run's) says so in its message. The tree's TreeProblems follow the
/// programs in the result. Once calib::interruptRequested() (installInterruptStop), no program
/// is started: those in progress are finished, the rest are kNotStarted, and the result says
/// it was interrupted. `progress` (may be empty) is called after each file, from the
/// worker thread, one call at a time. Throws InputError when `in_dir` is not a directory or
/// `out_dir` is inside it.
BatchResult runBatch(const std::string& in_dir, const std::string& out_dir, const BatchOptions& options,
                     const std::function<void(const BatchFileResult&, int done, int total)>& progress = {});

/// Compensates one program file: reads it, compensates it, renders it at `out_path` (and the
/// .dat next to it, named like the input's .dat) without writing. Throws like readProgram and
/// compensateProgram.
std::vector<calib::OutputFile> compensateFile(const std::string& in_path, const std::string& out_path,
                                       const ProgramReadOptions& read, const JobSettings& job, JobReport* report);

}  // namespace accura::postproc
