// accura: writing output files without ever leaving a half-written one.
#pragma once

#include <string>

namespace accura {

/// Writes `content` to `path` through a temporary file in the same directory
/// ("PATH.tmp.<pid>") that is renamed into place once complete, so readers see either the old
/// file or the whole new one. Throws InputError (naming the file) when the file cannot be
/// written or renamed; the temporary file is removed then.
void writeFileAtomically(const std::string& path, const std::string& content);

}  // namespace accura
