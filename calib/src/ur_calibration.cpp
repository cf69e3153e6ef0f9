// accura: Universal Robots' factory calibration (calibration.conf DH deltas, ur_calibration's
// YAML) <-> calibrated accura models. See ur_calibration.h.
#include "accura/calib/ur_calibration.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>
#include <utility>

#include "accura/calib/errors.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/text.h"
#include "urdf_common.h"

namespace accura::calib {
namespace {

constexpr auto num17 = urdf_detail::shortestNumber;

/// 1-based column of the first character of `raw` from `from` on that is not blank (one past
/// the end when there is none).
int columnOfText(const std::string& raw, size_t from = 0) {
  const size_t a = raw.find_first_not_of(" \t\r", from);
  return static_cast<int>((a == std::string::npos ? raw.size() : a) + 1);
}

double parseNumber(const std::string& file, int line, int column, const std::string& text, const std::string& what) {
  const std::string t = trimBlanks(text);
  char* end = nullptr;
  const double v = std::strtod(t.c_str(), &end);
  if (t.empty() || *end != '\0' || !std::isfinite(v))
    throw InputError(file, line, column, what + ": expected a finite number, found '" + t + "'");
  return v;
}

/// Where a missing entry was expected: at the end of the file (line 1, column 1 when empty).
std::pair<int, int> endOfFile(const std::vector<std::string>& lines) {
  if (lines.empty()) return {1, 1};
  return {static_cast<int>(lines.size()), static_cast<int>(lines.back().size()) + 1};
}

std::vector<std::string> readLines(const std::string& path, const char* what) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, 0, 0, std::string("cannot open ") + what);
  std::vector<std::string> lines;
  for (std::string l; std::getline(in, l);) lines.push_back(l);
  // a UTF-8 byte-order mark (Windows editors write one) is not part of the text, as in the CSV,
  // mapping, URDF and robot file readers
  if (!lines.empty() && lines[0].rfind("\xEF\xBB\xBF", 0) == 0) lines[0].erase(0, 3);
  return lines;
}

// Rz(theta) Tz(d) Tx(a) Rx(alpha) in mm from rad / m.
Eigen::Isometry3d dh(double theta, double d_m, double a_m, double alpha) {
  return urdf_detail::linkFrame(theta, 1000.0 * d_m, 1000.0 * a_m, alpha, 0.0);
}

Eigen::Matrix3d rpyMatrix(double r, double p, double y) {
  return (Eigen::AngleAxisd(y, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(p, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(r, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

const char* const kYamlLinks[6] = {"shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3"};

// What a UR table cannot hold of a model: base / tool deviations and the effects.
std::vector<std::string> notInUrTable(const RobotModel& model) {
  std::vector<std::string> out;
  const Deviations& d = model.deviations;
  auto vec = [](const Eigen::Vector3d& v, double s) {
    return "(" + num17(v.x() * s) + ", " + num17(v.y() * s) + ", " + num17(v.z() * s) + ")";
  };
  if (d.base_mm.norm() > 0 || d.base_rot_rad.norm() > 0)
    out.push_back("base deviation " + vec(d.base_mm, 1) + " mm, rotation vector " + vec(d.base_rot_rad, kRadToDeg) +
                  " deg: where the arm's Base stands in the world frame the model was identified in (the measurement "
                  "frame: the laser tracker's or CMM's station), not part of the arm's calibration and not exported "
                  "(UR's table starts at the Base frame)");
  if (d.tool_mm.norm() > 0 || d.tool_rot_rad.norm() > 0)
    out.push_back("tool deviation " + vec(d.tool_mm, 1) + " mm, rotation vector " + vec(d.tool_rot_rad, kRadToDeg) +
                  " deg: not in UR's table (it ends at the flange); set it in the TCP");
  for (const std::string& e : urdf_detail::effectsLeftOut(model, "UR's table")) out.push_back(e);
  return out;
}

// The model's calibrated chain from DH frame 0 to the flange (base and tool excluded, the
// effects beyond geometry left out), as a serial chain about z axes.
SerialChain flangeChain(const RobotModel& model) {
  SerialChain c;
  c.name = model.nominal.name;
  c.source = "model '" + model.nominal.name + "'";
  c.root_link = "base";
  c.tip_link = "flange";
  Eigen::Isometry3d prev = Eigen::Isometry3d::Identity();
  for (int i = 0; i < model.dof(); ++i) {
    const JointSpec& j = model.nominal.joints[static_cast<size_t>(i)];
    ChainJoint cj;
    cj.name = j.name;
    cj.type = j.type;
    cj.T_prev_joint = prev;
    cj.axis = Eigen::Vector3d(0, 0, j.direction);
    cj.lower = j.lower;
    cj.upper = j.upper;
    c.joints.push_back(cj);
    prev = urdf_detail::calibratedLinkAtZero(model, i);
  }
  c.T_last_tip = prev;
  return c;
}

// `chain` with `before` in front of its first joint and `after` behind its tip.
SerialChain framed(SerialChain chain, const Eigen::Isometry3d& before, const Eigen::Isometry3d& after) {
  chain.joints.front().T_prev_joint = before * chain.joints.front().T_prev_joint;
  chain.T_last_tip = chain.T_last_tip * after;
  return chain;
}

// The model's calibrated flange chain in UR's frames (Base to UR's flange) of `c`.
SerialChain urFlangeChain(const RobotModel& model, const UrConvention& c) {
  return framed(flangeChain(model), c.T_frame0_urbase.inverse(), c.T_urflange_flange.inverse());
}

// What the error of a chain that is not a UR arm's says to do.
const char* const kUrChainHint =
    " (from a URDF: choose the arm's own chain with --chain ROOT:TIP, e.g. --chain base:tool0 on ur_description's URDF)";

// cos and sin of an angle in degrees, exact for multiples of 90 deg (the frame turns of the
// conventions: cos(pi) from radians is exact, sin(pi) is 1.2e-16)
std::pair<double, double> cosSinDeg(double deg) {
  const double k = std::round(deg / 90.0);
  if (deg == 90.0 * k) {
    const int q = static_cast<int>(std::fmod(std::fmod(k, 4.0) + 4.0, 4.0));
    static const double kCos[4] = {1, 0, -1, 0}, kSin[4] = {0, 1, 0, -1};
    return {kCos[q], kSin[q]};
  }
  return {std::cos(deg * kDegToRad), std::sin(deg * kDegToRad)};
}
Eigen::Matrix3d rotZDeg(double deg) {
  const auto [c, s] = cosSinDeg(deg);
  Eigen::Matrix3d R;
  R << c, -s, 0, s, c, 0, 0, 0, 1;
  return R;
}
Eigen::Matrix3d rotXDeg(double deg) {
  const auto [c, s] = cosSinDeg(deg);
  Eigen::Matrix3d R;
  R << 1, 0, 0, 0, c, -s, 0, s, c;
  return R;
}
// A half turn about x (about z with `z_axis`) when `on`, else the identity.
Eigen::Matrix3d halfTurnIf(bool on, bool z_axis = false) {
  return on ? (z_axis ? rotZDeg(180) : rotXDeg(180)) : Eigen::Matrix3d::Identity();
}

// To (-180, 180] deg.
double wrap180(double deg) {
  const double a = std::remainder(deg, 360.0);
  return a <= -180.0 ? a + 360.0 : a;
}

}  // namespace

namespace {

// urConventionOf with frame 0 turned by `base_turn_deg` more about axis 1.
UrConvention urConventionTurned(const RobotDefinition& nominal, double base_turn_deg) {
  const int n = nominal.dof();
  UrConvention c;
  RobotDefinition& ur = c.ur;
  ur = nominal;
  ur.T_world_base.setIdentity();
  ur.T_flange_tcp.setIdentity();
  c.folded_theta0_deg.assign(static_cast<size_t>(n), 0.0);
  // Link i of the robot, A(theta0 + direction q, d, a, alpha), with the factor L = Rz(phi) Rx(180)^z
  // left over from link i-1 in front: Rx(180) A(t, d, a, al) = A(-t, -d, a, al + 180) turns
  // direction -1 into +1; L A = A'(q) R with A' in UR's form (theta0 0, direction 1) and R a
  // factor for link i+1: A(t, d, a, al) = A(t - 180, d, -a, -al) Rz(180) = A(t, d, a, al - 180) Rx(180).
  // The last frame, when a_n = 0, takes its theta0 and alpha (a turn about axis n, then about
  // x). UR's Base is the robot's DH frame 0 (its x
  // from the root's: ur_description's base or base_link) turned by `base_turn_deg`: link 1's
  // theta0 within kMaxUrFactoryCorrectionDeg of 0 or 180 deg is a delta_theta (a calibrated
  // description's), one further from them turns frame 0 (a root that is not the arm's base).
  bool flip = nominal.joints[0].direction == -1;  // z of L
  const double theta1 = wrap180((flip ? -1.0 : 1.0) * nominal.joints[0].theta0_deg + base_turn_deg);
  const double rest1 = theta1 - 180.0 * std::round(theta1 / 180.0);
  double phi = base_turn_deg - (std::abs(rest1) > kMaxUrFactoryCorrectionDeg ? rest1 : 0.0);  // phi of L
  Eigen::Matrix3d L = rotZDeg(phi) * halfTurnIf(flip);
  c.T_frame0_urbase.linear() = L.transpose();
  ur.gravity_base = L * nominal.gravity_base;
  for (int i = 0; i < n; ++i) {
    const JointSpec& j = nominal.joints[static_cast<size_t>(i)];
    JointSpec& u = ur.joints[static_cast<size_t>(i)];
    const double s = flip ? -1.0 : 1.0;
    double theta = wrap180(s * j.theta0_deg + phi);  // the constant part of the joint angle
    double a = j.a_mm, alpha = j.alpha_deg + (flip ? 180.0 : 0.0);
    const double d = s * j.d_mm;
    const bool last = i + 1 == n;
    Eigen::Matrix3d R;
    bool next_flip = false;
    double next_phi = 0;
    if (last && a == 0.0) {
      // Rz(q + theta) Tz(d) Rx(alpha) = Rz(q + rest) Tz(d) * Rz(theta - rest) Rx(alpha): as on link 1, a
      // rest within kMaxUrFactoryCorrectionDeg of 0 or 180 deg is a delta_theta, a larger one
      // turns the flange frame; so does alpha (UR's delta_alpha and delta_a of the last joint are 0)
      const double rest = theta - 180.0 * std::round(theta / 180.0);
      const bool fold = std::abs(rest) <= kMaxUrFactoryCorrectionDeg && std::abs(rest) > kUrAngleSnapDeg;
      if (fold) c.folded_theta0_deg[static_cast<size_t>(i)] = rest;
      const double turn = fold || std::abs(rest) <= kUrAngleSnapDeg ? theta - rest : theta;
      R = rotZDeg(turn) * rotXDeg(std::abs(wrap180(alpha)) <= kUrAngleSnapDeg ? 0.0 : alpha);
      theta = alpha = 0;
    } else {
      const double k = std::round(theta / 180.0), rest = theta - 180.0 * k;
      if (std::abs(rest) > kMaxUrFactoryCorrectionDeg)  // (never on link 1: frame 0 turned)
        throw ArgumentError("robot '" + nominal.name + "' joint '" + j.name + "': a UR table has theta0 0 on every joint, found " +
                            formatNumber("%.6g", theta) + " deg in UR's convention (more than " +
                            formatNumber("%g", kMaxUrFactoryCorrectionDeg) +
                            " deg from 0 and 180 deg, which a turn of the DH x axis absorbs): not a UR arm's chain" + kUrChainHint);
      if (std::abs(rest) > kUrAngleSnapDeg) c.folded_theta0_deg[static_cast<size_t>(i)] = rest;
      const bool x_flip = k != 0.0 && std::fmod(std::abs(k), 2.0) == 1.0;
      if (x_flip) {
        a = -a;
        alpha = -alpha;
      }
      next_flip = !last && nominal.joints[static_cast<size_t>(i + 1)].direction == -1;
      if (next_flip) alpha -= 180.0;
      next_phi = x_flip ? 180.0 : 0.0;
      R = halfTurnIf(x_flip, true) * halfTurnIf(next_flip);
      theta = 0;
    }
    alpha = wrap180(alpha);
    const double k90 = std::round(alpha / 90.0);
    if (std::abs(alpha - 90.0 * k90) <= kUrAngleSnapDeg) alpha = 90.0 * k90;
    u.theta0_deg = 0;
    u.direction = 1;
    u.d_mm = d + 0.0;  // (never -0)
    u.a_mm = a + 0.0;
    u.alpha_deg = alpha + 0.0;
    u.com_mm = R * j.com_mm;  // frame i of the robot = frame i of the table * R
    if (last) {
      c.T_urflange_flange.linear() = R;
      ur.payload_com_mm = R * nominal.payload_com_mm;
    }
    flip = next_flip;
    phi = next_phi;
  }
  c.rewritten = !c.T_frame0_urbase.isApprox(Eigen::Isometry3d::Identity(), 0) ||
                !c.T_urflange_flange.isApprox(Eigen::Isometry3d::Identity(), 0);
  for (int i = 0; i < n; ++i) {
    const JointSpec &j = nominal.joints[static_cast<size_t>(i)], &u = ur.joints[static_cast<size_t>(i)];
    c.rewritten = c.rewritten || j.direction != 1 || j.theta0_deg != 0.0 || j.d_mm != u.d_mm || j.a_mm != u.a_mm || j.alpha_deg != u.alpha_deg;
  }
  return c;
}

}  // namespace

UrConvention urConventionOf(const RobotDefinition& nominal) {
  if (nominal.dof() == 0) throw ArgumentError("robot '" + nominal.name + "': a UR table needs joints, found none");
  for (const JointSpec& j : nominal.joints)
    if (j.type != JointType::kRevolute)
      throw ArgumentError("robot '" + nominal.name + "' joint '" + j.name + "': a UR table holds revolute joints, found a prismatic one" +
                          kUrChainHint);
  // Frame 0's x has two signs that give theta0 0 (ROS's base_link and UR's Base, turned by 180
  // deg about axis 1 from each other); UR's tables take the one with alpha_1 = +90 deg (and
  // a_2 < 0: the arm stretched along -x at zero).
  UrConvention c = urConventionTurned(nominal, 0.0);
  if (c.ur.joints[0].alpha_deg < 0.0 && c.ur.joints[0].alpha_deg > -180.0) c = urConventionTurned(nominal, 180.0);
  return c;
}

UrDeltas readUrCalibrationConf(const std::string& path, int dof) {
  const std::vector<std::string> lines = readLines(path, "UR calibration file");
  std::map<std::string, std::vector<double>*> wanted;
  UrDeltas d;
  wanted["delta_theta"] = &d.theta_rad;
  wanted["delta_a"] = &d.a_m;
  wanted["delta_d"] = &d.d_m;
  wanted["delta_alpha"] = &d.alpha_rad;
  std::map<std::string, int> seen;
  std::string section;
  bool any_section = false;
  std::string other_sections;                  // the names of the sections that are not [mounting]
  int mounting_line = 0, mounting_column = 0;  // the [mounting] header, when there is one
  for (size_t k = 0; k < lines.size(); ++k) {
    const int line = static_cast<int>(k + 1);
    // (the columns are those of the line as written: a comment is cut off at its end)
    std::string raw = lines[k];
    if (const size_t hash = raw.find('#'); hash != std::string::npos) raw = raw.substr(0, hash);
    const std::string l = trimBlanks(raw);
    if (l.empty()) continue;
    const int first = columnOfText(raw);
    if (l.front() == '[') {
      if (l.back() != ']') throw InputError(path, line, first, "expected a section header like [mounting], found '" + l + "'");
      section = trimBlanks(l.substr(1, l.size() - 2));
      any_section = true;
      // UR's controller writes the section as [mounting]; another spelling is another section
      // to an INI reader, and taking it for this one would be a guess
      std::string lower = section;
      for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
      if (lower == "mounting" && section != "mounting")
        throw InputError(path, line, first, "expected the section header [mounting] (in lower case, as UR's controller writes "
                                            "calibration.conf), found '" + l + "'");
      if (section == "mounting") {
        mounting_line = line;
        mounting_column = first;
      } else {
        other_sections += (other_sections.empty() ? "" : ", ") + l;
      }
      continue;
    }
    const size_t eq = raw.find('=');
    if (eq == std::string::npos) throw InputError(path, line, first, "expected 'key = value', found '" + l + "'");
    if (!any_section)  // an INI file's keys belong to a section: UR's controller writes [mounting] first
      throw InputError(path, line, first, "expected the section header [mounting] before '" + trimBlanks(raw.substr(0, eq)) +
                                          " = ...' (UR's controller writes the deltas in section [mounting]), found no section header");
    if (section != "mounting") continue;
    const std::string key = trimBlanks(raw.substr(0, eq));
    auto it = wanted.find(key);
    if (it == wanted.end()) continue;  // joint_checksum, calibration_status, ...: not kinematics
    if (seen.count(key))
      throw InputError(path, line, first, key + " given twice (first at line " + std::to_string(seen[key]) + ")");
    seen[key] = line;
    const int value_column = columnOfText(raw, eq + 1);
    const std::string v = trimBlanks(raw.substr(eq + 1));
    if (v.size() < 2 || v.front() != '[' || v.back() != ']')
      throw InputError(path, line, value_column,
                       key + ": expected a list [v1, ..., v" + std::to_string(dof) + "], found '" + v + "'");
    // the items between the brackets, each with its column
    const size_t open = static_cast<size_t>(value_column - 1), close = raw.find_last_of(']');
    std::vector<int> item_column;
    for (size_t a = open + 1; a <= close;) {
      size_t b = raw.find(',', a);
      if (b == std::string::npos || b > close) b = close;
      const int c = columnOfText(raw, a);  // (an empty item: where it would start)
      item_column.push_back(c <= static_cast<int>(b) ? c : static_cast<int>(a) + 1);
      it->second->push_back(parseNumber(path, line, item_column.back(), raw.substr(a, b - a), key));
      a = b + 1;
    }
    if (static_cast<int>(it->second->size()) != dof)
      throw InputError(path, line, value_column, key + ": expected " + std::to_string(dof) + " values, found " +
                                                     std::to_string(it->second->size()));
    for (size_t i = 0; i < it->second->size(); ++i) {
      const double x = (*it->second)[i];
      const bool angle = key == "delta_theta" || key == "delta_alpha";
      if (angle ? std::abs(x) > 2 * kPi : std::abs(x) > 1000.0)
        throw InputError(path, line, item_column[i],
                         key + " value " + std::to_string(i + 1) + ": expected " +
                             (angle ? "an angle of at most a turn (2 pi rad)" : "a DH delta of at most 1000 m") +
                             ", found " + num17(x) + (angle ? " rad" : " m"));
    }
  }
  if (!mounting_line) {
    bool blank = true;
    for (const std::string& l : lines) blank = blank && trimBlanks(l).empty();
    throw InputError(path, 1, 1, "expected a section [mounting] with delta_theta, delta_a, delta_d and delta_alpha, found " +
                                     (other_sections.empty() ? std::string(blank ? "an empty file" : "no section")
                                                             : "only the section(s) " + other_sections));
  }
  for (const auto& [key, vec] : wanted) {
    if (seen.count(key)) continue;
    throw InputError(path, mounting_line, mounting_column, "expected '" + key + " = [...]' in [mounting], found none");
  }
  return d;
}

std::string formatUrCalibrationConf(const UrDeltas& d) {
  std::ostringstream out;
  auto list = [&](const char* key, const std::vector<double>& v) {
    out << key << " = [";
    for (size_t i = 0; i < v.size(); ++i) out << (i ? ", " : " ") << num17(v[i]);
    out << "]\n";
  };
  out << "[mounting]\n";
  list("delta_theta", d.theta_rad);
  list("delta_a", d.a_m);
  list("delta_d", d.d_m);
  list("delta_alpha", d.alpha_rad);
  return out.str();
}

void checkUrNominal(const RobotDefinition& nominal, const UrDeltas* deltas) {
  for (const JointSpec& j : nominal.joints)
    if (j.type != JointType::kRevolute || j.direction != 1 || j.theta0_deg != 0.0)
      throw ArgumentError("robot '" + nominal.name + "' joint '" + j.name +
                          "': a UR table needs revolute joints with direction 1 and theta0 0");
  if (!nominal.T_world_base.isApprox(Eigen::Isometry3d::Identity(), 0) ||
      !nominal.T_flange_tcp.isApprox(Eigen::Isometry3d::Identity(), 0))
    throw ArgumentError("robot '" + nominal.name + "': a UR table needs identity base and tool (world = Base = DH frame 0)");
  if (deltas) {
    const size_t n = nominal.joints.size();
    if (deltas->theta_rad.size() != n || deltas->a_m.size() != n || deltas->d_m.size() != n || deltas->alpha_rad.size() != n)
      throw ArgumentError("UR deltas: expected " + std::to_string(n) + " values per list for robot '" + nominal.name + "'");
  }
}

Eigen::Isometry3d urFlangePose(const RobotDefinition& nominal, const UrDeltas& d, const Eigen::VectorXd& q) {
  checkUrNominal(nominal, &d);
  if (q.size() != nominal.dof()) throw ArgumentError("expected " + std::to_string(nominal.dof()) + " joint values");
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  for (int i = 0; i < nominal.dof(); ++i) {
    const JointSpec& j = nominal.joints[static_cast<size_t>(i)];
    const size_t k = static_cast<size_t>(i);
    T = T * dh(q[i] * kDegToRad + d.theta_rad[k], j.d_mm / 1000.0 + d.d_m[k], j.a_mm / 1000.0 + d.a_m[k],
               j.alpha_deg * kDegToRad + d.alpha_rad[k]);
  }
  return T;
}

SerialChain urDeltaChain(const RobotDefinition& nominal, const UrDeltas& d) {
  checkUrNominal(nominal, &d);
  SerialChain c;
  c.name = nominal.name;
  c.source = "UR DH deltas";
  c.root_link = "base";
  c.tip_link = "flange";
  Eigen::Isometry3d prev = Eigen::Isometry3d::Identity();
  for (int i = 0; i < nominal.dof(); ++i) {
    const JointSpec& j = nominal.joints[static_cast<size_t>(i)];
    const size_t k = static_cast<size_t>(i);
    ChainJoint cj;
    cj.name = j.name;
    cj.T_prev_joint = prev;
    cj.lower = j.lower;
    cj.upper = j.upper;
    c.joints.push_back(cj);
    prev = dh(d.theta_rad[k], j.d_mm / 1000.0 + d.d_m[k], j.a_mm / 1000.0 + d.a_m[k], j.alpha_deg * kDegToRad + d.alpha_rad[k]);
  }
  c.T_last_tip = prev;
  return c;
}

namespace {

// A factory calibration moves the flange by millimetres: one that moves it by more is the
// calibration of another arm (a UR5's on a UR10) or a corrupted file, not this arm's.
void checkFactoryCalibrationSize(const RobotDefinition& nominal, const SerialChain& chain, const std::string& what) {
  const ChainComparison c = compareModelWithChain(RobotModel::fromDefinition(nominal), chain);
  if (c.max_position_mm <= kMaxUrFactoryCorrectionMm && c.max_rotation_rad * kRadToDeg <= kMaxUrFactoryCorrectionDeg) return;
  throw ArgumentError(what + ": expected the factory calibration of a " + nominal.name + " (the flange within " +
                      formatFixed(kMaxUrFactoryCorrectionMm, 0) + " mm and " + formatFixed(kMaxUrFactoryCorrectionDeg, 0) +
                      " deg of the nominal arm's), found one that moves it by up to " + formatFixed(c.max_position_mm, 1) + " mm and " +
                      formatFixed(c.max_rotation_rad * kRadToDeg, 2) +
                      " deg: the calibration of another arm type, or values that are not this arm's");
}

}  // namespace

RobotModel modelFromUrDeltas(const RobotDefinition& nominal, const UrDeltas& deltas) {
  const UrConvention c = urConventionOf(nominal);
  for (size_t i = 0; i < c.folded_theta0_deg.size(); ++i)
    if (c.folded_theta0_deg[i] != 0.0)
      throw ArgumentError("robot '" + nominal.name + "' joint '" + nominal.joints[i].name + "': expected UR's nominal table (theta0 0 or 180 deg), found " +
                          formatNumber("%.6g", c.folded_theta0_deg[i]) +
                          " deg off it: a calibrated description? UR's factory deltas apply to the nominal arm (e.g. the bundled robot or "
                          "ur_description's URDF without a calibration)");
  const SerialChain ur_chain = urDeltaChain(c.ur, deltas);
  // in the robot's frames: its base, UR's table between its DH frame 0 and its flange, its tool
  const SerialChain chain = framed(ur_chain, nominal.T_world_base * c.T_frame0_urbase, c.T_urflange_flange * nominal.T_flange_tcp);
  RobotModel m = modelFromChain(chain, &nominal, FormPolicy::kAuto, kUrCheckTolMm);
  checkFactoryCalibrationSize(c.ur, ur_chain, "UR factory DH deltas");
  m.nominal.source = nominal.source + "; calibrated with UR's factory DH deltas";
  return m;
}

UrDeltasFromModel urDeltasFromModel(const RobotModel& model) {
  model.validate();
  const UrConvention c = urConventionOf(model.nominal);
  const RobotDefinition& ur = c.ur;
  UrDeltasFromModel out;
  out.not_represented = notInUrTable(model);
  out.table = ur;
  out.table_rewritten = c.rewritten;
  const SerialChain chain = urFlangeChain(model, c);
  RobotModel dh_model;
  try {
    dh_model = modelFromChain(chain, &ur, FormPolicy::kDHOnly, kUrCheckTolMm);
  } catch (const ArgumentError& e) {
    throw ArgumentError(std::string("UR deltas of '") + model.nominal.name + "': " + e.what());
  }
  UrDeltas& d = out.deltas;
  for (int i = 0; i < model.dof(); ++i) {
    const LinkDeviation& l = dh_model.deviations.links[static_cast<size_t>(i)];
    d.theta_rad.push_back(l.dtheta_rad);
    d.a_m.push_back(l.da_mm / 1000.0);
    d.d_m.push_back(l.dd_mm / 1000.0);
    d.alpha_rad.push_back(l.dalpha_rad);
    if (std::abs(l.dd_mm) > 1000.0)
      out.not_represented.push_back("joint '" + model.nominal.joints[static_cast<size_t>(i)].name + "': delta_d = " +
                                    num17(l.dd_mm / 1000.0) +
                                    " m: its axis is nearly parallel to the previous one and DH needs a huge length "
                                    "(exact, but ill-conditioned: the Hayati form holds it with a small beta)");
  }
  // Base and tool of the DH rewrite: the chain starts at DH frame 0 and its last frame is a
  // DH frame, so both are identity to round-off (the check below proves it).
  // Check: the model's flange chain (in UR's frames) against UR's formula (as a chain) with these deltas.
  RobotModel geometric = urdf_detail::geometricPart(model);  // without base and tool deviations:
  geometric.nominal.T_world_base = c.T_frame0_urbase.inverse();
  geometric.nominal.T_flange_tcp = c.T_urflange_flange.inverse();
  geometric.deviations.base_mm.setZero();
  geometric.deviations.base_rot_rad.setZero();
  geometric.deviations.tool_mm.setZero();
  geometric.deviations.tool_rot_rad.setZero();
  out.max_difference_mm = compareModelWithChain(geometric, urDeltaChain(ur, d)).max_position_mm;
  return out;
}

SerialChain readUrCalibrationYaml(const std::string& path) {
  const std::vector<std::string> lines = readLines(path, "UR calibration YAML");
  // The subset ur_calibration writes: "kinematics:", link names indented (the first one's
  // indentation is the links'), "key: value" indented deeper, "hash: ..." at the links' level;
  // a link may also be written as a flow mapping "shoulder: {x: 0, y: 0, ...}", and a
  // document may start with "---".
  std::map<std::string, std::map<std::string, double>> values;
  std::map<std::string, std::map<std::string, int>> value_line;
  std::map<std::string, int> link_line, link_column;
  std::string link;
  int kin_line = 0;
  size_t link_indent = 0;  // 0: not known yet
  auto setValue = [&](int line, int key_column, int column, const std::string& key, const std::string& text) {
    if (link.empty()) throw InputError(path, line, key_column, "'" + key + "' outside a link entry");
    if (!(key == "x" || key == "y" || key == "z" || key == "roll" || key == "pitch" || key == "yaw"))
      throw InputError(path, line, key_column, "'" + link + "': expected a key x, y, z, roll, pitch or yaw, found '" + key + "'");
    if (const auto it = value_line[link].find(key); it != value_line[link].end())
      throw InputError(path, line, key_column,
                       "'" + link + "." + key + "': expected one value, found a second one (the first at line " + std::to_string(it->second) + ")");
    value_line[link][key] = line;
    // a number may be written as a quoted scalar ("0.1273" or '0.1273')
    const bool quoted = text.size() >= 2 && (text.front() == '"' || text.front() == '\'') && text.back() == text.front();
    const double v = parseNumber(path, line, column + (quoted ? 1 : 0), quoted ? text.substr(1, text.size() - 2) : text, link + "." + key);
    const bool angle = key == "roll" || key == "pitch" || key == "yaw";
    if (angle ? std::abs(v) > 2 * kPi : std::abs(v) > 1000.0)
      throw InputError(path, line, column,
                       link + "." + key + ": expected " + (angle ? "an angle of at most a turn (2 pi rad)" : "an offset of at most 1000 m") +
                           ", found " + num17(v) + (angle ? " rad" : " m"));
    values[link][key] = v;
  };
  for (size_t k = 0; k < lines.size(); ++k) {
    const int line = static_cast<int>(k + 1);
    std::string raw = lines[k];
    if (const size_t hash = raw.find('#'); hash != std::string::npos) raw = raw.substr(0, hash);
    if (trimBlanks(raw).empty()) continue;
    const size_t indent = raw.find_first_not_of(' ');
    const int first = columnOfText(raw);
    const std::string l = trimBlanks(raw);
    if (raw[indent] == '\t') throw InputError(path, line, static_cast<int>(indent) + 1, "expected spaces for the indentation (YAML allows no tabs there), found a tab");
    if (indent == 0 && (l == "---" || l == "...")) continue;  // a YAML document's start and end
    const size_t colon = raw.find(':');
    if (colon == std::string::npos) throw InputError(path, line, first, "expected 'key: value', found '" + l + "'");
    const std::string key = trimBlanks(raw.substr(0, colon)), value = trimBlanks(raw.substr(colon + 1));
    if (indent == 0) {
      if (key != "kinematics") throw InputError(path, line, first, "expected 'kinematics:', found '" + l + "'");
      kin_line = line;
      link.clear();
      link_indent = 0;
      continue;
    }
    if (kin_line == 0) throw InputError(path, line, first, "expected 'kinematics:' before '" + l + "'");
    if (link_indent == 0) link_indent = indent;
    if (indent < link_indent)
      throw InputError(path, line, first, "expected an indentation of " + std::to_string(link_indent) + " (the links') or more, found " +
                                              std::to_string(indent));
    if (indent == link_indent) {
      if (key == "hash") {
        link.clear();  // a key below it is no link's
        continue;
      }
      link = key;
      if (link_line.count(link)) throw InputError(path, line, first, "'" + link + "' given twice");
      link_line[link] = line;
      link_column[link] = first;
      if (value.empty()) continue;
      // a flow mapping: {x: 0, y: 0, ...}
      const size_t open = raw.find('{', colon), close = raw.rfind('}');
      if (value.front() != '{' || value.back() != '}' || close == std::string::npos)
        throw InputError(path, line, columnOfText(raw, colon + 1), "'" + link + "': expected its keys on the lines below or as {x: .., ...}, found '" + value + "'");
      size_t at = open + 1;
      while (at < close) {
        size_t end = raw.find(',', at);
        if (end == std::string::npos || end > close) end = close;
        const std::string item = raw.substr(at, end - at);
        const size_t c = item.find(':');
        const int item_column = columnOfText(raw, at);
        if (c == std::string::npos) throw InputError(path, line, item_column, "'" + link + "': expected 'key: value', found '" + trimBlanks(item) + "'");
        setValue(line, item_column, columnOfText(raw, at + c + 1), trimBlanks(item.substr(0, c)), trimBlanks(item.substr(c + 1)));
        at = end + 1;
      }
      link.clear();
      continue;
    }
    setValue(line, first, columnOfText(raw, colon + 1), key, value);
  }
  SerialChain c;
  c.name = "UR (ur_calibration YAML)";
  c.source = path;
  c.root_link = "base";
  c.tip_link = "flange";
  for (const char* name : kYamlLinks) {
    auto it = values.find(name);
    if (it == values.end()) {
      const auto [line, column] = kin_line ? std::pair<int, int>{kin_line, 1} : endOfFile(lines);
      throw InputError(path, line, column, std::string("kinematics: expected an entry '") + name + ":', found none");
    }
    for (const char* key : {"x", "y", "z", "roll", "pitch", "yaw"})
      if (!it->second.count(key))
        throw InputError(path, link_line[name], link_column[name],
                         std::string("'") + name + "': expected '" + key + ": value', found none");
    const auto& v = it->second;
    ChainJoint j;
    j.name = std::string(name) + "_joint";
    j.T_prev_joint.linear() = rpyMatrix(v.at("roll"), v.at("pitch"), v.at("yaw"));
    j.T_prev_joint.translation() = 1000.0 * Eigen::Vector3d(v.at("x"), v.at("y"), v.at("z"));
    j.line = link_line[name];
    j.column = link_column[name];
    c.joints.push_back(j);
  }
  return c;
}

RobotModel modelFromUrCalibrationYaml(const RobotDefinition& nominal, const std::string& path) {
  const UrConvention c = urConventionOf(nominal);
  SerialChain chain = readUrCalibrationYaml(path);
  if (nominal.dof() != static_cast<int>(chain.joints.size()))
    throw ArgumentError("robot '" + nominal.name + "' has " + std::to_string(nominal.dof()) + " joints, the YAML 6" + kUrChainHint);
  for (size_t i = 0; i < chain.joints.size(); ++i) {
    chain.joints[i].name = nominal.joints[i].name;
    chain.joints[i].lower = nominal.joints[i].lower;
    chain.joints[i].upper = nominal.joints[i].upper;
  }
  // The YAML's shoulder entry places joint 1 from UR's Base, which the table puts at the robot's
  // DH frame 0: the foot of the perpendicular from its chain's root onto axis 1. A root on a mount
  // (a pedestal or a ceiling under ur_description's base_link) puts frame 0 at the mount's level
  // and d1 holds the mount's height, which the YAML does not (the deltas of calibration.conf add
  // to d1, which a shift along axis 1 leaves alone). The arm the YAML describes from there:
  const double mount_mm = c.ur.joints[0].d_mm - chain.joints[0].T_prev_joint.translation().z();
  if (std::abs(mount_mm) > kMaxUrFactoryCorrectionMm) {
    SerialChain on_mount = chain;
    on_mount.joints[0].T_prev_joint.translation().z() += mount_mm;
    const ChainComparison m = compareModelWithChain(RobotModel::fromDefinition(c.ur), on_mount);
    if (m.max_position_mm <= kMaxUrFactoryCorrectionMm && m.max_rotation_rad * kRadToDeg <= kMaxUrFactoryCorrectionDeg)
      throw ArgumentError(path + ": expected UR's Base at the robot's DH frame 0, the shoulder " + formatFixed(c.ur.joints[0].d_mm, 1) +
                          " mm from it (d1 of '" + nominal.name + "' in UR's convention), found the shoulder " +
                          formatFixed(chain.joints[0].T_prev_joint.translation().z(), 1) +
                          " mm from UR's Base in the YAML: the robot's DH frame 0 lies about " + formatFixed(std::abs(mount_mm), 1) +
                          " mm from the arm's Base along axis 1 (a mount between the chain's root and the arm), where the YAML cannot place the arm"
                          " (from a URDF: read the arm from its own base with --chain base:tool0 on ur_description's URDF)");
  }
  // in the robot's frames: its base, the YAML's chain between its DH frame 0 and its flange, its tool
  const SerialChain robot_chain = framed(chain, nominal.T_world_base * c.T_frame0_urbase, c.T_urflange_flange * nominal.T_flange_tcp);
  RobotModel m = modelFromChain(robot_chain, &nominal, FormPolicy::kAuto, kUrCheckTolMm);  // (its joint-by-joint errors first)
  checkFactoryCalibrationSize(c.ur, chain, path);
  m.nominal.source = nominal.source + "; calibrated with the ur_calibration YAML " + path;
  return m;
}

std::string formatUrCalibrationYaml(const RobotModel& model, std::vector<std::string>* not_represented) {
  model.validate();
  if (model.dof() != 6) throw ArgumentError("UR calibration YAML: expected a 6-axis robot, '" + model.nominal.name + "' has " +
                                            std::to_string(model.dof()) + " joints" + kUrChainHint);
  const UrConvention c = urConventionOf(model.nominal);
  std::vector<std::string> notes = notInUrTable(model);
  // A model written in another convention: its flange chain as the table's model (Hayati form)
  const RobotModel converted = c.rewritten ? modelFromChain(urFlangeChain(model, c), &c.ur, FormPolicy::kAuto, kUrCheckTolMm) : RobotModel();
  const RobotModel& m = c.rewritten ? converted : model;
  // Joint k's origin = [Tx(a) Rx(alpha) Ry(beta)] of link k-1 * [Rz(theta) Tz(d)] of link k.
  std::ostringstream out;
  out << "kinematics:\n";
  Eigen::Isometry3d pending = Eigen::Isometry3d::Identity();
  for (int i = 0; i < 6; ++i) {
    const JointSpec& j = m.nominal.joints[static_cast<size_t>(i)];
    const LinkDeviation& d = m.deviations.links[static_cast<size_t>(i)];
    Eigen::Isometry3d O = pending;
    O.rotate(Eigen::AngleAxisd(j.theta0_deg * kDegToRad + d.dtheta_rad, Eigen::Vector3d::UnitZ()));
    O.translate(Eigen::Vector3d(0, 0, j.d_mm + d.dd_mm));
    // UR's Base is the arm's own: a model read from a root on a mount has the mount's height in
    // d1 (frame 0 at the mount's foot), which the YAML would place under the arm once more
    if (i == 0 && std::abs(O.translation().z()) > kMaxUrShoulderHeightMm)
      throw ArgumentError("UR calibration YAML: expected the shoulder within " + formatFixed(kMaxUrShoulderHeightMm, 0) +
                          " mm of UR's Base (d1 of every UR arm: 89.2 to 236.3 mm), found it " + formatFixed(O.translation().z(), 1) +
                          " mm from the DH frame 0 of '" + model.nominal.name +
                          "' along axis 1: its chain's root stands on a mount, whose height the YAML cannot hold (written, it would"
                          " lift the arm by it once more); from a URDF, read the arm from its own base with --chain base:tool0");
    const Eigen::Vector3d p = O.translation() / 1000.0, rpy = urdf_detail::urdfRpy(O.linear());
    out << "  " << kYamlLinks[i] << ":\n    x: " << num17(p.x()) << "\n    y: " << num17(p.y()) << "\n    z: " << num17(p.z())
        << "\n    roll: " << num17(rpy.x()) << "\n    pitch: " << num17(rpy.y()) << "\n    yaw: " << num17(rpy.z()) << "\n";
    pending.setIdentity();
    pending.translate(Eigen::Vector3d(j.a_mm + d.da_mm, 0, 0));
    pending.rotate(Eigen::AngleAxisd(j.alpha_deg * kDegToRad + d.dalpha_rad, Eigen::Vector3d::UnitX()));
    pending.rotate(Eigen::AngleAxisd(d.dbeta_rad, Eigen::Vector3d::UnitY()));
  }
  if (pending.translation().norm() > 0 || !pending.linear().isIdentity(0))
    notes.push_back("last link: a = " + num17(pending.translation().x()) +
                    " mm / alpha, beta not zero: the YAML's six entries end at the wrist_3 joint; move it into the TCP");
  // ur_description's xacro reads kinematics.hash (a missing key stops it); the driver compares
  // it with the connected arm's own calibration hash and warns when they differ, which they do:
  // this is not the factory calibration. A digest of the numbers above, marked as accura's.
  std::uint64_t fnv = 1469598103934665603ull;
  for (const char ch : out.str()) fnv = (fnv ^ static_cast<unsigned char>(ch)) * 1099511628211ull;
  out << "  hash: calib_accura_" << fnv << "\n";
  if (not_represented) *not_represented = notes;
  return out.str();
}

}  // namespace accura::calib
