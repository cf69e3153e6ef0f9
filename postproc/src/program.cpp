#include "accura/postproc/program.h"

#include <cctype>
#include <cmath>
#include <cstdio>

#include "accura/calib/errors.h"

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
