// accura: measurement exports read through a mapping file (docs/measurement-mapping.md).
#include "accura/calib/import.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "accura/calib/errors.h"
#include "accura/calib/geometry.h"
#include "accura/calib/text.h"

namespace accura::calib {
namespace {

std::string lower(std::string s) {
  for (char& c : s)
    if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
  return s;
}

std::vector<std::string> splitOn(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::string cur;
  for (char c : s) {
    if (c == sep) {
      out.push_back(cur);
      cur.clear();
    } else {
      cur += c;
    }
  }
  out.push_back(cur);
  return out;
}

/// The fields of an export's line: split at `sep`, a field in double quotes taken as its text
/// (it may hold the delimiter; "" is one quote), as spreadsheet and instrument exports write
/// them (RFC 4180). Spaces around a quoted field are kept out of it.
std::vector<std::string> splitFields(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::string cur;
  bool quoted = false, was_quoted = false;
  for (size_t i = 0; i < s.size(); ++i) {
    const char c = s[i];
    if (quoted) {
      if (c == '"' && i + 1 < s.size() && s[i + 1] == '"') {
        cur += '"';
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        cur += c;
      }
    } else if (c == '"' && cur.find_first_not_of(" \t") == std::string::npos && !was_quoted) {
      quoted = was_quoted = true;
      cur.clear();
    } else if (c == sep) {
      out.push_back(cur);
      cur.clear();
      was_quoted = false;
    } else if (!(was_quoted && (c == ' ' || c == '\t' || c == '\r'))) {
      cur += c;
    }
  }
  out.push_back(cur);
  return out;
}

std::vector<std::string> readLines(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw InputError(path, 0, 0, "cannot open file");
  std::ostringstream bytes;
  bytes << f.rdbuf();
  if (f.bad()) throw InputError(path, 0, 0, "read error");
  const std::string content = bytes.str();
  int bad_line = 0;
  if (const std::string why = unsplittableText(content, &bad_line); !why.empty()) throw InputError(path, bad_line, 1, why);
  std::vector<std::string> lines;
  std::istringstream in(content);
  std::string line;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    lines.push_back(line);
  }
  if (!lines.empty() && lines[0].rfind("\xEF\xBB\xBF", 0) == 0) lines[0].erase(0, 3);
  return lines;
}

// Parses a number written with `decimal` as the decimal separator; no thousands separators.
bool parseNumber(std::string text, char decimal, double* value) {
  text = trimBlanks(text);
  if (text.empty()) return false;
  if (decimal == ',') {
    if (text.find('.') != std::string::npos) return false;  // '.' is not the decimal mark here
    std::replace(text.begin(), text.end(), ',', '.');
  }
  const char* b = text.c_str();
  if (*b == '+' && b[1] != '-' && b[1] != '+') ++b;  // "+-1.5" is no number (was read as -1.5)
  const char* e = text.c_str() + text.size();
  const auto r = std::from_chars(b, e, *value);
  return r.ec == std::errc() && r.ptr == e && std::isfinite(*value);
}

const std::set<std::string> kKeys = {
    "delimiter", "decimal", "joints", "joint_unit", "prismatic_unit", "position", "position_unit",
    "orientation", "orientation_unit", "position_std", "orientation_std", "weight", "payload_kg",
    "temperature_c", "time_s", "directions", "ignore"};

/// The first line of a measurement file given where a mapping is expected (--map and --data
/// swapped): a row of at least 3 fields separated by ';', a tab or ',' and no '='. What the file
/// looks like, for the error at that line; else "".
std::string measurementFileNote(const std::string& line) {
  if (line.find('=') != std::string::npos) return "";
  for (const char sep : {';', '\t', ','}) {
    const std::vector<std::string> fields = splitFields(line, sep);
    if (fields.size() < 3) continue;
    const std::string name = sep == '\t' ? "tabs" : "'" + std::string(1, sep) + "'";
    return ": this looks like a measurement file, not a mapping: its first line is a row of " + std::to_string(fields.size()) +
           " fields separated by " + name +
           "; give the measurements with --data (or --validate) and the mapping (key = value lines, docs/measurement-mapping.md) "
           "with --map";
  }
  return "";
}

}  // namespace

std::string mappingFileNote(const std::string& line) {
  const size_t eq = line.find('=');
  if (eq == std::string::npos) return "";
  const std::string key = lower(trimBlanks(line.substr(0, eq)));
  if (!kKeys.count(key)) return "";
  return "this looks like a mapping file, not a measurement file: its first line '" + trimBlanks(line) + "' is a mapping's key = value; give "
         "the mapping with --map (or --validate-map) and the measurements with --data (or --validate)";
}

Eigen::Matrix3d rotationFromAngles(const std::string& convention, const Eigen::Vector3d& a) {
  auto axis = [](char c) {
    switch (c) {
      case 'x': return Eigen::Vector3d::UnitX().eval();
      case 'y': return Eigen::Vector3d::UnitY().eval();
      case 'z': return Eigen::Vector3d::UnitZ().eval();
    }
    throw ArgumentError(std::string("rotation axis must be x, y or z, got '") + c + "'");
  };
  if (convention == "kuka_abc") return rotationZYX(a[0], a[1], a[2]);
  for (const std::string kind : {"euler_intrinsic_", "euler_extrinsic_"}) {
    if (convention.rfind(kind, 0) == 0 && convention.size() == kind.size() + 3) {
      const std::string ax = convention.substr(kind.size());
      // two turns about one axis in a row are one turn: such a sequence has two degrees of
      // freedom and describes no rotation in general (a misspelt convention)
      if (ax[0] == ax[1] || ax[1] == ax[2])
        throw ArgumentError("rotation axes '" + ax + "': expected consecutive axes that differ (e.g. xyz, zyx, zyz)");
      const Eigen::Matrix3d R1 = Eigen::AngleAxisd(a[0], axis(ax[0])).toRotationMatrix();
      const Eigen::Matrix3d R2 = Eigen::AngleAxisd(a[1], axis(ax[1])).toRotationMatrix();
      const Eigen::Matrix3d R3 = Eigen::AngleAxisd(a[2], axis(ax[2])).toRotationMatrix();
      // intrinsic: about the moving axes, R = R1 R2 R3; extrinsic: about fixed axes, R = R3 R2 R1
      return kind == "euler_intrinsic_" ? Eigen::Matrix3d(R1 * R2 * R3) : Eigen::Matrix3d(R3 * R2 * R1);
    }
  }
  throw ArgumentError("unknown rotation convention '" + convention + "'");
}

MeasurementMapping readMeasurementMapping(const std::string& path, const RobotDefinition& robot) {
  const std::vector<std::string> lines = readLines(path);
  MeasurementMapping m;
  m.file = path;
  std::map<std::string, std::pair<std::string, int>> kv;  // key -> (value, line)
  std::map<std::string, int> value_col;
  // key -> its line's text and where its value lies in it ([from, to): after '=', before a
  // trailing comment), for the column of each name the value lists
  struct ValueText {
    std::string line;
    size_t from = 0, to = 0;
  };
  std::map<std::string, ValueText> value_text;
  for (size_t i = 0; i < lines.size(); ++i) {
    const int ln = static_cast<int>(i) + 1;
    const std::string t = trimBlanks(lines[i]);
    if (t.empty() || t[0] == '#') continue;
    const size_t eq = lines[i].find('=');
    if (eq == std::string::npos) {
      const std::string note = kv.empty() ? measurementFileNote(t) : std::string();
      throw InputError(path, ln, 1, "expected 'key = value', found '" + (note.empty() || t.size() <= 60 ? t : t.substr(0, 57) + "...") +
                                        "'" + note);
    }
    const std::string key = lower(trimBlanks(lines[i].substr(0, eq)));
    std::string value = lines[i].substr(eq + 1);
    // trailing comment: ' #' outside the value (a '#' right after '=' may be a delimiter)
    const size_t hash = value.find(" #");
    value_text[lower(trimBlanks(lines[i].substr(0, eq)))] = {lines[i], eq + 1, hash == std::string::npos ? lines[i].size() : eq + 1 + hash};
    if (hash != std::string::npos) value = value.substr(0, hash);
    value = trimBlanks(value);
    const int col = static_cast<int>(lines[i].find_first_not_of(" \t")) + 1;
    if (!kKeys.count(key)) {
      std::string list;
      for (const auto& k : kKeys) list += (list.empty() ? "" : ", ") + k;
      throw InputError(path, ln, col, "unknown key '" + key + "' (expected one of: " + list + ")");
    }
    if (kv.count(key))
      throw InputError(path, ln, col, "expected each key once, found '" + key + "' a second time (first on line " +
                                          std::to_string(kv[key].second) + ")");
    kv[key] = {value, ln};
    const size_t vstart = lines[i].find_first_not_of(" \t", eq + 1);
    value_col[key] = static_cast<int>(vstart == std::string::npos ? eq + 1 : vstart) + 1;
    m.key_lines.push_back({key, ln});
  }
  auto fail = [&](const std::string& key, const std::string& msg) -> InputError {
    auto it = kv.find(key);
    if (it == kv.end()) return InputError(path, 1, 1, msg);  // the file as a whole
    return InputError(path, it->second.second, value_col[key], msg);
  };
  auto require = [&](const std::string& key) -> std::string {
    auto it = kv.find(key);
    if (it == kv.end()) throw InputError(path, 1, 1, "expected a key '" + key + "', found none");
    return it->second.first;
  };
  auto optional = [&](const std::string& key) -> std::string {
    auto it = kv.find(key);
    return it == kv.end() ? std::string() : it->second.first;
  };
  auto columns = [&](const std::string& key, const std::string& value) {
    std::vector<std::string> out;
    if (value.empty()) return out;
    for (const auto& c : splitOn(value, ',')) {
      const std::string name = trimBlanks(c);
      if (name.empty()) throw fail(key, "key '" + key + "': expected column names separated by ',', found an empty name");
      out.push_back(name);
    }
    return out;
  };
  auto expectCount = [&](const std::string& key, const std::vector<std::string>& cols,
                         std::initializer_list<size_t> counts) {
    for (size_t c : counts)
      if (cols.size() == c) return;
    std::string expected;
    for (size_t c : counts) expected += (expected.empty() ? "" : " or ") + std::to_string(c);
    throw fail(key, "key '" + key + "': expected " + expected + " column names, found " + std::to_string(cols.size()));
  };

  const std::string delim = lower(require("delimiter"));
  if (delim == ";") m.delimiter = ';';
  else if (delim == ",") m.delimiter = ',';
  else if (delim == "tab" || delim == "\\t") m.delimiter = '\t';
  else throw fail("delimiter", "key 'delimiter': expected ';', ',' or 'tab', found '" + delim + "'");
  const std::string dec = require("decimal");
  if (dec == ".") m.decimal = '.';
  else if (dec == ",") m.decimal = ',';
  else throw fail("decimal", "key 'decimal': expected '.' or ',', found '" + dec + "'");
  if (m.delimiter == m.decimal)
    throw fail("decimal", "key 'decimal': expected a decimal mark other than the delimiter, found '" + dec + "' for both");

  m.joints = columns("joints", require("joints"));
  expectCount("joints", m.joints, {static_cast<size_t>(robot.dof())});
  const std::string ju = lower(require("joint_unit"));
  if (ju == "deg") m.joint_scale = 1.0;
  else if (ju == "rad") m.joint_scale = kRadToDeg;
  else throw fail("joint_unit", "key 'joint_unit': expected 'deg' or 'rad', found '" + ju + "'");
  const bool has_prismatic = std::any_of(robot.joints.begin(), robot.joints.end(),
                                         [](const JointSpec& j) { return j.type == JointType::kPrismatic; });
  if (has_prismatic) {
    const std::string pu = lower(require("prismatic_unit"));
    if (pu == "mm") m.prismatic_scale = 1.0;
    else if (pu == "m") m.prismatic_scale = 1000.0;
    else throw fail("prismatic_unit", "key 'prismatic_unit': expected 'mm' or 'm', found '" + pu + "'");
  }
  m.position = columns("position", require("position"));
  expectCount("position", m.position, {3});
  const std::string pu = lower(require("position_unit"));
  if (pu == "mm") m.position_scale = 1.0;
  else if (pu == "m") m.position_scale = 1000.0;
  else throw fail("position_unit", "key 'position_unit': expected 'mm' or 'm', found '" + pu + "'");

  const std::string ori = optional("orientation");
  if (!ori.empty()) {
    const size_t colon = ori.find(':');
    if (colon == std::string::npos)
      throw fail("orientation", "key 'orientation': expected 'CONVENTION: column, column, ...', found '" + ori + "'");
    m.orientation_convention = lower(trimBlanks(ori.substr(0, colon)));
    m.orientation = columns("orientation", ori.substr(colon + 1));
    const std::string& conv = m.orientation_convention;
    if (conv == "quaternion_wxyz" || conv == "quaternion_xyzw") {
      expectCount("orientation", m.orientation, {4});
    } else {
      try {
        rotationFromAngles(conv, Eigen::Vector3d::Zero());
      } catch (const ArgumentError&) {
        throw fail("orientation", "key 'orientation': expected a convention quaternion_wxyz, quaternion_xyzw, "
                                  "kuka_abc, euler_intrinsic_<axes> or euler_extrinsic_<axes> (three axes of x, y, z, "
                                  "consecutive ones different: e.g. xyz, zyx, zyz), found '" + conv + "'");
      }
      expectCount("orientation", m.orientation, {3});
      const std::string ou = lower(require("orientation_unit"));
      if (ou == "deg") m.angle_scale = 1.0;
      else if (ou == "rad") m.angle_scale = kRadToDeg;
      else throw fail("orientation_unit", "key 'orientation_unit': expected 'deg' or 'rad', found '" + ou + "'");
    }
  } else if (kv.count("orientation_unit") || kv.count("orientation_std")) {
    throw fail(kv.count("orientation_std") ? "orientation_std" : "orientation_unit",
               "expected an 'orientation' key before orientation units or stds, found none");
  }
  m.position_std = columns("position_std", optional("position_std"));
  if (!m.position_std.empty()) expectCount("position_std", m.position_std, {1, 3});
  m.orientation_std = columns("orientation_std", optional("orientation_std"));
  if (!m.orientation_std.empty()) {
    expectCount("orientation_std", m.orientation_std, {1, 3});
    if (m.orientation.size() == 4)
      throw fail("orientation_std", "key 'orientation_std': expected no stds with a quaternion orientation (stds of quaternion "
                                    "components are not supported: give the orientation as angles or leave the stds out), found some");
  }
  m.weight = optional("weight");
  m.payload_kg = optional("payload_kg");
  m.temperature_c = optional("temperature_c");
  m.time_s = optional("time_s");
  m.directions = columns("directions", optional("directions"));
  if (!m.directions.empty()) expectCount("directions", m.directions, {static_cast<size_t>(robot.dof())});
  m.ignore = columns("ignore", optional("ignore"));

  // Each column of the export in one role: a column mapped twice would be read as two
  // quantities at once (x also as y, a temperature also as a weight) and one listed under
  // 'ignore' that is also mapped is both used and not. Refused at its second mention, in the
  // order of the file, naming the first.
  {
    static const std::set<std::string> roles = {"joints", "position", "orientation", "position_std", "orientation_std", "weight",
                                                 "payload_kg", "temperature_c", "time_s", "directions", "ignore"};
    struct First {
      std::string role;
      int line = 0;
    };
    std::map<std::string, First> seen;  // lower-cased column name -> its first role
    for (const auto& [key, ln] : m.key_lines) {
      if (!roles.count(key)) continue;
      const ValueText& t = value_text.at(key);
      size_t from = t.from;
      if (key == "orientation") {  // 'CONVENTION: names'
        const size_t colon = t.line.find(':', from);
        if (colon != std::string::npos && colon < t.to) from = colon + 1;
      }
      size_t start = from;
      for (size_t k = from; k <= t.to; ++k) {
        if (k < t.to && t.line[k] != ',') continue;
        const std::string piece = t.line.substr(start, k - start);
        const size_t lead = piece.find_first_not_of(" \t");
        if (lead != std::string::npos) {
          const std::string name = trimBlanks(piece);
          const int column = static_cast<int>(start + lead) + 1;
          const auto [it, first] = seen.emplace(lower(name), First{key, ln});
          if (!first)
            throw InputError(path, ln, column,
                             "key '" + key + "': expected each column in one role, found column '" + name + "' mapped twice (first as " +
                                 it->second.role + ", line " + std::to_string(it->second.line) + ")");
        }
        start = k + 1;
      }
    }
  }
  return m;
}

namespace {

/// The header row of a mapped file: its line (1-based), its names (trimmed) and their indices
/// by lower-cased name; rows start after it.
struct MappedHeader {
  size_t row = 0;  ///< index of the header in the file's lines
  int line = 0;
  std::vector<std::string> names;
  std::map<std::string, int> index;             ///< the first column of each name
  std::map<std::string, std::vector<int>> all;  ///< every column of each name (a name may repeat)
};

MappedHeader readHeader(const std::string& path, const std::vector<std::string>& lines, char delimiter) {
  MappedHeader h;
  while (h.row < lines.size() && (trimBlanks(lines[h.row]).empty() || trimBlanks(lines[h.row])[0] == '#')) ++h.row;
  if (h.row == lines.size()) throw InputError(path, 1, 1, "expected a header row, found an empty file");
  h.line = static_cast<int>(h.row) + 1;
  // a mapping given as the measurements (--data and --map swapped)
  if (const std::string note = mappingFileNote(lines[h.row]); !note.empty())
    throw InputError(path, h.line, 1, "expected a header row naming the export's columns, found a line of a mapping: " + note);
  h.names = splitFields(lines[h.row], delimiter);
  for (size_t c = 0; c < h.names.size(); ++c) {
    h.names[c] = trimBlanks(h.names[c]);
    if (h.names[c].empty()) continue;  // an unnamed column (a trailing delimiter): never mapped, reported as unused
    // a name may repeat (exports write 'std' after every value): ambiguous only when the mapping
    // uses it (mapColumns)
    const std::string key = lower(h.names[c]);
    h.index.emplace(key, static_cast<int>(c));
    h.all[key].push_back(static_cast<int>(c));
  }
  return h;
}

/// The field index of every mapped column (-1 / empty: not mapped) and the columns used.
struct MappedColumns {
  std::vector<int> joints, position, orientation, position_std, orientation_std, directions;
  int weight = -1, payload = -1, temperature = -1, time = -1;
  std::set<int> used;
  std::vector<std::string> ignored_absent;  ///< names under `ignore` the header does not have
};

/// Where the mapping states `key`: "FILE:LINE" (its last statement), or the file alone.
std::string mappingPlace(const MeasurementMapping& m, const std::string& key) {
  int line = 0;
  for (const auto& kl : m.key_lines)
    if (kl.first == key) line = kl.second;
  return m.file + (line ? ":" + std::to_string(line) : std::string());
}

/// The end of an error about a column in degrees read through `key` = rad (joint_unit,
/// orientation_unit).
std::string looksLikeDegrees(const MeasurementMapping& m, const std::string& key) {
  return "the column looks like degrees, not the radians the mapping states (" + key + " = rad in " + mappingPlace(m, key) +
         "); check the mapping's " + key;
}

MappedColumns mapColumns(const std::string& path, const MappedHeader& h, const MeasurementMapping& m) {
  MappedColumns c;
  auto col = [&](const std::string& name, const std::string& role) {
    auto it = h.index.find(lower(name));
    if (it == h.index.end()) {
      throw InputError(path, h.line, 1,
                       "expected a column '" + name + "' in the header, found none (mapped as " + role + " in " +
                           mappingPlace(m, role) + "; the delimiter is '" +
                           (m.delimiter == '\t' ? std::string("tab") : std::string(1, m.delimiter)) + "')");
    }
    const std::vector<int>& same = h.all.at(it->first);
    if (same.size() > 1)  // the mapping uses the name: which of its columns is meant is ambiguous
      throw InputError(path, h.line, same[1] + 1,
                       "expected each column name once in the header, found '" + h.names[static_cast<size_t>(same[1])] +
                           "' a second time (first as column " + std::to_string(same[0] + 1) + ")");
    c.used.insert(it->second);
    return it->second;
  };
  auto cols = [&](const std::vector<std::string>& names, const std::string& role) {
    std::vector<int> out;
    for (const auto& n : names) out.push_back(col(n, role));
    return out;
  };
  c.joints = cols(m.joints, "joints");
  c.position = cols(m.position, "position");
  c.orientation = cols(m.orientation, "orientation");
  c.position_std = cols(m.position_std, "position_std");
  c.orientation_std = cols(m.orientation_std, "orientation_std");
  c.directions = cols(m.directions, "directions");
  c.weight = m.weight.empty() ? -1 : col(m.weight, "weight");
  c.payload = m.payload_kg.empty() ? -1 : col(m.payload_kg, "payload_kg");
  c.temperature = m.temperature_c.empty() ? -1 : col(m.temperature_c, "temperature_c");
  c.time = m.time_s.empty() ? -1 : col(m.time_s, "time_s");
  for (const auto& n : m.ignore) {
    // a column to leave out that this export does not have loses nothing: said, not refused (one
    // mapping serves a data set's series, some written without a column others have)
    auto it = h.index.find(lower(n));
    if (it == h.index.end()) {
      c.ignored_absent.push_back(n);
      continue;
    }
    for (int same : h.all.at(it->first)) c.used.insert(same);  // every column of that name
  }
  return c;
}

/// One data row's fields, read as numbers with the file, line and column of a bad one.
struct MappedRow {
  const std::string& path;
  const std::vector<std::string>& header;
  const MeasurementMapping& m;
  int ln;
  std::vector<std::string> f;

  double num(int c) const {
    double v;
    if (!parseNumber(f[c], m.decimal, &v)) {
      const std::string shown = trimBlanks(f[c]).empty() ? "an empty field"
                                : "'" + trimBlanks(f[c]) + "'" +
                                      (f[c].find('\0') != std::string::npos ? " (\\0 is a NUL byte: a binary or corrupted file?)" : "");
      throw InputError(path, ln, c + 1, "column '" + header[c] + "': expected a number with '" + std::string(1, m.decimal) +
                                            "' as decimal mark, found " + shown);
    }
    return v;
  }
  /// Column c times `scale` (into accura's unit `unit`), a plausible value of `kind`
  /// (implausibleMeasuredValue: the CSV reader's ranges).
  double value(int c, double scale, MeasuredValue kind, const char* unit) const {
    const double v = num(c) * scale;
    const std::string expected = implausibleMeasuredValue(kind, v);
    if (!expected.empty()) {
      char converted[64] = "";
      if (scale != 1) std::snprintf(converted, sizeof converted, " (%.6g %s)", v, unit);
      throw InputError(path, ln, c + 1,
                       "column '" + header[c] + "': expected " + expected + ", found '" + trimBlanks(f[c]) + "'" + converted);
    }
    return v;
  }
};

/// The row's joint values (deg / mm), within the robot's joint limits.
void readJoints(const MappedRow& row, const std::vector<int>& jc, const RobotDefinition& robot, Measurement& r) {
  const int n = robot.dof();
  r.q.resize(n);
  for (int j = 0; j < n; ++j) {
    const JointSpec& js = robot.joints[j];
    const double raw = row.num(jc[j]);
    const double v = raw * (js.type == JointType::kRevolute ? row.m.joint_scale : row.m.prismatic_scale);
    if (!withinJointLimits(js, v)) {
      const char* unit = js.type == JointType::kRevolute ? "deg" : "mm";
      char buf[200];
      std::snprintf(buf, sizeof buf, "expected a joint value within the joint limits [%.10g, %.10g] %s, found %.6g %s", js.lower,
                    js.upper, unit, v, unit);
      // joint_unit = rad and a value beyond a turn in radians (2 pi) that is within the limits
      // read as degrees: the column is in degrees, whatever the mapping says
      std::string note = jointTurnNote(js, v);
      if (js.type == JointType::kRevolute && row.m.joint_scale != 1.0 && std::abs(raw) > 2 * kPi && withinJointLimits(js, raw)) {
        note = " (" + trimBlanks(row.f[static_cast<size_t>(jc[j])]) + " rad): a joint value beyond a turn in radians, and within the limits "
               "as degrees: " + looksLikeDegrees(row.m, "joint_unit");
      }
      throw InputError(row.path, row.ln, jc[j] + 1, "column '" + row.header[jc[j]] + "': " + buf + note);
    }
    r.q[j] = v;
  }
}

/// The row's orientation (a unit quaternion or three angles); returns the angles (rad; zero for
/// a quaternion).
Eigen::Vector3d readOrientation(const MappedRow& row, const MappedColumns& c, Measurement& r) {
  const MeasurementMapping& m = row.m;
  const std::vector<int>& oc = c.orientation;
  Eigen::Vector3d angles_rad = Eigen::Vector3d::Zero();
  r.has_orientation = true;
  if (oc.size() == 4) {
    double w, x, y, z;
    if (m.orientation_convention == "quaternion_wxyz") {
      w = row.num(oc[0]); x = row.num(oc[1]); y = row.num(oc[2]); z = row.num(oc[3]);
    } else {
      x = row.num(oc[0]); y = row.num(oc[1]); z = row.num(oc[2]); w = row.num(oc[3]);
    }
    const double norm = std::sqrt(w * w + x * x + y * y + z * z);
    if (std::abs(norm - 1.0) > 1e-3)
      throw InputError(row.path, row.ln, oc[0] + 1, "expected a unit quaternion (norm 1 within 1e-3), found norm " + std::to_string(norm));
    r.R_world_tcp = Eigen::Quaterniond(w / norm, x / norm, y / norm, z / norm);
  } else {
    for (int k = 0; k < 3; ++k) {
      // orientation_unit = rad and an angle beyond the plausible range that is within a turn read
      // as degrees: the column is in degrees, whatever the mapping says (as for a joint)
      const double raw = row.num(oc[k]);
      const std::string implausible =
          m.angle_scale != 1.0 && std::abs(raw) > 2 * kPi && std::abs(raw) <= 360.0 ? implausibleMeasuredValue(MeasuredValue::kAngleDeg, raw * m.angle_scale) : "";
      if (!implausible.empty()) {
        char buf[160];
        std::snprintf(buf, sizeof buf, "expected %s, found '%s' (%.6g deg)", implausible.c_str(),
                      trimBlanks(row.f[static_cast<size_t>(oc[k])]).c_str(), raw * m.angle_scale);
        throw InputError(row.path, row.ln, oc[k] + 1,
                         "column '" + row.header[static_cast<size_t>(oc[k])] + "': " + buf +
                             ": an angle beyond a turn in radians, and within a turn as degrees: " + looksLikeDegrees(m, "orientation_unit"));
      }
      angles_rad[k] = row.value(oc[k], m.angle_scale, MeasuredValue::kAngleDeg, "deg") * kDegToRad;
    }
    r.R_world_tcp = Eigen::Quaterniond(rotationFromAngles(m.orientation_convention, angles_rad));
  }
  return angles_rad;
}

/// The row's orientation stds (of the angles `angles_rad`) about the world axes.
void readOrientationStds(const MappedRow& row, const std::vector<int>& osc, const Eigen::Vector3d& angles_rad, Measurement& r) {
  const MeasurementMapping& m = row.m;
  Eigen::Vector3d s_angle;
  for (int k = 0; k < 3; ++k)
    s_angle[k] = row.value(osc[osc.size() == 1 ? 0 : k], m.angle_scale, MeasuredValue::kStd, "deg") * kDegToRad;
  // Euler-angle stds -> stds of the rotation about the world axes: Sigma_w = J S J^T with
  // J the derivative of the world rotation vector with respect to the angles (central
  // differences, step 1e-6 rad; the angles' own stds are ~1e-5 rad, linearisation exact enough).
  Eigen::Matrix3d J;
  for (int k = 0; k < 3; ++k) {
    const double h = 1e-6;
    Eigen::Vector3d ap = angles_rad, am = angles_rad;
    ap[k] += h;
    am[k] -= h;
    J.col(k) = logSO3(rotationFromAngles(m.orientation_convention, ap) * rotationFromAngles(m.orientation_convention, am).transpose()) /
               (2 * h);
  }
  const Eigen::Matrix3d S = J * s_angle.cwiseAbs2().asDiagonal() * J.transpose();
  for (int k = 0; k < 3; ++k) r.std_rot_deg[k] = std::sqrt(S(k, k)) * kRadToDeg;
}

/// One measurement of a data row.
Measurement readRow(const MappedRow& row, const MappedColumns& c, const RobotDefinition& robot) {
  Measurement r;
  r.line = row.ln;
  readJoints(row, c.joints, robot, r);
  for (int k = 0; k < 3; ++k)
    r.p_world_mm[k] = row.value(c.position[k], row.m.position_scale, MeasuredValue::kPositionMm, "mm");
  const Eigen::Vector3d angles_rad = c.orientation.empty() ? Eigen::Vector3d::Zero() : readOrientation(row, c, r);
  const std::vector<int>& psc = c.position_std;
  if (!psc.empty()) {
    for (int k = 0; k < 3; ++k)
      r.std_mm[k] = row.value(psc[psc.size() == 1 ? 0 : k], row.m.position_scale, MeasuredValue::kStd, "mm");
  }
  if (!c.orientation_std.empty()) readOrientationStds(row, c.orientation_std, angles_rad, r);
  if (c.weight >= 0) r.weight = row.value(c.weight, 1.0, MeasuredValue::kWeight, "");
  if (c.payload >= 0) r.context.payload_kg = row.value(c.payload, 1.0, MeasuredValue::kPayloadKg, "kg");
  if (c.temperature >= 0) r.temp_c = row.value(c.temperature, 1.0, MeasuredValue::kTemperatureC, "deg C");
  if (c.time >= 0) r.time_s = row.value(c.time, 1.0, MeasuredValue::kTimeS, "s");
  for (int col : c.directions) {
    const double d = row.num(col);
    if (d != 1.0 && d != -1.0)
      throw InputError(row.path, row.ln, col + 1, "column '" + row.header[col] + "': expected +1 or -1, found " + trimBlanks(row.f[col]));
    r.dir.push_back(static_cast<int>(d));
  }
  // the model's context (kinematics.h): temperature and approach directions, when given
  if (c.temperature >= 0) r.context.temp_c = r.temp_c;
  r.context.dir = r.dir;
  return r;
}

}  // namespace

/// The steps: the header, the mapped columns, then every data row.
MeasurementSet readMappedMeasurements(const std::string& path, const MeasurementMapping& m,
                                      const RobotDefinition& robot) {
  const std::vector<std::string> lines = readLines(path);
  const MappedHeader h = readHeader(path, lines, m.delimiter);
  const MappedColumns c = mapColumns(path, h, m);
  MeasurementSet set;
  set.file = path;
  set.has_orientation = !c.orientation.empty();
  set.has_std_position = !c.position_std.empty();
  set.has_std_orientation = !c.orientation_std.empty();
  set.has_weight = c.weight >= 0;
  set.has_payload = c.payload >= 0;
  set.has_temperature = c.temperature >= 0;
  set.has_time = c.time >= 0;
  set.has_direction = !c.directions.empty();
  set.ignored_absent_columns = c.ignored_absent;
  {
    const auto stated = [&](const std::string& key, const std::string& unit) {
      set.units.push_back({key, unit, mappingPlace(m, key)});
      return key + " = " + unit + " (" + set.units.back().place + ")";
    };
    const bool prismatic = std::any_of(robot.joints.begin(), robot.joints.end(), [](const JointSpec& j) { return j.type == JointType::kPrismatic; });
    const bool revolute = std::any_of(robot.joints.begin(), robot.joints.end(), [](const JointSpec& j) { return j.type == JointType::kRevolute; });
    set.units_stated = (revolute ? stated("joint_unit", m.joint_scale == 1.0 ? "deg" : "rad") + ", " : std::string()) +
                       (prismatic ? stated("prismatic_unit", m.prismatic_scale == 1.0 ? "mm" : "m") + ", " : std::string()) +
                       stated("position_unit", m.position_scale == 1.0 ? "mm" : "m");
  }
  const std::string delimiter = m.delimiter == '\t' ? std::string("tab") : "'" + std::string(1, m.delimiter) + "'";
  for (size_t k = 0; k < h.names.size(); ++k) {
    if (c.used.count(static_cast<int>(k))) continue;
    if (!h.names[k].empty()) set.unknown_columns.push_back(h.names[k]);
    else if (k + 1 == h.names.size()) set.unknown_columns.push_back("an empty column at the end (a trailing " + delimiter + ")");
    else set.unknown_columns.push_back("an unnamed column " + std::to_string(k + 1));
  }
  // a trailing delimiter on the header or on the rows only: named when the field count differs
  const auto endsWithDelimiter = [&](const std::string& l) { const std::string t = trimBlanks(l); return !t.empty() && t.back() == m.delimiter; };
  const bool header_trails = endsWithDelimiter(lines[h.row]);
  for (size_t li = h.row + 1; li < lines.size(); ++li) {
    const std::string t = trimBlanks(lines[li]);
    if (t.empty() || t[0] == '#') continue;
    const MappedRow row{path, h.names, m, static_cast<int>(li) + 1, splitFields(lines[li], m.delimiter)};
    // the header again (two exports concatenated): said as such, not as a field that is no number;
    // with the second export's byte-order mark before it when they were joined byte for byte
    // (cat a.csv b.csv)
    const std::vector<std::string> again =
        lines[li].rfind("\xEF\xBB\xBF", 0) == 0 ? splitFields(lines[li].substr(3), m.delimiter) : row.f;
    if (again.size() == h.names.size()) {
      bool header = true;
      for (size_t k = 0; header && k < h.names.size(); ++k) header = lower(trimBlanks(again[k])) == lower(h.names[k]);
      if (header)
        throw InputError(path, row.ln, 1, headerRowAgainMessage(h.line));
    }
    if (row.f.size() != h.names.size()) {
      const bool row_trails = endsWithDelimiter(lines[li]);
      const std::string note = row_trails && !header_trails
                                   ? " (the line ends with " + delimiter + ", the header does not: a trailing delimiter on the rows only)"
                               : header_trails && !row_trails
                                   ? " (the header ends with " + delimiter + ": an empty column at the end, which every row must have too)"
                                   : "";
      throw InputError(path, row.ln, static_cast<int>(std::min(row.f.size(), h.names.size())) + 1,
                       "expected " + std::to_string(h.names.size()) + " fields as in the header, found " +
                           std::to_string(row.f.size()) + note);
    }
    set.rows.push_back(readRow(row, c, robot));
  }
  if (set.rows.empty()) throw InputError(path, h.line, 1, "expected at least one data row after the header, found none");
  return set;
}

}  // namespace accura::calib
