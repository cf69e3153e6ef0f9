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

namespace accura::calib {
namespace {

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t\r") - b + 1);
}

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

std::vector<std::string> readLines(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw InputError(path, 0, 0, "cannot open file");
  std::vector<std::string> lines;
  std::string line;
  while (std::getline(f, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    lines.push_back(line);
  }
  if (f.bad()) throw InputError(path, 0, 0, "read error");
  if (!lines.empty() && lines[0].rfind("\xEF\xBB\xBF", 0) == 0) lines[0].erase(0, 3);
  return lines;
}

// Parses a number written with `decimal` as the decimal separator; no thousands separators.
bool parseNumber(std::string text, char decimal, double* value) {
  text = trim(text);
  if (text.empty()) return false;
  if (decimal == ',') {
    if (text.find('.') != std::string::npos) return false;  // '.' is not the decimal mark here
    std::replace(text.begin(), text.end(), ',', '.');
  }
  const char* b = text.c_str();
  if (*b == '+') ++b;
  const char* e = text.c_str() + text.size();
  const auto r = std::from_chars(b, e, *value);
  return r.ec == std::errc() && r.ptr == e && std::isfinite(*value);
}

const std::set<std::string> kKeys = {
    "delimiter", "decimal", "joints", "joint_unit", "prismatic_unit", "position", "position_unit",
    "orientation", "orientation_unit", "position_std", "orientation_std", "weight", "payload_kg",
    "temperature_c", "time_s", "directions", "ignore"};

}  // namespace

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
  for (size_t i = 0; i < lines.size(); ++i) {
    const int ln = static_cast<int>(i) + 1;
    const std::string t = trim(lines[i]);
    if (t.empty() || t[0] == '#') continue;
    const size_t eq = lines[i].find('=');
    if (eq == std::string::npos)
      throw InputError(path, ln, 1, "expected 'key = value', found '" + t + "'");
    const std::string key = lower(trim(lines[i].substr(0, eq)));
    std::string value = lines[i].substr(eq + 1);
    // trailing comment: ' #' outside the value (a '#' right after '=' may be a delimiter)
    const size_t hash = value.find(" #");
    if (hash != std::string::npos) value = value.substr(0, hash);
    value = trim(value);
    const int col = static_cast<int>(lines[i].find_first_not_of(" \t")) + 1;
    if (!kKeys.count(key)) {
      std::string list;
      for (const auto& k : kKeys) list += (list.empty() ? "" : ", ") + k;
      throw InputError(path, ln, col, "unknown key '" + key + "' (expected one of: " + list + ")");
    }
    if (kv.count(key))
      throw InputError(path, ln, col, "key '" + key + "' given twice (first on line " +
                                          std::to_string(kv[key].second) + ")");
    kv[key] = {value, ln};
    const size_t vstart = lines[i].find_first_not_of(" \t", eq + 1);
    value_col[key] = static_cast<int>(vstart == std::string::npos ? eq + 1 : vstart) + 1;
    m.key_lines.push_back({key, ln});
  }
  auto fail = [&](const std::string& key, const std::string& msg) -> InputError {
    auto it = kv.find(key);
    if (it == kv.end()) return InputError(path, 0, 0, msg);
    return InputError(path, it->second.second, value_col[key], msg);
  };
  auto require = [&](const std::string& key) -> std::string {
    auto it = kv.find(key);
    if (it == kv.end()) throw InputError(path, 0, 0, "missing key '" + key + "'");
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
      const std::string name = trim(c);
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
    throw fail("decimal", "key 'decimal': the decimal mark cannot be the delimiter");

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
    m.orientation_convention = lower(trim(ori.substr(0, colon)));
    m.orientation = columns("orientation", ori.substr(colon + 1));
    const std::string& conv = m.orientation_convention;
    if (conv == "quaternion_wxyz" || conv == "quaternion_xyzw") {
      expectCount("orientation", m.orientation, {4});
    } else {
      try {
        rotationFromAngles(conv, Eigen::Vector3d::Zero());
      } catch (const ArgumentError&) {
        throw fail("orientation", "key 'orientation': expected a convention quaternion_wxyz, quaternion_xyzw, "
                                  "kuka_abc, euler_intrinsic_<axes> or euler_extrinsic_<axes> (axes e.g. xyz, zyx, "
                                  "zyz), found '" + conv + "'");
      }
      expectCount("orientation", m.orientation, {3});
      const std::string ou = lower(require("orientation_unit"));
      if (ou == "deg") m.angle_scale = 1.0;
      else if (ou == "rad") m.angle_scale = kRadToDeg;
      else throw fail("orientation_unit", "key 'orientation_unit': expected 'deg' or 'rad', found '" + ou + "'");
    }
  } else if (kv.count("orientation_unit") || kv.count("orientation_std")) {
    throw fail(kv.count("orientation_std") ? "orientation_std" : "orientation_unit",
               "orientation units or stds given, but no 'orientation' key");
  }
  m.position_std = columns("position_std", optional("position_std"));
  if (!m.position_std.empty()) expectCount("position_std", m.position_std, {1, 3});
  m.orientation_std = columns("orientation_std", optional("orientation_std"));
  if (!m.orientation_std.empty()) {
    expectCount("orientation_std", m.orientation_std, {1, 3});
    if (m.orientation.size() == 4)
      throw fail("orientation_std", "key 'orientation_std': stds of quaternion components are not supported; "
                                    "give the orientation as angles or leave the stds out");
  }
  m.weight = optional("weight");
  m.payload_kg = optional("payload_kg");
  m.temperature_c = optional("temperature_c");
  m.time_s = optional("time_s");
  m.directions = columns("directions", optional("directions"));
  if (!m.directions.empty()) expectCount("directions", m.directions, {static_cast<size_t>(robot.dof())});
  m.ignore = columns("ignore", optional("ignore"));
  return m;
}

MeasurementSet readMappedMeasurements(const std::string& path, const MeasurementMapping& m,
                                      const RobotDefinition& robot) {
  const std::vector<std::string> lines = readLines(path);
  size_t hi = 0;
  while (hi < lines.size() && (trim(lines[hi]).empty() || trim(lines[hi])[0] == '#')) ++hi;
  if (hi == lines.size()) throw InputError(path, 0, 0, "expected a header row, found an empty file");
  const int header_line = static_cast<int>(hi) + 1;
  std::vector<std::string> header = splitOn(lines[hi], m.delimiter);
  std::map<std::string, int> index;  // lower-cased name -> field index
  for (size_t c = 0; c < header.size(); ++c) {
    header[c] = trim(header[c]);
    const std::string key = lower(header[c]);
    if (index.count(key))
      throw InputError(path, header_line, static_cast<int>(c) + 1,
                       "column '" + header[c] + "' appears twice (first as column " +
                           std::to_string(index[key] + 1) + ")");
    index[key] = static_cast<int>(c);
  }
  std::set<int> used;
  auto col = [&](const std::string& name, const std::string& role) {
    auto it = index.find(lower(name));
    if (it == index.end()) {
      int ml = 0;
      for (const auto& kl : m.key_lines)
        if (kl.first == role) ml = kl.second;
      throw InputError(path, header_line, 0,
                       "missing column '" + name + "' (mapped as " + role + " in " + m.file +
                           (ml ? ":" + std::to_string(ml) : std::string()) + "; the delimiter is '" +
                           (m.delimiter == '\t' ? std::string("tab") : std::string(1, m.delimiter)) + "')");
    }
    used.insert(it->second);
    return it->second;
  };
  auto cols = [&](const std::vector<std::string>& names, const std::string& role) {
    std::vector<int> out;
    for (const auto& n : names) out.push_back(col(n, role));
    return out;
  };
  const std::vector<int> jc = cols(m.joints, "joints");
  const std::vector<int> pc = cols(m.position, "position");
  const std::vector<int> oc = cols(m.orientation, "orientation");
  const std::vector<int> psc = cols(m.position_std, "position_std");
  const std::vector<int> osc = cols(m.orientation_std, "orientation_std");
  const std::vector<int> dc = cols(m.directions, "directions");
  const int wc = m.weight.empty() ? -1 : col(m.weight, "weight");
  const int plc = m.payload_kg.empty() ? -1 : col(m.payload_kg, "payload_kg");
  const int tc = m.temperature_c.empty() ? -1 : col(m.temperature_c, "temperature_c");
  const int timec = m.time_s.empty() ? -1 : col(m.time_s, "time_s");
  for (const auto& n : m.ignore) {
    auto it = index.find(lower(n));
    if (it == index.end())
      throw InputError(path, header_line, 0, "missing column '" + n + "' (listed under 'ignore' in " + m.file + ")");
    used.insert(it->second);
  }

  MeasurementSet set;
  set.file = path;
  set.has_orientation = !oc.empty();
  set.has_std_position = !psc.empty();
  set.has_std_orientation = !osc.empty();
  set.has_weight = wc >= 0;
  set.has_payload = plc >= 0;
  set.has_temperature = tc >= 0;
  set.has_time = timec >= 0;
  set.has_direction = !dc.empty();
  for (size_t c = 0; c < header.size(); ++c)
    if (!used.count(static_cast<int>(c))) set.unknown_columns.push_back(header[c]);

  const int n = robot.dof();
  for (size_t li = hi + 1; li < lines.size(); ++li) {
    const int ln = static_cast<int>(li) + 1;
    const std::string t = trim(lines[li]);
    if (t.empty() || t[0] == '#') continue;
    const std::vector<std::string> f = splitOn(lines[li], m.delimiter);
    if (f.size() != header.size())
      throw InputError(path, ln, 0, "expected " + std::to_string(header.size()) + " fields as in the header, found " +
                                        std::to_string(f.size()));
    auto num = [&](int c) {
      double v;
      if (!parseNumber(f[c], m.decimal, &v)) {
        const std::string shown = trim(f[c]).empty() ? "an empty field" : "'" + trim(f[c]) + "'";
        throw InputError(path, ln, c + 1, "column '" + header[c] + "': expected a number with '" +
                                              std::string(1, m.decimal) + "' as decimal mark, found " + shown);
      }
      return v;
    };
    Measurement r;
    r.line = ln;
    r.q.resize(n);
    for (int j = 0; j < n; ++j) {
      const JointSpec& js = robot.joints[j];
      const double v = num(jc[j]) * (js.type == JointType::kRevolute ? m.joint_scale : m.prismatic_scale);
      if (v < js.lower || v > js.upper) {
        const char* unit = js.type == JointType::kRevolute ? "deg" : "mm";
        char buf[160];
        std::snprintf(buf, sizeof buf, "joint value %.6g %s is outside the joint limits [%g, %g] %s", v, unit, js.lower,
                      js.upper, unit);
        throw InputError(path, ln, jc[j] + 1, "column '" + header[jc[j]] + "': " + buf);
      }
      r.q[j] = v;
    }
    for (int k = 0; k < 3; ++k) r.p_world_mm[k] = num(pc[k]) * m.position_scale;
    Eigen::Vector3d angles_rad = Eigen::Vector3d::Zero();
    if (set.has_orientation) {
      r.has_orientation = true;
      if (oc.size() == 4) {
        double w, x, y, z;
        if (m.orientation_convention == "quaternion_wxyz") {
          w = num(oc[0]); x = num(oc[1]); y = num(oc[2]); z = num(oc[3]);
        } else {
          x = num(oc[0]); y = num(oc[1]); z = num(oc[2]); w = num(oc[3]);
        }
        const double norm = std::sqrt(w * w + x * x + y * y + z * z);
        if (std::abs(norm - 1.0) > 1e-3)
          throw InputError(path, ln, oc[0] + 1, "expected a unit quaternion (norm 1 within 1e-3), found norm " + std::to_string(norm));
        r.R_world_tcp = Eigen::Quaterniond(w / norm, x / norm, y / norm, z / norm);
      } else {
        for (int k = 0; k < 3; ++k) angles_rad[k] = num(oc[k]) * m.angle_scale * kDegToRad;
        r.R_world_tcp = Eigen::Quaterniond(rotationFromAngles(m.orientation_convention, angles_rad));
      }
    }
    auto positive = [&](int c, double scale) {
      const double v = num(c) * scale;
      if (!(v > 0)) throw InputError(path, ln, c + 1, "column '" + header[c] + "': expected a standard deviation > 0, found " + trim(f[c]));
      return v;
    };
    if (!psc.empty()) {
      for (int k = 0; k < 3; ++k) r.std_mm[k] = positive(psc[psc.size() == 1 ? 0 : k], m.position_scale);
    }
    if (!osc.empty()) {
      Eigen::Vector3d s_angle;
      for (int k = 0; k < 3; ++k) s_angle[k] = positive(osc[osc.size() == 1 ? 0 : k], m.angle_scale) * kDegToRad;
      // Euler-angle stds -> stds of the rotation about the world axes: Sigma_w = J S J^T with
      // J the derivative of the world rotation vector with respect to the angles (central
      // differences, step 1e-6 rad; the angles' own stds are ~1e-5 rad, linearisation exact enough).
      Eigen::Matrix3d J;
      for (int k = 0; k < 3; ++k) {
        const double h = 1e-6;
        Eigen::Vector3d ap = angles_rad, am = angles_rad;
        ap[k] += h;
        am[k] -= h;
        J.col(k) = logSO3(rotationFromAngles(m.orientation_convention, ap) *
                          rotationFromAngles(m.orientation_convention, am).transpose()) / (2 * h);
      }
      const Eigen::Matrix3d S = J * s_angle.cwiseAbs2().asDiagonal() * J.transpose();
      for (int k = 0; k < 3; ++k) r.std_rot_deg[k] = std::sqrt(S(k, k)) * kRadToDeg;
    }
    if (wc >= 0) r.weight = positive(wc, 1.0);
    if (plc >= 0) {
      r.context.payload_kg = num(plc);
      if (r.context.payload_kg < 0)
        throw InputError(path, ln, plc + 1, "column '" + header[plc] + "': expected a mass >= 0 kg, found " + trim(f[plc]));
    }
    if (tc >= 0) r.temp_c = num(tc);
    if (timec >= 0) r.time_s = num(timec);
    for (int c : dc) {
      const double d = num(c);
      if (d != 1.0 && d != -1.0)
        throw InputError(path, ln, c + 1, "column '" + header[c] + "': expected +1 or -1, found " + trim(f[c]));
      r.dir.push_back(static_cast<int>(d));
    }
    // the model's context (kinematics.h): temperature and approach directions, when given
    if (tc >= 0) r.context.temp_c = r.temp_c;
    r.context.dir = r.dir;
    set.rows.push_back(r);
  }
  if (set.rows.empty()) throw InputError(path, 0, 0, "expected at least one data row, found none");
  return set;
}

}  // namespace accura::calib
