// accura post-processor: reading and writing programs in either format, chosen by the file
// extension (.src: KUKA KRL with its .dat; .xml: the XML program format; .script: URScript;
// .mod, .prg: ABB RAPID).
#pragma once

#include <map>
#include <string>
#include <vector>

#include "accura/calib/file_io.h"
#include "accura/postproc/program.h"

namespace accura::postproc {

enum class ProgramFormat { kKrl, kXml, kUrScript, kRapid };

/// The format of a program file by its extension (case-insensitive): .src -> KRL, .xml -> XML,
/// .script -> URScript (urscript.h), .mod / .modx / .sys / .sysx / .prg -> ABB RAPID (rapid.h).
/// Throws InputError for any other extension.
ProgramFormat programFormat(const std::string& path);

/// True when `path` names a RAPID module by its extension (programFormat's: .mod, .modx, .sys,
/// .sysx, .prg), e.g. the module of a task that declares its tooldata and wobjdata.
bool isRapidModulePath(const std::string& path);

struct ProgramReadOptions {
  std::string dat_path;     ///< KRL: the .dat (empty: found next to the .src)
  /// KRL and XML: the $config.dat: TOOL_DATA / BASE_DATA (and global points for KRL). RAPID:
  /// another module of the task whose tooldata and wobjdata the module uses (readRapid).
  std::string config_path;
  /// --config given more than once, the second and further: RAPID, more modules of the task
  /// (readRapid's task_modules: CalibData.mod, user.sys, a module of global robtargets). KRL and
  /// XML: refused (InputError): KUKA's controller has one $config.dat.
  std::vector<std::string> more_config_paths;
  /// KRL: the GLOBAL points of other programs' data lists (KrlReadOptions::other_globals)
  std::map<std::string, SourceLocation> other_globals;
};

/// The --config paths as given, in order: the first into config_path, the others into
/// more_config_paths.
void setConfigPaths(ProgramReadOptions& options, const std::vector<std::string>& paths);
/// Every --config path of `options` (config_path, then more_config_paths; empty ones left out).
std::vector<std::string> configPaths(const ProgramReadOptions& options);

/// Reads a program in the format of its extension. Throws InputError (file:line:column).
Program readProgram(const std::string& path, const ProgramReadOptions& options = {});

/// One output file (file_io.h, the one writer).

/// The files of `program` written as `format`: XML -> `path`; KRL -> `path` (the .src) and
/// `dat_path` (empty: `path` with the extension .dat) when the program has a .dat (a program
/// read from KRL without .dat gets none; a new KRL program always gets one); URScript ->
/// `path` (urscript.h, writeUrScript; a program read from URScript goes into XML with every
/// line carried, into KRL and RAPID only when it holds nothing but motions, set_tcp and pose
/// assignments); RAPID -> `path` (rapid.h, writeRapid; a program read from RAPID goes into
/// another format with every line carried, its statements outside the motion model as
/// pass-through, which only XML carries). The lines carried only to give a RAPID or URScript
/// source back (PassThrough::role) are left out of the other languages. Throws
/// ArgumentError when the program cannot be written in that format.
/// `program` made ready for `format` with what that format cannot hold left out (convert
/// --drop-unconvertible): the pass-through statements of another language, and those no other
/// program can carry (PassThrough::refuse); the motions stay. The statements left out are
/// appended to `dropped` (where they were read, their text) in the program's order. Nothing is
/// left out for XML, which carries every statement.
Program dropUnconvertible(const Program& program, ProgramFormat format, std::vector<PassThrough>* dropped);

std::vector<calib::OutputFile> renderProgram(const Program& program, ProgramFormat format, const std::string& path,
                                      const std::string& dat_path = "");

}  // namespace accura::postproc
