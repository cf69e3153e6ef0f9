#include "accura/postproc/program.h"

#include <cctype>
#include <cmath>
#include <algorithm>
#include <cstdio>

#include "accura/calib/errors.h"
#include "accura/postproc/rapid.h"

namespace accura::postproc {

std::string SourceLocation::str() const {
  std::string s = calib::formatLocation(file, line, column);
  // formatLocation ends with ": "; a location on its own has no separator.
  if (s.size() >= 2) s.resize(s.size() - 2);
  return s;
}

const char* toString(Approximation a) {
  switch (a) {
    case Approximation::kCPtp: return "C_PTP";
    case Approximation::kCDis: return "C_DIS";
    case Approximation::kCVel: return "C_VEL";
    case Approximation::kCOri: return "C_ORI";
    case Approximation::kCSpl: return "C_SPL";
  }
  return "?";
}

bool parseApproximation(const std::string& text, Approximation* out) {
  std::string u;
  for (char c : text) u += static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  static const Approximation all[] = {Approximation::kCPtp, Approximation::kCDis, Approximation::kCVel,
                                      Approximation::kCOri, Approximation::kCSpl};
  for (Approximation a : all) {
    if (u == toString(a)) {
      *out = a;
      return true;
    }
  }
  return false;
}

bool Target::completePose() const {
  for (const auto& c : pose)
    if (!c) return false;
  return true;
}

calib::XyzAbc Target::xyzAbc() const {
  if (!completePose()) throw calib::ArgumentError("Target::xyzAbc: the pose of " + (name.empty() ? std::string("an inline target") : name) + " is partial");
  return calib::XyzAbc{*pose[0], *pose[1], *pose[2], *pose[3], *pose[4], *pose[5]};
}

void Target::setPose(const calib::XyzAbc& p) {
  pose = {p.x_mm, p.y_mm, p.z_mm, p.a_deg, p.b_deg, p.c_deg};
}

bool Target::setPoseIfChanged(const calib::XyzAbc& p) {
  const double v[6] = {p.x_mm, p.y_mm, p.z_mm, p.a_deg, p.b_deg, p.c_deg};
  auto text = [](int k, double x) { return k < 3 ? formatMm(x) : formatDeg(x); };
  bool changed = false;
  for (int k = 0; k < 6; ++k) {
    if (pose[k] && text(k, *pose[k]) == text(k, v[k])) continue;
    pose[k] = v[k];
    changed = true;
  }
  return changed;
}

bool programChanged(const Program& program) {
  for (const Motion& m : program.motions) {
    if (m.inserted || m.target.modified || (m.aux && m.aux->modified)) return true;
  }
  return false;
}

namespace {

std::string upperAscii(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

bool isIdentChar(char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '$'; }

// `up` as an identifier (upper case) in `text`.
bool containsIdentifier(const std::string& text, const std::string& up) {
  const std::string u = upperAscii(text);
  for (size_t p = u.find(up); p != std::string::npos; p = u.find(up, p + 1)) {
    const bool left = p == 0 || !isIdentChar(u[p - 1]);
    const bool right = p + up.size() >= u.size() || !isIdentChar(u[p + up.size()]);
    if (left && right) return true;
  }
  return false;
}

}  // namespace

std::string newPointName(const Program& program, const std::string& base, const std::vector<std::string>& taken) {
  for (int n = 1; n < 100000; ++n) {
    const std::string suffix = "_" + std::to_string(n);
    const std::string name = base.substr(0, std::min(base.size(), static_cast<size_t>(24) - suffix.size())) + suffix;
    const std::string up = upperAscii(name);
    bool used = false;
    for (const std::string& t : taken) used = used || upperAscii(t) == up;
    for (const Motion& m : program.motions) {
      used = used || upperAscii(m.target.name) == up || (m.aux && upperAscii(m.aux->name) == up);
    }
    if (program.krl) used = used || containsIdentifier(program.krl->src_text, up) || containsIdentifier(program.krl->dat_text, up);
    if (program.rapid) used = used || containsIdentifier(program.rapid->text, up);
    for (const PassThrough& s : program.passthrough) used = used || containsIdentifier(s.text, up);
    if (!used) return name;
  }
  throw calib::ArgumentError("newPointName: no free name for " + base);
}

void checkPassThrough(const Program& program, const std::string& language) {
  for (const PassThrough& s : program.passthrough) {
    if (!s.refuse.empty())
      throw calib::ArgumentError(s.where.str() + ": cannot convert '" + s.text + "': " + s.refuse);
    if (!language.empty() && s.language != language)
      throw calib::ArgumentError(s.where.str() + ": cannot convert the " + s.language + " statement '" + s.text + "' to " + language +
                          ": it is outside the motion model and only " + s.language + " can carry it");
  }
}

std::string motionKeyword(const Motion& m) {
  std::string k;
  switch (m.type) {
    case MotionType::kPtp: k = "PTP"; break;
    case MotionType::kLin: k = "LIN"; break;
    case MotionType::kCirc: k = "CIRC"; break;
    case MotionType::kSpl: return "SPL";
  }
  if (m.spline) k = "S" + k;
  if (m.relative) k += "_REL";
  return k;
}

std::string formatMm(double v) { return calib::formatFixed(v, 4); }
std::string formatDeg(double v) { return calib::formatFixed(v, 5); }

}  // namespace accura::postproc
