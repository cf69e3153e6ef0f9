// accura post-processor: the XML program format for off-line programming exchange (schema:
// postproc/schema/accura-program.xsd; description: docs/program-formats.md). It carries the
// motion model of a Program: robot, tool and base frames, and the motions with their targets,
// speeds and approximation, in the same terms as KRL.
#pragma once

#include <map>
#include <set>
#include <string>

#include "accura/postproc/program.h"

namespace accura::postproc {

/// Reads an XML program. `tables` resolves <tool source="data" index="n"/> frames that carry no
/// values (TOOL_DATA / BASE_DATA from a $config.dat); may be null. Throws InputError
/// (file:line:column) on malformed XML, an unknown element or attribute, a missing or
/// non-numeric value, a motion without its target; InputError ("PATH: cannot read the XML
/// program: not a regular file") for a path that is no regular file (a named pipe is not opened).
Program readXmlProgram(const std::string& path, const FrameTables* tables = nullptr);

/// The same, from text (`file` names it in error messages).
Program parseXmlProgram(const std::string& text, const std::string& file, const FrameTables* tables = nullptr);

/// Writes a program as XML: canonical layout (two-space indentation, attributes in a fixed
/// order, the number formats of program.h), so that reading and writing it back gives the
/// same bytes. Throws ArgumentError for a motion whose target cannot be represented (computed
/// at run time without a name).
std::string writeXmlProgram(const Program& program);

/// The elements of the format and their attributes, as the reader accepts them (checked
/// against the schema file by a test).
const std::map<std::string, std::set<std::string>>& xmlProgramVocabulary();

}  // namespace accura::postproc
