// accura post-processor: batch compensation of a tree of programs, and the atomic file writing
// every post-processor command uses.
//
// Files are written to a temporary file in the target directory (".NAME.PID.accura-tmp") and
// renamed into place; the files of one program (.src and .dat) are renamed together once all
// are written. With installInterruptCleanup(), SIGINT / SIGTERM remove the temporary files in
// flight and end the process with status 130: an interrupted run leaves every output either
// complete or absent, never half-written.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "accura/postproc/job.h"
#include "accura/postproc/program_io.h"

namespace accura::postproc {

/// Writes the files through temporary files renamed into place (see the file comment).
/// Throws InputError when a file cannot be written (the temporaries are removed).
void writeFilesAtomically(const std::vector<OutputFile>& files);

/// Installs the SIGINT / SIGTERM handler that removes in-flight temporary files and exits with
/// status 130. Idempotent.
void installInterruptCleanup();

/// True once SIGINT / SIGTERM arrived (workers stop taking new files).
bool interruptRequested();

struct BatchOptions {
  JobSettings job;
  std::string config_path;  ///< $config.dat for every program (empty: none)
  int jobs = 1;             ///< worker threads (>= 1)
};

struct BatchFileResult {
  std::string input;                 ///< path relative to the input directory ('/' separated)
  std::vector<std::string> outputs;  ///< paths written (relative to the output directory)
  enum class Status { kConverted, kFailed, kSkipped } status = Status::kFailed;
  std::string message;  ///< the error (kFailed) or why it was skipped
  JobReport report;     ///< kConverted
};

struct BatchResult {
  std::vector<BatchFileResult> files;  ///< in the order of findPrograms
  int converted = 0, failed = 0, skipped = 0;
};

/// The programs of a tree: every *.src (any case) and every *.xml, relative paths sorted
/// byte-wise ('/' separated). Hidden entries (starting with '.') are skipped.
std::vector<std::string> findPrograms(const std::string& in_dir);

/// Compensates every program of `in_dir` into the same relative path under `out_dir` (created
/// as needed), `options.jobs` at a time. A file that fails is reported in its result and
/// skipped; the others go on. An .xml file whose root element is not <program> is skipped.
/// The input tree is only read. `progress` (may be empty) is called after each file, from the
/// worker thread, one call at a time. Throws InputError when `in_dir` is not a directory or
/// `out_dir` is inside it.
BatchResult runBatch(const std::string& in_dir, const std::string& out_dir, const BatchOptions& options,
                     const std::function<void(const BatchFileResult&, int done, int total)>& progress = {});

/// Compensates one program file: reads it, compensates it, renders it at `out_path` (and the
/// .dat next to it, named like the input's .dat) without writing. Throws like readProgram and
/// compensateProgram.
std::vector<OutputFile> compensateFile(const std::string& in_path, const std::string& out_path,
                                       const ProgramReadOptions& read, const JobSettings& job, JobReport* report);

}  // namespace accura::postproc
