#include <algorithm>
#include <cmath>

#include "accura/calib/identify.h"
#include "accura/calib/kinematics.h"

namespace accura::calib {

void summarize(const std::vector<double>& e, double* rms, double* mean, double* max, double* p95) {
  *rms = *mean = *max = *p95 = 0;
  if (e.empty()) return;
  double s2 = 0, s1 = 0;
  for (double v : e) {
    s2 += v * v;
    s1 += v;
  }
  const double n = static_cast<double>(e.size());
  *rms = std::sqrt(s2 / n);
  *mean = s1 / n;
  std::vector<double> sorted = e;
  std::sort(sorted.begin(), sorted.end());
  *max = sorted.back();
  // nearest rank: the smallest value with at least 95% of the values at or below it
  const size_t rank = static_cast<size_t>(std::ceil(0.95 * n));
  *p95 = sorted[std::max<size_t>(rank, 1) - 1];
}

std::vector<double> positionErrors(const RobotModel& model, const MeasurementSet& data) {
  KinematicWorkspace ws;
  std::vector<double> e;
  e.reserve(data.rows.size());
  for (const Measurement& m : data.rows) {
    const Eigen::Isometry3d T = forwardKinematics(model, m.q, m.context, ws);
    e.push_back((T.translation() - m.p_world_mm).norm());
  }
  return e;
}

ErrorStats evaluate(const RobotModel& model, const MeasurementSet& data) {
  KinematicWorkspace ws;
  std::vector<double> pos, rot;
  for (const Measurement& m : data.rows) {
    const Eigen::Isometry3d T = forwardKinematics(model, m.q, m.context, ws);
    pos.push_back((T.translation() - m.p_world_mm).norm());
    if (m.has_orientation) {
      const Eigen::AngleAxisd d(m.R_world_tcp.toRotationMatrix() * T.linear().transpose());
      rot.push_back(std::abs(d.angle()) * kRadToDeg);
    }
  }
  ErrorStats s;
  s.n = static_cast<int>(pos.size());
  summarize(pos, &s.rms_mm, &s.mean_mm, &s.max_mm, &s.p95_mm);
  s.has_orientation = !rot.empty() && rot.size() == pos.size();
  if (s.has_orientation) summarize(rot, &s.rot_rms_deg, &s.rot_mean_deg, &s.rot_max_deg, &s.rot_p95_deg);
  return s;
}

}  // namespace accura::calib
