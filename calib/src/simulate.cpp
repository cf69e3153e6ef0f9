#include "accura/calib/simulate.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <set>

#include "accura/calib/errors.h"
#include "accura/calib/kinematics.h"

namespace accura::calib {
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

const std::set<std::string> kEffects = {"none",        "geometric", "joint_compliance", "gear_periodic",
                                        "joint_scale", "backlash",  "thermal",          "unmodelled_coupling"};

std::string effectList() {
  return "none, geometric, joint_compliance, gear_periodic, joint_scale, backlash, thermal, "
         "unmodelled_coupling";
}

}  // namespace

JointCoupling defaultCoupling(const RobotModel& model) {
  const int n = model.dof();
  if (n < 2) throw ArgumentError("unmodelled_coupling needs at least 2 joints, the robot has " + std::to_string(n));
  JointCoupling c;
  c.from = std::max(0, n - 3);
  c.to = c.from + 1;
  c.ratio = model.nominal.joints[c.to].type == JointType::kRevolute ? 200e-6 : 0.05;
  return c;
}

bool SimulateOptions::IsValid(std::string* error) const {
  auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (poses < 1) return fail("poses must be >= 1, got " + std::to_string(poses));
  for (const auto& e : effects)
    if (!kEffects.count(e))
      return fail("unknown effect '" + e + "' (expected " + effectList() + ")");
  if (effects.size() > 1 && std::find(effects.begin(), effects.end(), "none") != effects.end())
    return fail("effect 'none' cannot be combined with other effects");
  if (!(noise_mm >= 0) || !(noise_deg >= 0)) return fail("noise must be >= 0");
  if (payloads_kg.empty()) return fail("payloads: expected at least one mass");
  for (double p : payloads_kg)
    if (!(p >= 0) || !std::isfinite(p)) return fail("payloads: expected masses >= 0 kg");
  if (!(limit_margin >= 0 && limit_margin < 0.5)) return fail("limit_margin must be in [0, 0.5)");
  if (!(error_scale >= 0)) return fail("error_scale must be >= 0");
  if (repeat_every < 0 || repeat_every == 1)
    return fail("repeat_every must be 0 (no repeats) or >= 2, got " + std::to_string(repeat_every));
  if (!std::isfinite(coupling.ratio)) return fail("coupling ratio must be finite");
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
  Deviations& dev = truth.deviations;
  const int n = truth.dof();
  if (effects.count("gear_periodic")) {
    const int H = dev.gear_harmonics;
    for (int i = 0; i < n; ++i) {
      if (truth.nominal.joints[i].type != JointType::kRevolute) continue;
      for (int h = 1; h <= H; ++h) {
        const double amplitude = rng.uniform(0.004, 0.012) * kDegToRad;
        const double phase = rng.uniform(0, 2 * kPi);
        dev.gear_sin[i * H + h - 1] = amplitude * std::cos(phase);
        dev.gear_cos[i * H + h - 1] = amplitude * std::sin(phase);
      }
    }
  }
  if (effects.count("joint_scale"))
    for (int i = 0; i < n; ++i) dev.joint_scale[i] = rng.sign() * rng.uniform(50e-6, 150e-6);
  if (effects.count("backlash")) {
    for (int i = 0; i < n; ++i) {
      const bool revolute = truth.nominal.joints[i].type == JointType::kRevolute;
      dev.backlash[i] = revolute ? rng.uniform(0.006, 0.016) * kDegToRad : rng.uniform(0.005, 0.015);
    }
  }
  if (effects.count("thermal")) dev.thermal_alpha_per_k = rng.uniform(15e-6, 25e-6);
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
  const bool coupled = std::find(o.effects.begin(), o.effects.end(), "unmodelled_coupling") != o.effects.end();
  const JointCoupling coupling = !coupled ? JointCoupling{} : (o.coupling.ratio != 0 ? o.coupling : defaultCoupling(truth));
  if (coupled && (coupling.from < 0 || coupling.from >= n || coupling.to < 0 || coupling.to >= n || coupling.from == coupling.to))
    throw ArgumentError("simulate: coupling joints " + std::to_string(coupling.from + 1) + " -> " +
                        std::to_string(coupling.to + 1) + " are not two different joints of the robot");
  KinematicWorkspace ws;
  for (int k = 0; k < o.poses; ++k) {
    Measurement m;
    m.line = 0;
    const bool repeat = o.repeat_every > 0 && k % o.repeat_every == o.repeat_every - 1 && !set.rows.empty();
    if (repeat) {
      const Measurement& prev = set.rows.back();
      m.q = prev.q;
      m.dir = prev.dir;
      m.context.payload_kg = prev.context.payload_kg;
    } else {
      m.q.resize(n);
      for (int i = 0; i < n; ++i) {
        const JointSpec& j = truth.nominal.joints[i];
        const double margin = o.limit_margin * (j.upper - j.lower);
        m.q[i] = rng.uniform(j.lower + margin, j.upper - margin);
      }
      m.context.payload_kg = o.payloads_kg[static_cast<size_t>(k) % o.payloads_kg.size()];
      m.dir.resize(n);
      for (int i = 0; i < n; ++i) m.dir[i] = rng.sign();
    }
    const double u = o.poses > 1 ? k / double(o.poses - 1) : 0.0;
    m.temp_c = 19.0 + 6.0 * u + 0.8 * std::sin(2 * kPi * 5.0 * u);
    m.time_s = 30.0 * k;
    m.context.temp_c = m.temp_c;
    m.context.dir = m.dir;
    Eigen::VectorXd q_real = m.q;
    if (coupled) {
      const JointSpec& from = truth.nominal.joints[coupling.from];
      const JointSpec& to = truth.nominal.joints[coupling.to];
      const double q_from = from.type == JointType::kRevolute ? m.q[coupling.from] * kDegToRad : m.q[coupling.from];
      const double shift = coupling.ratio * q_from;  // rad (revolute target) or mm
      // theta = theta0 + direction q: the real joint value moves by direction * shift
      q_real[coupling.to] += to.direction * (to.type == JointType::kRevolute ? shift * kRadToDeg : shift);
    }
    const Eigen::Isometry3d T = forwardKinematics(truth, q_real, m.context, ws);
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

}  // namespace accura::calib
