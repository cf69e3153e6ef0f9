#include "accura/calib/simulate.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <set>

#include "accura/calib/errors.h"
#include "accura/calib/kinematics.h"

namespace accura {
namespace {

// Portable random numbers: mt19937_64 is specified bit for bit by the standard; the
// distributions are not, so they are written here (same numbers on every platform).
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : gen_(seed) {}
  double uniform() { return double(gen_() >> 11) * (1.0 / 9007199254740992.0); }  // [0,1)
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  double normal() {  // Box-Muller
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    double u1 = uniform();
    while (u1 <= 1e-300) u1 = uniform();
    const double u2 = uniform();
    const double r = std::sqrt(-2.0 * std::log(u1));
    spare_ = r * std::sin(2 * kPi * u2);
    has_spare_ = true;
    return r * std::cos(2 * kPi * u2);
  }
  int sign() { return (gen_() >> 63) ? 1 : -1; }

 private:
  std::mt19937_64 gen_;
  bool has_spare_ = false;
  double spare_ = 0;
};

const std::set<std::string> kEffects = {"none", "geometric", "joint_compliance"};

}  // namespace

bool SimulateOptions::IsValid(std::string* error) const {
  auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (poses < 1) return fail("poses must be >= 1, got " + std::to_string(poses));
  for (const auto& e : effects)
    if (!kEffects.count(e))
      return fail("unknown effect '" + e + "' (expected none, geometric, joint_compliance)");
  if (effects.size() > 1 && std::find(effects.begin(), effects.end(), "none") != effects.end())
    return fail("effect 'none' cannot be combined with other effects");
  if (!(noise_mm >= 0) || !(noise_deg >= 0)) return fail("noise must be >= 0");
  if (payloads_kg.empty()) return fail("payloads: expected at least one mass");
  for (double p : payloads_kg)
    if (!(p >= 0) || !std::isfinite(p)) return fail("payloads: expected masses >= 0 kg");
  if (!(limit_margin >= 0 && limit_margin < 0.5)) return fail("limit_margin must be in [0, 0.5)");
  if (!(error_scale >= 0)) return fail("error_scale must be >= 0");
  return true;
}

RobotModel perturbModel(const RobotModel& nominal, const SimulateOptions& o) {
  std::string why;
  if (!o.IsValid(&why)) throw ArgumentError("simulate: " + why);
  RobotModel truth = nominal;
  Rng rng(o.seed * 7919 + 17);
  const std::set<std::string> effects(o.effects.begin(), o.effects.end());
  if (o.set_station) {
    const Eigen::Isometry3d D = nominal.nominal.T_world_base.inverse() * toIsometry(o.station);
    truth.deviations.base_mm = D.translation();
    truth.deviations.base_rot_rad = logSO3(D.linear());
  }
  if (o.set_tool) truth.nominal.T_flange_tcp = toIsometry(o.tool);
  if (effects.count("geometric")) {
    for (const ParamInfo& p : parameterLayout(truth)) {
      const bool angle = p.unit == "deg";
      double sigma = 0;
      if (p.group == "tool") sigma = angle ? 0.03 * kDegToRad : 0.3;
      if (p.group == "offsets" || p.group == "lengths" || p.group == "angles")
        sigma = angle ? 0.03 * kDegToRad : 0.3;
      if (sigma > 0)
        setParameter(truth.deviations, p, getParameter(truth.deviations, p) + o.error_scale * sigma * rng.normal());
    }
  }
  if (effects.count("joint_compliance")) {
    for (int i = 0; i < truth.dof(); ++i) {
      const bool revolute = truth.nominal.joints[i].type == JointType::kRevolute;
      if (revolute) {
        truth.deviations.compliance[i] = i < 3 ? rng.uniform(0.5e-6, 1.5e-6) : rng.uniform(2e-6, 6e-6);
      } else {
        truth.deviations.compliance[i] = rng.uniform(0.5e-3, 1.5e-3);
      }
    }
  }
  return truth;
}

MeasurementSet simulateMeasurements(const RobotModel& truth, const SimulateOptions& o) {
  std::string why;
  if (!o.IsValid(&why)) throw ArgumentError("simulate: " + why);
  Rng rng(o.seed);
  const int n = truth.dof();
  MeasurementSet set;
  set.file = "simulated";
  set.has_orientation = o.orientation;
  set.has_std_position = o.write_std;
  set.has_std_orientation = o.write_std && o.orientation;
  set.has_payload = set.has_temperature = set.has_direction = set.has_time = true;
  KinematicWorkspace ws;
  for (int k = 0; k < o.poses; ++k) {
    Measurement m;
    m.line = 0;
    m.q.resize(n);
    for (int i = 0; i < n; ++i) {
      const JointSpec& j = truth.nominal.joints[i];
      const double margin = o.limit_margin * (j.upper - j.lower);
      m.q[i] = rng.uniform(j.lower + margin, j.upper - margin);
    }
    m.context.payload_kg = o.payloads_kg[static_cast<size_t>(k) % o.payloads_kg.size()];
    m.temp_c = 20.0 + 2.0 * std::sin(2 * kPi * k / double(o.poses));
    m.time_s = 30.0 * k;
    m.dir.resize(n);
    for (int i = 0; i < n; ++i) m.dir[i] = rng.sign();
    const Eigen::Isometry3d T = forwardKinematics(truth, m.q, m.context, ws);
    const Eigen::Vector3d noise(rng.normal(), rng.normal(), rng.normal());
    m.p_world_mm = T.translation() + o.noise_mm * noise;
    if (o.orientation) {
      const Eigen::Vector3d w(rng.normal(), rng.normal(), rng.normal());
      m.has_orientation = true;
      m.R_world_tcp = Eigen::Quaterniond(expSO3(o.noise_deg * kDegToRad * w) * T.linear());
      m.R_world_tcp.normalize();
    }
    if (o.write_std) {
      m.std_mm.setConstant(std::max(o.noise_mm, 1e-6));
      if (o.orientation) m.std_rot_deg.setConstant(std::max(o.noise_deg, 1e-6));
    }
    set.rows.push_back(m);
  }
  return set;
}

}  // namespace accura
