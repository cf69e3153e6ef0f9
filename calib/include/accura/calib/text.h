// accura: small text helpers shared by the writers.
#pragma once

#include <string>

namespace accura {

/// `s` with & < > " replaced by their entities: safe in XML and HTML text and in
/// double-quoted attribute values.
std::string xmlEscape(const std::string& s);

}  // namespace accura
