// accura: the text of every JSON report (the command line's --json, the plug-in's report, the
// diagnosis). Header-only: it needs nlohmann_json, which calib itself keeps private; include it
// from code that already builds JSON.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

namespace accura::calib {

/// The report's text: indented by 2 spaces, with a final newline. Strings from the user's files
/// are not always UTF-8 (a cp1252 '°' in a CSV header, a Latin-1 byte in a KRL point name): each
/// byte that is not valid UTF-8 becomes U+FFFD, so a report is never lost to a byte its input
/// carried (JSON must be UTF-8). Works for nlohmann::json and nlohmann::ordered_json. Never throws
/// for text; throws std::bad_alloc only when memory runs out.
template <class Json>
std::string jsonText(const Json& j) {
  return j.dump(2, ' ', false, Json::error_handler_t::replace) + "\n";
}

}  // namespace accura::calib
