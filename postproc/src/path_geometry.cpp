#include "path_geometry.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "accura/calib/errors.h"
#include "accura/calib/geometry.h"

namespace accura::postproc::detail {

PathGeometry::PathGeometry(const PathSegment& s) : type(s.type) {
  p0 = s.T_world_start.translation();
  p1 = s.T_world_end.translation();
  q0 = Eigen::Quaterniond(s.T_world_start.linear()).normalized();
  q1 = Eigen::Quaterniond(s.T_world_end.linear()).normalized();
  if (q0.dot(q1) < 0) q1.coeffs() *= -1;  // the short way
  rotation_rad = q0.angularDistance(q1);
  if (type == PathType::kLin) {
    length_mm = (p1 - p0).norm();
    return;
  }
  const Eigen::Vector3d pa = s.T_world_aux.translation();
  const Eigen::Vector3d a = pa - p0, b = p1 - p0;
  const Eigen::Vector3d axb = a.cross(b);
  const double scale = std::max({a.norm(), b.norm(), (p1 - pa).norm()});
  // |a x b| = 2 * triangle area; relative to the longest side squared it is the sine of an
  // angle of the triangle: below 1e-6 the circle is not defined to better than a metre
  if (!(scale > 1e-9) || !(axb.norm() > 1e-6 * scale * scale))
    throw calib::NumericalError("CIRC: start, auxiliary and end point are collinear or coincide (no circle through them)");
  c = p0 + (a.squaredNorm() * b.cross(axb) + b.squaredNorm() * axb.cross(a)) / (2 * axb.squaredNorm());
  n = axb.normalized();  // start -> aux -> end turns positively about n
  r = (p0 - c).norm();
  e1 = (p0 - c) / r;
  e2 = n.cross(e1);
  auto angleOf = [&](const Eigen::Vector3d& p) {
    const Eigen::Vector3d v = p - c;
    double t = std::atan2(v.dot(e2), v.dot(e1));
    if (t < 0) t += 2 * calib::kPi;
    return t;
  };
  arc = angleOf(p1);
  if (arc <= 0) arc = 2 * calib::kPi;
  length_mm = r * arc;
}

Eigen::Vector3d PathGeometry::position(double s) const {
  if (type == PathType::kLin) return p0 + s * (p1 - p0);
  const double t = s * arc;
  return c + r * (std::cos(t) * e1 + std::sin(t) * e2);
}

Eigen::Isometry3d PathGeometry::pose(double s) const {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = q0.slerp(s, q1).toRotationMatrix();
  T.translation() = position(s);
  return T;
}

Eigen::Vector3d PathGeometry::deviation(const Eigen::Vector3d& p) const {
  if (type == PathType::kLin) {
    const Eigen::Vector3d v = p - p0;
    if (!(length_mm > 0)) return v;
    const Eigen::Vector3d u = (p1 - p0) / length_mm;
    return v - v.dot(u) * u;
  }
  const Eigen::Vector3d v = p - c;
  const double h = v.dot(n);
  const double rho = (v - h * n).norm();
  return Eigen::Vector3d(h, rho - r, 0);
}

double PathGeometry::distance(const Eigen::Vector3d& p) const {
  if (type == PathType::kLin) {
    const Eigen::Vector3d d = p1 - p0;
    const double L2 = d.squaredNorm();
    const double t = L2 > 0 ? std::clamp((p - p0).dot(d) / L2, 0.0, 1.0) : 0.0;
    return (p - (p0 + t * d)).norm();
  }
  const Eigen::Vector3d v = p - c;
  const double h = v.dot(n);
  const Eigen::Vector3d w = v - h * n;
  double t = std::atan2(w.dot(e2), w.dot(e1));
  if (t < 0) t += 2 * calib::kPi;
  if (t <= arc && w.norm() > 0) return std::hypot(h, w.norm() - r);
  return std::min((p - p0).norm(), (p - p1).norm());
}

/// Samples of one commanded sub-segment: at least 16 and at most `step_mm` / `step_deg`
/// apart.
int sampleCount(const PathGeometry& g, double step_mm, double step_deg) {
  const double by_length = std::ceil(g.length_mm / step_mm);
  const double by_rotation = std::ceil(g.rotation_rad * calib::kRadToDeg / step_deg);
  return static_cast<int>(std::clamp(std::max({16.0, by_length, by_rotation}), 16.0, 1e6));
}

}  // namespace accura::postproc::detail

namespace accura::postproc {

using detail::PathGeometry;

Eigen::Isometry3d interpolate(const PathSegment& segment, double s) { return PathGeometry(segment).pose(s); }
double pathLength(const PathSegment& segment) { return PathGeometry(segment).length_mm; }
double pathRotation(const PathSegment& segment) { return PathGeometry(segment).rotation_rad; }
double distanceToPath(const Eigen::Vector3d& p, const PathSegment& segment) {
  return PathGeometry(segment).distance(p);
}

double maxPathDeviation(const std::vector<Eigen::Isometry3d>& samples, const std::vector<PathSegment>& intended) {
  if (intended.empty()) throw calib::ArgumentError("maxPathDeviation: no intended segment");
  std::vector<PathGeometry> g;
  g.reserve(intended.size());
  for (const PathSegment& s : intended) g.emplace_back(s);
  double worst = 0;
  for (const Eigen::Isometry3d& T : samples) {
    double best = std::numeric_limits<double>::infinity();
    for (const PathGeometry& p : g) best = std::min(best, p.distance(T.translation()));
    worst = std::max(worst, best);
  }
  return worst;
}

}  // namespace accura::postproc
