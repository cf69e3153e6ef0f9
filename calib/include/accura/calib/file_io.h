// accura: the one writer of output files, used by every layer (calib's model and measurement
// files, postproc's programs and reports, the command line, the plug-in). An output is never
// half-written: each file is written to a temporary file in its target directory
// (".NAME.PID.N.accura-tmp", N counting the files this process writes: concurrent writers of one
// path never share a temporary file) and renamed into place; the files of one call (a program's
// .src and .dat) are renamed together once all are written. With installInterruptCleanup() (the command
// line; a library host owns its signals), SIGINT / SIGTERM remove the temporary files in flight
// and end the process with status 130. A path that is a stream, not a file to replace
// (/dev/stdout, /dev/stderr, /dev/fd/N, /proc/self/fd/N, an existing character device, FIFO or
// socket such as /dev/null or a named pipe), is written into directly once the set's files are
// in place: renaming a file onto it would replace the device or link itself.
#pragma once

#include <string>
#include <vector>

namespace accura::calib {

/// One output file: where it goes and its bytes.
struct OutputFile {
  std::string path;
  std::string text;
};

/// Writes the files through temporary files renamed into place (see the file comment). Throws
/// InputError ("PATH: cannot write file: ...") when a file cannot be written or renamed, or when
/// two of the files are one (nothing is written then); the temporary files are removed. The
/// directories must exist.
void writeFilesAtomically(const std::vector<OutputFile>& files);

/// Creates the directory `dir` and its parents where missing (nothing for ""): for the outputs
/// of writeFilesAtomically. Throws InputError ("DIR: cannot create the directory: ...").
void createDirectories(const std::string& dir);

/// writeFilesAtomically of one file.
void writeFileAtomically(const std::string& path, const std::string& content);

/// Installs the SIGINT / SIGTERM handler that removes in-flight temporary files and exits with
/// status 130. Idempotent.
void installInterruptCleanup();

/// installInterruptCleanup for a command that reports what it finished (batch): the first
/// SIGINT / SIGTERM only writes `note` (a string literal: it must live as long as the process)
/// to stderr and makes interruptRequested() true; nothing is removed and nothing exits, the
/// files being written are written and renamed into place as usual, and the command stops its
/// work, writes its report and ends with status 130 itself. A second signal acts as
/// installInterruptCleanup's at once (no report). Idempotent.
void installInterruptStop(const char* note);

/// True once SIGINT / SIGTERM arrived (workers stop taking new files).
bool interruptRequested();

/// True when `a` and `b` name the same file: the same inode when both exist, else the same
/// normalised absolute path (a file about to be written onto an input). Never throws.
bool sameFile(const std::string& a, const std::string& b);

/// What is at `path` when it is no file to read, in words for a message: "no such file", "it is a
/// directory", "not a regular file", or the reason its status cannot be read; "" for a regular
/// file. Never throws.
std::string notAFileProblem(const std::string& path);

/// Why files cannot be created in the directory `dir` ("" empty: the current directory), in words
/// for a message: "the directory D does not exist", "D is not a directory", "the directory D is
/// not writable (reason)"; "" when they can. Never throws.
std::string directoryWriteProblem(const std::string& dir);

/// The checks a command that works long before it writes makes first (identify, diagnose): every
/// non-empty path in `outputs` must lie in an existing, writable directory and must not be a
/// directory itself, and none may be one of `inputs` (refuseToOverwrite). Throws InputError
/// ("PATH: cannot write file: ...", or refuseToOverwrite's) before any work is done. The final
/// write checks again: a directory may still vanish in between.
void refuseUnwritableOutputs(const std::vector<std::string>& outputs, const std::vector<std::string>& inputs,
                             const std::string& out_name);

/// The overwrite guard of every command that writes: throws InputError ("OUT: the output would
/// overwrite the input IN: choose another <out_name>") when an output is one of `inputs`
/// (sameFile); inputs that are empty strings are skipped.
void refuseToOverwrite(const std::vector<OutputFile>& outputs, const std::vector<std::string>& inputs, const std::string& out_name);

}  // namespace accura::calib
