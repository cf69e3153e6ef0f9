// accura: writing output files without ever leaving a half-written one.
#pragma once

#include <string>

namespace accura {

/// Writes `content` to `path` through a temporary file in the same directory
/// ("PATH.tmp.<pid>") that is renamed into place once complete, so readers see either the old
/// file or the whole new one. Throws InputError (naming the file) when the file cannot be
/// written or renamed; the temporary file is removed then.
void writeFileAtomically(const std::string& path, const std::string& content);

/// True when `a` and `b` name the same file: the same inode when both exist, else the same
/// normalised absolute path (a file about to be written onto an input). Never throws.
bool sameFile(const std::string& a, const std::string& b);

}  // namespace accura
