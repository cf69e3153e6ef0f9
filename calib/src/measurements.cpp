// accura: measurement CSV files (docs/measurement-format.md).
#include "accura/calib/measurements.h"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <map>
#include <numeric>
#include <string_view>
#include <system_error>
#include <unordered_map>

#include "accura/calib/errors.h"
#include "accura/calib/file_io.h"
#include "accura/calib/import.h"
#include "accura/calib/text.h"

namespace accura::calib {
namespace {

// ---------------------------------------------------------------------------------------
// Small text helpers

std::string_view trim(std::string_view s) {
  const auto is_space = [](char c) { return c == ' ' || c == '\t'; };
  while (!s.empty() && is_space(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_space(s.back())) s.remove_suffix(1);
  return s;
}

std::string toLower(std::string_view s) {
  std::string out(s);
  for (char& c : out) {
    if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
  }
  return out;
}

std::vector<std::string_view> splitFields(std::string_view line) {
  std::vector<std::string_view> fields;
  std::size_t start = 0;
  for (;;) {
    const std::size_t comma = line.find(',', start);
    if (comma == std::string_view::npos) {
      fields.push_back(line.substr(start));
      return fields;
    }
    fields.push_back(line.substr(start, comma - start));
    start = comma + 1;
  }
}

/// A field as shown in messages: 'text' (shortened when long) or "an empty field"; a NUL byte
/// in it (a binary or corrupted file) is shown as \0 and named.
std::string shown(std::string_view field) {
  field = trim(field);
  if (field.empty()) return "an empty field";
  constexpr std::size_t kMax = 40;
  const bool nul = field.find('\0') != std::string_view::npos;
  std::string text(field.substr(0, std::min(field.size(), kMax)));
  for (std::size_t p = text.find('\0'); p != std::string::npos; p = text.find('\0', p + 2)) text.replace(p, 1, "\\0");
  return "'" + text + (field.size() > kMax ? "...'" : "'") + (nul ? " (\\0 is a NUL byte: a binary or corrupted file?)" : "");
}

/// The note on a field count that differs from the header's when a trailing delimiter explains it.
std::string trailingDelimiterNote(std::string_view header, std::string_view row) {
  const bool h = !trim(header).empty() && trim(header).back() == ',', r = !trim(row).empty() && trim(row).back() == ',';
  if (r && !h) return " (the line ends with ',', the header does not: a trailing delimiter on the rows only)";
  if (h && !r) return " (the header ends with ',': an empty column at the end, which every row must have too)";
  return "";
}

/// The note on a row with more fields than the header when a decimal comma explains it: the
/// line has no '.' at all, and its fields look like numbers split at a decimal comma: at least
/// three fields too many (a spreadsheet of a locale that writes 1,5 for 1.5 splits every
/// measured coordinate, and a tracker's x, y, z are never whole millimetres), or at least two
/// and a field that can only be the digits after a decimal comma ("087" of 0,087: a whole
/// number has no leading zero). Two whole numbers too many are as likely stray values.
std::string decimalCommaNote(std::string_view row, std::size_t found, std::size_t expected) {
  if (found < expected + 2 || row.find('.') != std::string_view::npos) return "";
  bool fraction_digits = false;
  for (std::size_t b = 0; b <= row.size() && !fraction_digits;) {
    std::size_t e = row.find(',', b);
    if (e == std::string_view::npos) e = row.size();
    const std::string_view f = trim(row.substr(b, e - b));
    fraction_digits = f.size() >= 2 && f[0] == '0' && f.find_first_not_of("0123456789") == std::string_view::npos;
    b = e + 1;
  }
  if (found < expected + 3 && !fraction_digits) return "";
  return " (no '.' in the line: a decimal comma? numbers take a decimal point, ',' separates the fields)";
}

/// Shortest text that reads back as the same double ("40", "-155", "0.1").
std::string shortest(double v) {
  char buf[64];
  const auto res = std::to_chars(buf, buf + sizeof(buf), v);
  if (res.ec != std::errc()) return std::to_string(v);
  return std::string(buf, res.ptr);
}

/// Parses a whole field as a finite double (C locale; spaces around it allowed; a leading
/// '+' allowed). On failure returns false and sets `why` to "expected ..., found ...".
bool parseNumber(std::string_view field, double& value, std::string& why) {
  std::string_view text = trim(field);
  if (text.empty()) {
    why = "expected a number, found an empty field";
    return false;
  }
  std::string_view digits = text;
  if (digits.size() > 1 && digits[0] == '+' && digits[1] != '+' && digits[1] != '-') {
    digits.remove_prefix(1);
  }
  double v = 0;
  const auto res = std::from_chars(digits.data(), digits.data() + digits.size(), v,
                                   std::chars_format::general);
  if (res.ec == std::errc::invalid_argument || res.ptr != digits.data() + digits.size()) {
    why = "expected a number, found " + shown(text);
    return false;
  }
  if (res.ec == std::errc::result_out_of_range) {
    why = "expected a finite number within the range of a double, found " + shown(text);
    return false;
  }
  if (res.ec != std::errc() || !std::isfinite(v)) {
    why = "expected a finite number, found " + shown(text);
    return false;
  }
  value = v;
  return true;
}

/// "q1..q6" (or "q1" for a one-axis robot).
std::string rangeName(const std::string& prefix, int n) {
  if (n == 1) return prefix + "1";
  return prefix + "1.." + prefix + std::to_string(n);
}

std::string joinNames(const std::vector<std::string>& names, bool quoted) {
  std::string out;
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (i > 0) out += ", ";
    out += quoted ? "'" + names[i] + "'" : names[i];
  }
  return out;
}

// ---------------------------------------------------------------------------------------
// Columns

enum class Role {
  kUnknown,
  kQ, kX, kY, kZ,
  kQw, kQx, kQy, kQz,
  kA, kB, kC,
  kStdX, kStdY, kStdZ, kStdMm,
  kStdRx, kStdRy, kStdRz, kStdDeg,
  kWeight, kPayload, kTemp, kDir, kTime,
};

struct Column {
  Role role = Role::kUnknown;
  int joint = -1;    ///< 0-based joint index for q and dir columns
  std::string name;  ///< as written in the header (trimmed)
};

Role fixedRole(const std::string& key) {
  static const std::pair<const char*, Role> kNames[] = {
      {"x", Role::kX},           {"y", Role::kY},           {"z", Role::kZ},
      {"qw", Role::kQw},         {"qx", Role::kQx},         {"qy", Role::kQy},
      {"qz", Role::kQz},         {"a", Role::kA},           {"b", Role::kB},
      {"c", Role::kC},           {"std_x", Role::kStdX},    {"std_y", Role::kStdY},
      {"std_z", Role::kStdZ},    {"std_mm", Role::kStdMm},  {"std_rx", Role::kStdRx},
      {"std_ry", Role::kStdRy},  {"std_rz", Role::kStdRz},  {"std_deg", Role::kStdDeg},
      {"weight", Role::kWeight}, {"payload_kg", Role::kPayload},
      {"temp_c", Role::kTemp},   {"time_s", Role::kTime},
  };
  for (const auto& [name, role] : kNames) {
    if (key == name) return role;
  }
  return Role::kUnknown;
}

/// If `key` is PREFIX followed by digits only, returns true and the digits.
bool indexedName(const std::string& key, const std::string& prefix, std::string& digits) {
  if (key.size() <= prefix.size() || key.compare(0, prefix.size(), prefix) != 0) return false;
  digits = key.substr(prefix.size());
  return std::all_of(digits.begin(), digits.end(), [](char c) { return c >= '0' && c <= '9'; });
}

/// 1-based index of "q3" / "dir3", or 0 when the digits are not a joint of the robot
/// ("q0", "q07", "q7" on a six-axis robot).
int jointNumber(const std::string& digits, int dof) {
  if (digits.empty() || digits[0] == '0' || digits.size() > 4) return 0;
  const int k = std::stoi(digits);
  return k <= dof ? k : 0;
}

struct Layout {
  std::vector<Column> columns;
  std::vector<int> q_col;    ///< field index (0-based) of q_i, -1 when missing
  std::vector<int> dir_col;  ///< field index of dir_i, -1 when missing
  int col[static_cast<int>(Role::kTime) + 1];  ///< field index per fixed role, -1 = absent

  int at(Role r) const { return col[static_cast<int>(r)]; }
  bool has(Role r) const { return at(r) >= 0; }
};

class MeasurementReader {
 public:
  MeasurementReader(const std::string& path, const RobotDefinition& robot)
      : path_(path), robot_(robot), dof_(robot.dof()) {}

  MeasurementSet read();

 private:
  [[noreturn]] void fail(int line, int column, const std::string& message) const {
    throw InputError(path_, line, column, message);
  }
  std::string loadFile() const;
  void parseHeader(std::string_view text, int line);
  void checkGroups(int line) const;
  void requireGroup(int line, const std::string& what, const std::vector<Role>& roles,
                    const std::vector<std::string>& names) const;
  Measurement parseRow(std::string_view text, int line) const;
  bool isHeaderAgain(std::string_view text) const;

  const std::string& path_;
  const RobotDefinition& robot_;
  const int dof_;
  /// 1-based field number of the first of `roles` the header has (1 when none).
  int firstColumn(const std::vector<Role>& roles) const {
    int first = -1;
    for (Role r : roles)
      if (layout_.has(r) && (first < 0 || layout_.at(r) < first)) first = layout_.at(r);
    return first + 1 > 0 ? first + 1 : 1;
  }

  Layout layout_{};
  int header_line_ = 0;
  std::string header_text_;
  MeasurementSet set_;
};

std::string MeasurementReader::loadFile() const {
  errno = 0;
  std::FILE* f = std::fopen(path_.c_str(), "rb");
  if (f == nullptr) {
    fail(0, 0, "cannot open file: " + std::string(std::strerror(errno ? errno : ENOENT)));
  }
  std::string content;
  char buf[65536];
  for (;;) {
    const std::size_t n = std::fread(buf, 1, sizeof(buf), f);
    content.append(buf, n);
    if (n < sizeof(buf)) break;
  }
  const bool bad = std::ferror(f) != 0;
  const int err = errno;
  std::fclose(f);
  if (bad) fail(0, 0, "cannot open file: " + std::string(std::strerror(err ? err : EIO)));
  return content;
}

void MeasurementReader::parseHeader(std::string_view text, int line) {
  std::fill(std::begin(layout_.col), std::end(layout_.col), -1);
  layout_.q_col.assign(static_cast<std::size_t>(dof_), -1);
  layout_.dir_col.assign(static_cast<std::size_t>(dof_), -1);

  // a mapping given as the measurements (--data and --map swapped)
  if (const std::string note = mappingFileNote(std::string(text)); !note.empty())
    fail(line, 1, "expected a header row (" + rangeName("q", dof_) + ", x, y, z), found a line of a mapping: " + note);
  const std::vector<std::string_view> fields = splitFields(text);
  // A file without its header row (a data row first): the numbers taken as names would fail as
  // a duplicate name or a missing column, which does not say that the names are missing.
  double first_value = 0;
  std::string why;
  if (parseNumber(fields.front(), first_value, why))
    fail(line, 1, "expected a header row (" + rangeName("q", dof_) + ", x, y, z), found a row starting with the number " +
                      shown(trim(fields.front())) + ": the first line that is neither a comment nor blank names the columns");
  std::vector<std::string> keys;
  for (std::size_t i = 0; i < fields.size(); ++i) {
    const int column = static_cast<int>(i) + 1;
    Column c;
    c.name = std::string(trim(fields[i]));
    if (c.name.empty() && i + 1 == fields.size() && fields.size() > 1) {
      // a trailing ',' (spreadsheets write one): an empty column at the end, not used; every row
      // must have it (the field count), its values are not read
      layout_.columns.push_back(std::move(c));
      set_.unknown_columns.push_back("an empty column at the end (a trailing ',')");
      continue;
    }
    if (c.name.empty()) fail(line, column, "expected a column name, found an empty field");
    const std::string key = toLower(c.name);
    const auto dup = std::find(keys.begin(), keys.end(), key);
    if (dup != keys.end()) {
      fail(line, column,
           "column '" + c.name + "': expected each column name once, found a duplicate of column " +
               std::to_string(dup - keys.begin() + 1));
    }
    keys.push_back(key);

    std::string digits;
    if (indexedName(key, "q", digits) || indexedName(key, "dir", digits)) {
      const bool is_q = key[0] == 'q';
      const int k = jointNumber(digits, dof_);
      if (k == 0) {
        fail(line, column,
             "column '" + c.name + "': expected " + (is_q ? "joint" : "direction") +
                 " columns " + rangeName(is_q ? "q" : "dir", dof_) + " for this " +
                 std::to_string(dof_) + "-axis robot, found '" + c.name + "'");
      }
      c.role = is_q ? Role::kQ : Role::kDir;
      c.joint = k - 1;
      (is_q ? layout_.q_col : layout_.dir_col)[static_cast<std::size_t>(k - 1)] =
          static_cast<int>(i);
    } else {
      c.role = fixedRole(key);
      if (c.role == Role::kUnknown) {
        set_.unknown_columns.push_back(c.name);
      } else {
        layout_.col[static_cast<int>(c.role)] = static_cast<int>(i);
      }
    }
    layout_.columns.push_back(std::move(c));
  }
  checkGroups(line);
}

/// A group of columns that must appear together (all or none).
void MeasurementReader::requireGroup(int line, const std::string& what, const std::vector<Role>& roles,
                                     const std::vector<std::string>& names) const {
  std::vector<std::string> found, missing;
  for (std::size_t i = 0; i < roles.size(); ++i) {
    (layout_.has(roles[i]) ? found : missing).push_back(names[i]);
  }
  if (!found.empty() && !missing.empty()) {
    fail(line, firstColumn(roles),
         "incomplete " + what + " columns: expected " + joinNames(names, false) +
             " together, found " + joinNames(found, false) + " (missing " +
             joinNames(missing, true) + ")");
  }
}

void MeasurementReader::checkGroups(int line) const {
  const Layout& L = layout_;
  // Required columns.
  std::vector<std::string> missing;
  for (int i = 0; i < dof_; ++i) {
    if (L.q_col[static_cast<std::size_t>(i)] < 0) missing.push_back("q" + std::to_string(i + 1));
  }
  if (!L.has(Role::kX)) missing.push_back("x");
  if (!L.has(Role::kY)) missing.push_back("y");
  if (!L.has(Role::kZ)) missing.push_back("z");
  if (!missing.empty()) {
    std::string msg = std::string(missing.size() == 1 ? "missing column " : "missing columns ") +
                      joinNames(missing, true) + " (expected " + rangeName("q", dof_) +
                      ", x, y, z)";
    if (L.columns.size() == 1 &&
        L.columns[0].name.find_first_of(";\t") != std::string::npos) {
      // (a spreadsheet's export with ';' usually has decimal commas too: the mapping reads both)
      msg += "; the delimiter is ',', found a header with ';' or tabs (an export with another delimiter or decimal commas is read "
             "as it is through a mapping file, --map: docs/measurement-mapping.md)";
    }
    // units in the names ('q1 [deg]', 'x (mm)'): an export's layout, not this format's
    for (const auto& c : L.columns) {
      if (c.role != Role::kUnknown) continue;
      const std::size_t cut = c.name.find_first_of(" [(_");
      if (cut == std::string::npos || cut == 0) continue;
      const std::string bare = toLower(c.name.substr(0, cut));
      std::string digits;
      if (bare == "x" || bare == "y" || bare == "z" || (indexedName(bare, "q", digits) && jointNumber(digits, dof_) > 0)) {
        msg += "; found '" + c.name + "': the format's names carry no unit (q in deg or mm, x, y, z in mm); read the export "
               "through a mapping file: docs/measurement-mapping.md";
        break;
      }
    }
    for (const auto& c : L.columns)
      if (!c.name.empty() && c.name.front() == '"') {
        msg += "; the format has no quoting, found the quoted name " + c.name +
               " (remove the quotes, or read the export through a mapping file: docs/measurement-mapping.md)";
        break;
      }
    fail(line, 1, msg);
  }

  // Orientation: qw,qx,qy,qz or a,b,c.
  const bool any_quat = L.has(Role::kQw) || L.has(Role::kQx) || L.has(Role::kQy) ||
                        L.has(Role::kQz);
  const bool any_abc = L.has(Role::kA) || L.has(Role::kB) || L.has(Role::kC);
  if (any_quat && any_abc) {
    fail(line, firstColumn({Role::kA, Role::kB, Role::kC}),
         "expected orientation as either qw, qx, qy, qz or a, b, c, found both");
  }
  requireGroup(line, "orientation", {Role::kQw, Role::kQx, Role::kQy, Role::kQz},
               {"qw", "qx", "qy", "qz"});
  requireGroup(line, "orientation", {Role::kA, Role::kB, Role::kC}, {"a", "b", "c"});

  // Standard deviations.
  const bool any_std_xyz = L.has(Role::kStdX) || L.has(Role::kStdY) || L.has(Role::kStdZ);
  if (any_std_xyz && L.has(Role::kStdMm)) {
    fail(line, firstColumn({Role::kStdMm}),
         "expected position standard deviations as either std_x, std_y, std_z or std_mm, "
         "found both");
  }
  requireGroup(line, "position standard deviation", {Role::kStdX, Role::kStdY, Role::kStdZ},
               {"std_x", "std_y", "std_z"});
  const bool any_std_r = L.has(Role::kStdRx) || L.has(Role::kStdRy) || L.has(Role::kStdRz);
  if (any_std_r && L.has(Role::kStdDeg)) {
    fail(line, firstColumn({Role::kStdDeg}),
         "expected orientation standard deviations as either std_rx, std_ry, std_rz or "
         "std_deg, found both");
  }
  requireGroup(line, "orientation standard deviation",
               {Role::kStdRx, Role::kStdRy, Role::kStdRz}, {"std_rx", "std_ry", "std_rz"});
  if ((any_std_r || L.has(Role::kStdDeg)) && !any_quat && !any_abc) {
    int first = -1;
    for (Role r : {Role::kStdRx, Role::kStdRy, Role::kStdRz, Role::kStdDeg}) {
      if (L.has(r) && (first < 0 || L.at(r) < first)) first = L.at(r);
    }
    const std::string& name = L.columns[static_cast<std::size_t>(first)].name;
    fail(line, first + 1,
         "column '" + name +
             "': expected orientation columns (qw, qx, qy, qz or a, b, c) with an orientation "
             "standard deviation, found none");
  }

  // Directions: all or none.
  std::vector<std::string> dir_found, dir_missing;
  for (int i = 0; i < dof_; ++i) {
    const std::string name = "dir" + std::to_string(i + 1);
    (L.dir_col[static_cast<std::size_t>(i)] >= 0 ? dir_found : dir_missing).push_back(name);
  }
  if (!dir_found.empty() && !dir_missing.empty()) {
    int first = static_cast<int>(L.columns.size());
    for (int c : L.dir_col)
      if (c >= 0) first = std::min(first, c);
    fail(line, first + 1,
         "incomplete direction columns: expected " + rangeName("dir", dof_) +
             " together, found " + joinNames(dir_found, false) + " (missing " +
             joinNames(dir_missing, true) + ")");
  }
}

/// The kind of value a column of `role` holds (kQ, kDir and the quaternion: none, never asked).
MeasuredValue measuredValueOf(Role role) {
  switch (role) {
    case Role::kStdX: case Role::kStdY: case Role::kStdZ: case Role::kStdMm:
    case Role::kStdRx: case Role::kStdRy: case Role::kStdRz: case Role::kStdDeg:
      return MeasuredValue::kStd;
    case Role::kWeight: return MeasuredValue::kWeight;
    case Role::kPayload: return MeasuredValue::kPayloadKg;
    case Role::kA: case Role::kB: case Role::kC: return MeasuredValue::kAngleDeg;
    case Role::kTemp: return MeasuredValue::kTemperatureC;
    case Role::kTime: return MeasuredValue::kTimeS;
    default: return MeasuredValue::kPositionMm;  // x, y, z (a quaternion's entries are within it)
  }
}

Measurement MeasurementReader::parseRow(std::string_view text, int line) const {
  const Layout& L = layout_;
  const std::vector<std::string_view> fields = splitFields(text);
  if (fields.size() != L.columns.size()) {
    // at the first field beyond the header's, or where the first missing one would start; the
    // likely cause: a trailing delimiter, else a decimal comma
    const std::string trailing = trailingDelimiterNote(header_text_, text);
    fail(line, static_cast<int>(std::min(fields.size(), L.columns.size())) + 1,
         "expected " + std::to_string(L.columns.size()) + " fields as in the header, found " + std::to_string(fields.size()) +
             (trailing.empty() ? decimalCommaNote(text, fields.size(), L.columns.size()) : trailing));
  }

  Measurement m;
  m.line = line;
  m.q = Eigen::VectorXd::Zero(dof_);
  if (set_.has_direction) m.dir.assign(static_cast<std::size_t>(dof_), 1);
  double value[static_cast<int>(Role::kTime) + 1] = {};

  for (std::size_t i = 0; i < fields.size(); ++i) {
    const Column& c = L.columns[i];
    if (c.role == Role::kUnknown) continue;
    const int column = static_cast<int>(i) + 1;
    const std::string where = "column '" + c.name + "': ";
    double v = 0;
    std::string why;
    if (!parseNumber(fields[i], v, why)) fail(line, column, where + why);

    switch (c.role) {
      case Role::kQ: {
        const JointSpec& joint = robot_.joints[static_cast<std::size_t>(c.joint)];
        if (!withinJointLimits(joint, v)) {
          const char* unit = joint.type == JointType::kRevolute ? " deg" : " mm";
          fail(line, column,
               where + "expected a joint value within the joint limits [" + shortest(joint.lower) + ", " +
                   shortest(joint.upper) + "]" + unit + ", found " + shortest(v) + unit + jointTurnNote(joint, v));
        }
        m.q[c.joint] = v;
        break;
      }
      case Role::kDir:
        if (v != 1.0 && v != -1.0) {
          fail(line, column, where + "expected +1 or -1, found " + shown(fields[i]));
        }
        m.dir[static_cast<std::size_t>(c.joint)] = v > 0 ? 1 : -1;
        break;
      case Role::kQw: case Role::kQx: case Role::kQy: case Role::kQz:
        break;  // (the quaternion's norm is checked below)
      default: {
        const std::string expected = implausibleMeasuredValue(measuredValueOf(c.role), v);
        if (!expected.empty()) fail(line, column, where + "expected " + expected + ", found " + shown(fields[i]));
        break;
      }
    }
    if (c.role != Role::kQ && c.role != Role::kDir) value[static_cast<int>(c.role)] = v;
  }

  const auto val = [&value](Role r) { return value[static_cast<int>(r)]; };
  m.p_world_mm = Eigen::Vector3d(val(Role::kX), val(Role::kY), val(Role::kZ));

  if (L.has(Role::kQw)) {
    const Eigen::Quaterniond q(val(Role::kQw), val(Role::kQx), val(Role::kQy), val(Role::kQz));
    const double norm = q.norm();
    if (!(std::abs(norm - 1.0) <= 1e-3)) {
      fail(line, L.at(Role::kQw) + 1,
           "columns 'qw', 'qx', 'qy', 'qz': expected a unit quaternion (norm 1 within 1e-3), "
           "found norm " + shortest(norm));
    }
    m.has_orientation = true;
    m.R_world_tcp = q.normalized();
  } else if (L.has(Role::kA)) {
    constexpr double kDeg = 3.14159265358979323846 / 180.0;
    const Eigen::Matrix3d R =
        (Eigen::AngleAxisd(val(Role::kA) * kDeg, Eigen::Vector3d::UnitZ()) *
         Eigen::AngleAxisd(val(Role::kB) * kDeg, Eigen::Vector3d::UnitY()) *
         Eigen::AngleAxisd(val(Role::kC) * kDeg, Eigen::Vector3d::UnitX()))
            .toRotationMatrix();
    m.has_orientation = true;
    m.R_world_tcp = Eigen::Quaterniond(R).normalized();
  }

  if (L.has(Role::kStdX)) {
    m.std_mm = Eigen::Vector3d(val(Role::kStdX), val(Role::kStdY), val(Role::kStdZ));
  } else if (L.has(Role::kStdMm)) {
    m.std_mm = Eigen::Vector3d::Constant(val(Role::kStdMm));
  }
  if (L.has(Role::kStdRx)) {
    m.std_rot_deg = Eigen::Vector3d(val(Role::kStdRx), val(Role::kStdRy), val(Role::kStdRz));
  } else if (L.has(Role::kStdDeg)) {
    m.std_rot_deg = Eigen::Vector3d::Constant(val(Role::kStdDeg));
  }
  if (L.has(Role::kWeight)) m.weight = val(Role::kWeight);
  if (L.has(Role::kPayload)) m.context.payload_kg = val(Role::kPayload);
  if (L.has(Role::kTemp)) m.temp_c = val(Role::kTemp);
  if (L.has(Role::kTime)) m.time_s = val(Role::kTime);
  // The model's context (kinematics.h): temperature and approach directions, when given.
  if (L.has(Role::kTemp)) m.context.temp_c = m.temp_c;
  m.context.dir = m.dir;
  return m;
}

/// True when the row `text` names the header's columns again (case-insensitive, trimmed), a
/// byte-order mark before it or not.
bool MeasurementReader::isHeaderAgain(std::string_view text) const {
  if (text.substr(0, 3) == "\xEF\xBB\xBF") text.remove_prefix(3);
  const std::vector<std::string_view> fields = splitFields(text);
  if (fields.size() != layout_.columns.size()) return false;
  for (std::size_t i = 0; i < fields.size(); ++i)
    if (toLower(trim(fields[i])) != toLower(layout_.columns[i].name)) return false;
  return true;
}

MeasurementSet MeasurementReader::read() {
  if (dof_ < 1) throw ArgumentError("readMeasurementsCsv: the robot has no joints");
  set_.file = path_;
  const std::string content = loadFile();
  int bad_line = 0;
  if (const std::string why = unsplittableText(content, &bad_line); !why.empty()) fail(bad_line, 1, why);

  bool have_header = false;
  bool saw_anything = false;
  int line = 0;
  std::size_t pos = 0;
  while (pos < content.size()) {
    std::size_t end = content.find('\n', pos);
    if (end == std::string::npos) end = content.size();
    std::string_view text(content.data() + pos, end - pos);
    pos = end + 1;
    ++line;
    if (!text.empty() && text.back() == '\r') text.remove_suffix(1);
    if (line == 1 && text.substr(0, 3) == "\xEF\xBB\xBF") text.remove_prefix(3);  // UTF-8 BOM
    const std::string_view trimmed = trim(text);
    if (trimmed.empty()) continue;
    saw_anything = true;
    if (trimmed.front() == '#') continue;

    if (!have_header) {
      parseHeader(text, line);
      have_header = true;
      header_line_ = line;
      header_text_ = std::string(text);
      set_.has_orientation = layout_.has(Role::kQw) || layout_.has(Role::kA);
      set_.has_std_position = layout_.has(Role::kStdX) || layout_.has(Role::kStdMm);
      set_.has_std_orientation = layout_.has(Role::kStdRx) || layout_.has(Role::kStdDeg);
      set_.has_weight = layout_.has(Role::kWeight);
      set_.has_payload = layout_.has(Role::kPayload);
      set_.has_temperature = layout_.has(Role::kTemp);
      set_.has_direction = layout_.dir_col[0] >= 0;
      set_.has_time = layout_.has(Role::kTime);
      continue;
    }
    // the header again (two exports concatenated, the second one's byte-order mark before it when
    // joined byte for byte): said as such, not as a field that is no number ("found 'q1'")
    if (isHeaderAgain(text)) {
      fail(line, 1, headerRowAgainMessage(header_line_));
    }
    set_.rows.push_back(parseRow(text, line));
  }

  if (!have_header) {
    fail(1, 1,
         "expected a header row (" + rangeName("q", dof_) + ", x, y, z), found " +
             (saw_anything ? "only comments and blank lines" : "an empty file"));
  }
  if (set_.rows.empty()) fail(header_line_, 1, "expected at least one data row after the header, found none");
  return std::move(set_);
}

// ---------------------------------------------------------------------------------------
// Writing

void appendFixed(std::string& out, double v, int decimals) { out += formatFixed(v, decimals); }

void requireFinite(double v, std::size_t row, const char* what) {
  if (!std::isfinite(v)) {
    throw ArgumentError("writeMeasurementsCsv: row " + std::to_string(row + 1) + ": " + what +
                        " is not finite");
  }
}

/// Values that must read back as > 0 must also print as > 0 with 6 decimals.
void requirePositive(double v, std::size_t row, const char* what) {
  requireFinite(v, row, what);
  if (!(v >= 0.5e-6)) {
    throw ArgumentError("writeMeasurementsCsv: row " + std::to_string(row + 1) + ": " + what +
                        " must be at least 0.000001 to be written, got " + std::to_string(v));
  }
}

}  // namespace

std::string jointTurnNote(const JointSpec& joint, double v) {
  if (joint.type != JointType::kRevolute || joint.lower != -360.0 || joint.upper != 360.0 || std::abs(v) <= 360.0) return "";
  if (!std::isfinite(v) || std::abs(v) > 1e9) return "";
  const double within = v - 360.0 * std::round(v / 360.0);
  return "; -360..360 deg is also what a joint without limits (a URDF's continuous joint) is given: " + shortest(v) +
         " deg is the pose of " + shortest(within) + " deg, give the value within a turn";
}

std::string headerRowAgainMessage(int header_line) {
  return "expected a data row, found the header row again (the header is line " + std::to_string(header_line) +
         "): two exports joined into one file? Split them, or delete the repeated header";
}

std::string unsplittableText(const std::string& content, int* line) {
  *line = 1;
  if (content.rfind("\xFF\xFE", 0) == 0 || content.rfind("\xFE\xFF", 0) == 0)
    return std::string("expected UTF-8 or ASCII text, found UTF-16 (the byte-order mark ") + (content[0] == '\xFF' ? "FF FE" : "FE FF") +
           " at the start of the file): save the export as UTF-8 text (a spreadsheet's 'CSV UTF-8', not 'Unicode Text')";
  // (UTF-16 of ASCII text: every other byte NUL; a NUL further on, in a comment, is not this)
  if (content.size() >= 2 && (content[0] == '\0' || content[1] == '\0'))
    return "expected UTF-8 or ASCII text, found a NUL byte at the start of the file (UTF-16 text without a byte-order mark, or a "
           "binary file?): save the export as UTF-8 text";
  const bool has_lf = content.find('\n') != std::string::npos;
  for (std::size_t p = content.find('\r'); p != std::string::npos; p = content.find('\r', p + 1)) {
    if (p + 1 < content.size() && content[p + 1] == '\n') continue;
    if (p + 1 == content.size()) continue;  // (the last line's CR: read as the end of the line)
    // a stray CR in a comment of a file with LF line ends is not read: on to the next line
    const std::size_t lf = content.rfind('\n', p);
    const std::size_t from = lf == std::string::npos ? (content.rfind("\xEF\xBB\xBF", 0) == 0 ? 3 : 0) : lf + 1;
    const std::size_t text = content.find_first_not_of(" \t", from);
    if (has_lf && text < p && content[text] == '#') {
      p = content.find('\n', p);
      if (p == std::string::npos) break;
      continue;
    }
    *line = 1 + static_cast<int>(std::count(content.begin(), content.begin() + static_cast<std::ptrdiff_t>(p), '\n'));
    return "expected lines that end in LF or CRLF, found a CR without LF after the text of line " + std::to_string(*line) +
           " (lines that end in CR only, as classic Mac OS exports write them, 'CSV (Macintosh)'?): the file would read as one "
           "line; convert its line ends (e.g. tr '\\r' '\\n' < in.csv > out.csv)";
  }
  return "";
}

std::string implausibleMeasuredValue(MeasuredValue kind, double v) {
  switch (kind) {
    case MeasuredValue::kPositionMm:
      return std::abs(v) <= 1e7 ? "" : "a position within +-1e+07 mm";
    case MeasuredValue::kAngleDeg:
      return std::abs(v) <= 1e4 ? "" : "an angle within +-1e+04 deg";
    case MeasuredValue::kStd:
      if (!(v > 0)) return "a standard deviation > 0";
      return v >= 1e-6 && v <= 1e6 ? "" : "a standard deviation from 1e-06 to 1e+06";
    case MeasuredValue::kWeight:
      if (!(v > 0)) return "a weight > 0";
      return v >= 1e-12 && v <= 1e12 ? "" : "a weight from 1e-12 to 1e+12";
    case MeasuredValue::kPayloadKg:
      if (!(v >= 0)) return "a payload mass >= 0 kg";
      return v <= 1e5 ? "" : "a payload mass of at most 1e+05 kg";
    case MeasuredValue::kTemperatureC:
      return v >= -273.15 && v <= 1e4 ? "" : "a temperature from -273.15 to 1e+04 deg C";
    case MeasuredValue::kTimeS:
      return std::abs(v) <= 1e12 ? "" : "a time within +-1e+12 s";
  }
  return "";
}

std::vector<JointRange> jointRanges(const MeasurementSet& data, int dof) {
  std::vector<JointRange> out(static_cast<size_t>(std::max(dof, 0)),
                              JointRange{std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()});
  for (const Measurement& r : data.rows)
    for (int j = 0; j < dof; ++j) {
      JointRange& c = out[static_cast<size_t>(j)];
      c.lower = std::min(c.lower, r.q[j]);
      c.upper = std::max(c.upper, r.q[j]);
    }
  return out;
}

std::vector<double> jointValues(const MeasurementSet& data, int joint) {
  std::vector<double> out;
  out.reserve(data.rows.size());
  for (const Measurement& r : data.rows) out.push_back(r.q[joint]);
  return out;
}

double statedPositionNoiseRms(const std::vector<const MeasurementSet*>& sets) {
  double s2 = 0;
  int n = 0;
  for (const MeasurementSet* set : sets) {
    if (!set || !set->has_std_position) continue;
    for (const Measurement& r : set->rows)
      if (r.std_mm.allFinite()) {
        s2 += r.std_mm.squaredNorm();
        ++n;
      }
  }
  return n > 0 ? std::sqrt(s2 / n) : std::numeric_limits<double>::quiet_NaN();
}

MeasurementSet readMeasurementsCsv(const std::string& path, const RobotDefinition& robot) {
  return MeasurementReader(path, robot).read();
}

void writeMeasurementsCsv(const std::string& path, const MeasurementSet& set, int dof,
                          const std::vector<std::string>& comments) {
  writeFileAtomically(path, measurementsCsvText(set, dof, comments));
}

std::string measurementsCsvText(const MeasurementSet& set, int dof, const std::vector<std::string>& comments) {
  if (dof < 1) throw ArgumentError("writeMeasurementsCsv: expected dof >= 1, got " +
                                   std::to_string(dof));
  if (set.rows.empty()) {
    throw ArgumentError("writeMeasurementsCsv: expected at least one measurement, got none");
  }
  const auto n = static_cast<std::size_t>(dof);

  // Check everything before writing anything: the file must read back.
  for (std::size_t r = 0; r < set.rows.size(); ++r) {
    const Measurement& m = set.rows[r];
    if (m.q.size() != dof) {
      throw ArgumentError("writeMeasurementsCsv: row " + std::to_string(r + 1) + ": expected " +
                          std::to_string(dof) + " joint values, got " +
                          std::to_string(m.q.size()));
    }
    for (int i = 0; i < dof; ++i) requireFinite(m.q[i], r, "a joint value");
    for (int i = 0; i < 3; ++i) requireFinite(m.p_world_mm[i], r, "the position");
    if (set.has_orientation) {
      for (int i = 0; i < 4; ++i) requireFinite(m.R_world_tcp.coeffs()[i], r, "the quaternion");
      if (!(m.R_world_tcp.norm() > 0.5)) {
        throw ArgumentError("writeMeasurementsCsv: row " + std::to_string(r + 1) +
                            ": expected a unit quaternion, got norm " +
                            std::to_string(m.R_world_tcp.norm()));
      }
    }
    if (set.has_std_position) {
      for (int i = 0; i < 3; ++i) requirePositive(m.std_mm[i], r, "std_mm");
    }
    if (set.has_std_orientation) {
      for (int i = 0; i < 3; ++i) requirePositive(m.std_rot_deg[i], r, "std_rot_deg");
    }
    if (set.has_weight) requirePositive(m.weight, r, "the weight");
    if (set.has_payload) {
      requireFinite(m.context.payload_kg, r, "payload_kg");
      if (m.context.payload_kg < -0.5e-6) {
        throw ArgumentError("writeMeasurementsCsv: row " + std::to_string(r + 1) +
                            ": expected payload_kg >= 0, got " +
                            std::to_string(m.context.payload_kg));
      }
    }
    if (set.has_temperature) requireFinite(m.temp_c, r, "temp_c");
    if (set.has_time) requireFinite(m.time_s, r, "time_s");
    if (set.has_direction) {
      if (m.dir.size() != n) {
        throw ArgumentError("writeMeasurementsCsv: row " + std::to_string(r + 1) +
                            ": expected " + std::to_string(dof) + " directions, got " +
                            std::to_string(m.dir.size()));
      }
      for (int d : m.dir) {
        if (d != 1 && d != -1) {
          throw ArgumentError("writeMeasurementsCsv: row " + std::to_string(r + 1) +
                              ": expected directions +1 or -1, got " + std::to_string(d));
        }
      }
    }
  }

  std::string out;
  for (const std::string& comment : comments) {
    std::size_t start = 0;
    for (;;) {  // one "# " line per line of the comment
      const std::size_t nl = comment.find('\n', start);
      std::string piece = comment.substr(start, nl == std::string::npos ? nl : nl - start);
      if (!piece.empty() && piece.back() == '\r') piece.pop_back();
      out += piece.empty() ? "#" : "# " + piece;
      out += '\n';
      if (nl == std::string::npos) break;
      start = nl + 1;
    }
  }

  std::vector<std::string> header;
  for (int i = 1; i <= dof; ++i) header.push_back("q" + std::to_string(i));
  for (const char* s : {"x", "y", "z"}) header.emplace_back(s);
  if (set.has_orientation) for (const char* s : {"qw", "qx", "qy", "qz"}) header.emplace_back(s);
  if (set.has_std_position) for (const char* s : {"std_x", "std_y", "std_z"}) header.emplace_back(s);
  if (set.has_std_orientation) {
    for (const char* s : {"std_rx", "std_ry", "std_rz"}) header.emplace_back(s);
  }
  if (set.has_weight) header.emplace_back("weight");
  if (set.has_payload) header.emplace_back("payload_kg");
  if (set.has_temperature) header.emplace_back("temp_c");
  if (set.has_direction) {
    for (int i = 1; i <= dof; ++i) header.push_back("dir" + std::to_string(i));
  }
  if (set.has_time) header.emplace_back("time_s");
  for (std::size_t i = 0; i < header.size(); ++i) {
    if (i > 0) out += ',';
    out += header[i];
  }
  out += '\n';

  for (const Measurement& m : set.rows) {
    bool first = true;
    const auto field = [&out, &first](double v, int decimals) {
      if (!first) out += ',';
      first = false;
      appendFixed(out, v, decimals);
    };
    for (int i = 0; i < dof; ++i) field(m.q[i], 6);
    for (int i = 0; i < 3; ++i) field(m.p_world_mm[i], 6);
    if (set.has_orientation) {
      const Eigen::Quaterniond q = m.R_world_tcp.normalized();
      field(q.w(), 9);
      field(q.x(), 9);
      field(q.y(), 9);
      field(q.z(), 9);
    }
    if (set.has_std_position) for (int i = 0; i < 3; ++i) field(m.std_mm[i], 6);
    if (set.has_std_orientation) for (int i = 0; i < 3; ++i) field(m.std_rot_deg[i], 6);
    if (set.has_weight) field(m.weight, 6);
    if (set.has_payload) field(m.context.payload_kg, 6);
    if (set.has_temperature) field(m.temp_c, 6);
    if (set.has_direction) {
      for (int d : m.dir) out += d > 0 ? ",1" : ",-1";
    }
    if (set.has_time) field(m.time_s, 6);
    out += '\n';
  }
  return out;
}

// Repeated joint configurations: every joint within `tol` (deg or mm, the file's units),
// the same payload and directions. Sweep over the rows sorted by q1, union-find over the pairs.
std::vector<std::vector<int>> repeatedConfigurations(const MeasurementSet& set, double tol, std::vector<std::pair<int, int>>* pairs,
                                                     const std::vector<int>* set_of_row) {
  const int m = static_cast<int>(set.rows.size());
  std::vector<int> order(static_cast<size_t>(m));
  std::iota(order.begin(), order.end(), 0);
  if (m == 0) return {};
  std::sort(order.begin(), order.end(), [&](int a, int b) { return set.rows[a].q[0] < set.rows[b].q[0]; });
  std::vector<int> parent(static_cast<size_t>(m));
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  if (pairs) pairs->clear();
  for (int a = 0; a < m; ++a) {
    const Measurement& A = set.rows[order[a]];
    for (int b = a + 1; b < m; ++b) {
      const Measurement& B = set.rows[order[b]];
      if (B.q[0] - A.q[0] > tol) break;
      bool same = std::abs(A.context.payload_kg - B.context.payload_kg) <= 1e-9 && A.dir == B.dir &&
                  (!set_of_row || (*set_of_row)[static_cast<size_t>(order[a])] == (*set_of_row)[static_cast<size_t>(order[b])]);
      for (Eigen::Index k = 1; same && k < A.q.size(); ++k) same = std::abs(A.q[k] - B.q[k]) <= tol;
      if (!same) continue;
      const int i = std::min(order[a], order[b]), k = std::max(order[a], order[b]);
      if (pairs) pairs->push_back({i, k});
      parent[find(i)] = find(k);
    }
  }
  std::map<int, std::vector<int>> by_root;
  for (int i = 0; i < m; ++i) by_root[find(i)].push_back(i);
  std::vector<std::vector<int>> groups;
  for (auto& kv : by_root) groups.push_back(kv.second);  // rows ascending within a group
  std::sort(groups.begin(), groups.end(), [](const auto& a, const auto& b) { return a.front() < b.front(); });
  if (pairs) std::sort(pairs->begin(), pairs->end());
  return groups;
}

std::vector<DuplicatedRow> duplicatedRows(const MeasurementSet& set, double tol) {
  std::vector<DuplicatedRow> out;
  const std::vector<Measurement>& rows = set.rows;
  auto same = [&](int a, int b) {
    const Measurement& A = rows[static_cast<size_t>(a)];
    const Measurement& B = rows[static_cast<size_t>(b)];
    if (A.p_world_mm != B.p_world_mm || A.has_orientation != B.has_orientation) return false;
    return !A.has_orientation || A.R_world_tcp.coeffs() == B.R_world_tcp.coeffs();
  };
  for (const std::vector<int>& g : repeatedConfigurations(set, tol)) {
    if (g.size() < 2) continue;
    std::vector<int> kept;  // the first row of each distinct measurement of the configuration
    for (int i : g) {
      const auto first = std::find_if(kept.begin(), kept.end(), [&](int k) { return same(i, k); });
      if (first == kept.end()) {
        kept.push_back(i);
        continue;
      }
      out.push_back({i, rows[static_cast<size_t>(i)].line, *first, rows[static_cast<size_t>(*first)].line});
    }
  }
  std::sort(out.begin(), out.end(), [](const DuplicatedRow& a, const DuplicatedRow& b) { return a.index < b.index; });
  return out;
}

std::vector<DuplicatedRow> removeDuplicatedRows(MeasurementSet& set, double tol) {
  const std::vector<DuplicatedRow> dups = duplicatedRows(set, tol);
  if (dups.empty()) return dups;
  std::vector<bool> drop(set.rows.size(), false);
  for (const DuplicatedRow& d : dups) drop[static_cast<size_t>(d.index)] = true;
  std::vector<Measurement> kept;
  kept.reserve(set.rows.size() - dups.size());
  for (size_t i = 0; i < set.rows.size(); ++i)
    if (!drop[i]) kept.push_back(std::move(set.rows[i]));
  set.rows = std::move(kept);
  return dups;
}

namespace {

/// The first ten of `rows` as FILE:LINE = SAME (SAME: FILE:LINE, or LINE alone when `same_file_short`),
/// then how many more.
std::string rowPairList(const std::string& file, const std::vector<DuplicatedRow>& rows, bool same_file_short) {
  std::string list;
  for (size_t k = 0; k < rows.size() && k < 10; ++k)
    list += (k ? ", " : "") + file + ":" + std::to_string(rows[k].line) + " = " + (same_file_short ? "" : file + ":") +
            std::to_string(rows[k].same_as_line);
  if (rows.size() > 10) list += ", ... (" + std::to_string(rows.size() - 10) + " more)";
  return list;
}

}  // namespace

std::string duplicatedRowsWarning(const std::string& file, const std::vector<DuplicatedRow>& rows) {
  if (rows.empty()) return "";
  const std::string list = rowPairList(file, rows, false);
  return std::to_string(rows.size()) + " row(s) of " + file +
         " repeat an earlier row of their joint configuration exactly (every measured value equal: " + list +
         "): the same measurement written twice, not a second measurement; each is counted once";
}

std::vector<DuplicatedRow> staleReadings(const MeasurementSet& set, double tol) {
  std::vector<DuplicatedRow> out;
  for (size_t i = 1; i < set.rows.size(); ++i) {
    const Measurement& a = set.rows[i - 1];
    const Measurement& b = set.rows[i];
    if (a.p_world_mm != b.p_world_mm) continue;
    if (a.has_orientation && b.has_orientation && a.R_world_tcp.coeffs() != b.R_world_tcp.coeffs()) continue;
    bool moved = a.q.size() != b.q.size() || a.context.payload_kg != b.context.payload_kg;
    for (Eigen::Index j = 0; !moved && j < a.q.size(); ++j) moved = std::abs(a.q[j] - b.q[j]) > tol;
    if (moved) out.push_back({static_cast<int>(i), b.line, static_cast<int>(i - 1), a.line});
  }
  return out;
}

std::string staleReadingsWarning(const std::string& file, const std::vector<DuplicatedRow>& rows) {
  if (rows.empty()) return "";
  const std::string list = rowPairList(file, rows, true);
  return std::to_string(rows.size()) + " row(s) of " + file +
         " carry the measured values of the row before them to the last digit at another joint configuration (" + list +
         "): most likely that row's reading written again (an instrument that did not update), not a measurement of "
         "their own pose; they are kept: check them, and delete the rows if so";
}

namespace {

/// A row's joint values and measured values, bit for bit (refuseSharedMeasurements,
/// refuseValidationInFitData).
std::string measurementKey(const Measurement& r) {
  std::string k;
  auto put = [&](double v) { k.append(reinterpret_cast<const char*>(&v), sizeof v); };
  for (Eigen::Index j = 0; j < r.q.size(); ++j) put(r.q[j]);
  for (int a = 0; a < 3; ++a) put(r.p_world_mm[a]);
  k.push_back(r.has_orientation ? 'R' : 'P');
  if (r.has_orientation)
    for (int a = 0; a < 4; ++a) put(r.R_world_tcp.coeffs()[a]);
  return k;
}

}  // namespace

void refuseValidationInFitData(const std::vector<MeasurementSet>& fit, const MeasurementSet& validation) {
  std::unordered_map<std::string, std::pair<size_t, size_t>> in_fit;  // key -> (set, row)
  for (size_t s = 0; s < fit.size(); ++s)
    for (size_t i = 0; i < fit[s].rows.size(); ++i) in_fit.emplace(measurementKey(fit[s].rows[i]), std::make_pair(s, i));
  size_t shared = 0;
  const Measurement* first = nullptr;
  std::pair<size_t, size_t> first_fit{0, 0};
  for (const Measurement& r : validation.rows) {
    const auto it = in_fit.find(measurementKey(r));
    if (it == in_fit.end()) continue;
    if (shared++ == 0) {
      first = &r;
      first_fit = it->second;
    }
  }
  if (shared == 0) return;
  const MeasurementSet& f = fit[first_fit.first];
  throw InputError(validation.file, first->line, 0,
                   "expected held-out measurements, not in the fit data, found " +
                       (shared == validation.rows.size() ? "every one of its " + std::to_string(shared) + " rows"
                                                         : std::to_string(shared) + " of its " + std::to_string(validation.rows.size()) + " rows") +
                       " identical to rows of the fit data (joint values and measured values equal to the last bit; the first: " +
                       validation.file + ":" + std::to_string(first->line) + " = " + f.file + ":" +
                       std::to_string(f.rows[first_fit.second].line) +
                       "): a validation on measurements the fit has seen measures the fit, not the accuracy on new poses; "
                       "validate on measurements kept apart from the fit data (or use --holdout)");
}

std::string validationLooksLikeFitDataWarning(const std::vector<MeasurementSet>& fit, const MeasurementSet& validation) {
  if (validation.rows.empty()) return "";
  // the fit rows ordered by their first joint; a validation row is compared with those within
  // the joint tolerance of it there
  struct FitRow {
    double q1;
    const Measurement* row;
    const std::string* file;
  };
  std::vector<FitRow> by_q1;
  for (const MeasurementSet& f : fit)
    for (const Measurement& r : f.rows)
      if (r.q.size() > 0) by_q1.push_back({r.q[0], &r, &f.file});
  std::sort(by_q1.begin(), by_q1.end(), [](const FitRow& a, const FitRow& b) { return a.q1 < b.q1; });
  size_t same = 0;
  const Measurement* first_val = nullptr;
  const FitRow* first_fit = nullptr;
  double worst_q = 0, worst_p_mm = 0;
  for (const Measurement& v : validation.rows) {
    if (v.q.size() == 0) continue;
    auto it = std::lower_bound(by_q1.begin(), by_q1.end(), v.q[0] - kReexportJointTol,
                               [](const FitRow& a, double x) { return a.q1 < x; });
    for (; it != by_q1.end() && it->q1 <= v.q[0] + kReexportJointTol; ++it) {
      const Measurement& f = *it->row;
      if (f.q.size() != v.q.size() || f.context.payload_kg != v.context.payload_kg) continue;
      const double dq = (f.q - v.q).cwiseAbs().maxCoeff();
      const double dp = (f.p_world_mm - v.p_world_mm).cwiseAbs().maxCoeff();
      if (!(dq <= kReexportJointTol && dp <= kReexportPositionTolMm)) continue;
      if (same++ == 0) {
        first_val = &v;
        first_fit = &*it;
      }
      worst_q = std::max(worst_q, dq);
      worst_p_mm = std::max(worst_p_mm, dp);
      break;
    }
  }
  if (same == 0 || 2 * same < validation.rows.size()) return "";
  return std::to_string(same) + " of the " + std::to_string(validation.rows.size()) + " rows of " + validation.file +
         " are rows of the fit data to within " + formatNumber("%g", kReexportJointTol) + " deg in every joint and " +
         formatNumber("%g", kReexportPositionTolMm) + " mm in every position component (the first: " + validation.file + ":" +
         std::to_string(first_val->line) + " = " + *first_fit->file + ":" + std::to_string(first_fit->row->line) + "; at most " +
         formatNumber("%.2g", worst_q) + " deg and " + formatNumber("%.2g", worst_p_mm) +
         " mm apart): most likely the fit's measurements exported again (other units or precision), and a validation on "
         "them measures the fit, not the accuracy on new poses; validate on measurements kept apart from the fit data";
}

void refuseSharedMeasurements(const std::vector<MeasurementSet>& sets) {
  if (sets.size() < 2) return;
  std::unordered_map<std::string, std::pair<size_t, size_t>> seen;  // key -> (set, row) of its first occurrence
  for (size_t s = 0; s < sets.size(); ++s) {
    const std::vector<Measurement>& rows = sets[s].rows;
    std::vector<std::string> keys(rows.size());
    size_t shared = 0, first_row = 0, first_other_set = 0, first_other_row = 0;
    for (size_t i = 0; i < rows.size(); ++i) {
      keys[i] = measurementKey(rows[i]);
      const auto it = seen.find(keys[i]);
      if (it == seen.end() || it->second.first == s) continue;
      if (shared++ == 0) {
        first_row = i;
        first_other_set = it->second.first;
        first_other_row = it->second.second;
      }
    }
    if (shared > 0) {
      const MeasurementSet& other = sets[first_other_set];
      size_t with_other = 0;  // of the shared rows, those of that earlier set
      for (size_t i = 0; i < rows.size(); ++i) {
        const auto it = seen.find(keys[i]);
        with_other += it != seen.end() && it->second.first == first_other_set ? 1 : 0;
      }
      throw InputError(sets[s].file, rows[first_row].line, 0,
                       "expected measurements of its own, found " +
                           (with_other == rows.size() ? "every one of its " + std::to_string(rows.size()) + " rows"
                                                      : std::to_string(with_other) + " of its " + std::to_string(rows.size()) + " rows") +
                           " identical to rows of " + other.file + " (joint values and measured values equal to the last bit; the first: " +
                           sets[s].file + ":" + std::to_string(rows[first_row].line) + " = " + other.file + ":" +
                           std::to_string(other.rows[first_other_row].line) +
                           "): the same measurements given twice would count twice, as if measured twice (the parameters' sigmas "
                           "too small, every test too significant); give each measurement once");
    }
    for (size_t i = 0; i < rows.size(); ++i) seen.emplace(keys[i], std::make_pair(s, i));
  }
}

std::vector<HeldJoint> heldJoints(const MeasurementSet& data, const RobotDefinition& robot, double tol) {
  std::vector<HeldJoint> out;
  if (data.rows.empty()) return out;
  const std::vector<JointRange> ranges = jointRanges(data, robot.dof());
  for (int j = 0; j < robot.dof(); ++j) {
    const JointRange& r = ranges[static_cast<size_t>(j)];
    if (!(r.upper - r.lower <= tol)) continue;
    double sum = 0;
    for (const Measurement& m : data.rows) sum += m.q[j];
    out.push_back({j, sum / double(data.rows.size())});
  }
  return out;
}

std::string heldJointWarning(const RobotDefinition& robot, const HeldJoint& held, size_t rows, double tol,
                             const std::string& fixed) {
  const std::string n = std::to_string(held.joint + 1);
  const char* unit = robot.joints[static_cast<size_t>(held.joint)].type == JointType::kRevolute ? "deg" : "mm";
  const double value = std::abs(held.value) < 0.5 * tol ? 0.0 : held.value;  // (no "-0")
  return "joint " + n + " never moves in the data (held at " + formatNumber("%.6g", value) + " " + unit + " in all " +
         std::to_string(rows) + " rows, within " + formatNumber("%g", tol) + " " + unit +
         "): the model holds only at that angle. What needs joint " + n + "'s motion to be determined is fixed or absorbed by " +
         "other parameters" +
         (fixed.empty() ? std::string()
                        : " (this fit fixed, of " +
                              (held.joint + 1 < robot.dof() ? "links " + n + " and " + std::to_string(held.joint + 2) : "link " + n) +
                              ": " + fixed + ")") +
         ", and the data say nothing of the robot at other angles of joint " + n +
         ": measure poses with joint " + n + " moving over its range";
}

}  // namespace accura::calib
