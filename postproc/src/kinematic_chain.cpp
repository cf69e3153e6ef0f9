#include "kinematic_chain.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "accura/calib/errors.h"
#include "accura/calib/geometry.h"

namespace accura::postproc::detail {
namespace {

/// cos and sin of theta from (c0, s0) = cos and sin of theta0 when |theta - theta0| < 0.1
/// rad: the series of cos and sin of the difference up to the 10th power (next term below
/// 0.1^11 / 11! = 2.5e-19; below 0.01, to the 6th power: 0.01^7 / 7! < 2e-18); else from
/// the library.
inline void cosSinFrom(double theta, double theta0, double c0, double s0, double& c, double& s) {
  const double d = theta - theta0;
  const double ad = std::abs(d);
  if (ad < 0.01) {
    // |d| < 0.01 (the deviations, a Newton step): to the 6th power (next term < 2e-18)
    const double d2 = d * d;
    constexpr double k6 = 1.0 / 6, k20 = 1.0 / 20, k12 = 1.0 / 12, k30 = 1.0 / 30;
    const double sd = d * (1 - d2 * k6 * (1 - d2 * k20));
    const double cd = 1 - d2 * 0.5 * (1 - d2 * k12 * (1 - d2 * k30));
    c = c0 * cd - s0 * sd;
    s = s0 * cd + c0 * sd;
    return;
  }
  if (ad < 0.1) {
    const double d2 = d * d;
    // (multiplications by constant reciprocals: no division in the inner loop)
    constexpr double k6 = 1.0 / 6, k20 = 1.0 / 20, k42 = 1.0 / 42, k72 = 1.0 / 72;
    constexpr double k12 = 1.0 / 12, k30 = 1.0 / 30, k56 = 1.0 / 56, k90 = 1.0 / 90;
    const double sd = d * (1 - d2 * k6 * (1 - d2 * k20 * (1 - d2 * k42 * (1 - d2 * k72))));
    const double cd = 1 - d2 * 0.5 * (1 - d2 * k12 * (1 - d2 * k30 * (1 - d2 * k56 * (1 - d2 * k90))));
    c = c0 * cd - s0 * sd;
    s = s0 * cd + c0 * sd;
    return;
  }
  c = std::cos(theta);
  s = std::sin(theta);
}

}  // namespace

KinematicChain::KinematicChain(const RobotModel& model) {
  model.validate();
  n_ = model.dof();
  if (n_ > kMaxDof)
    throw ArgumentError("kinematic solver: at most " + std::to_string(kMaxDof) + " joints, got " +
                        std::to_string(n_));
  const Deviations& dev = model.deviations;
  harmonics_ = dev.gear_harmonics;
  links_.resize(static_cast<size_t>(n_));
  double length = 0;
  for (int i = 0; i < n_; ++i) {
    const JointSpec& j = model.nominal.joints[static_cast<size_t>(i)];
    const LinkDeviation& ld = dev.links[static_cast<size_t>(i)];
    Link& L = links_[static_cast<size_t>(i)];
    L.revolute = j.type == JointType::kRevolute;
    L.dir = j.direction;
    L.theta_c = j.theta0_deg * kDegToRad + ld.dtheta_rad;
    L.d_c = j.d_mm + ld.dd_mm;
    L.a = j.a_mm + ld.da_mm;
    const double alpha = j.alpha_deg * kDegToRad + ld.dalpha_rad;
    const double ca = std::cos(alpha), sa = std::sin(alpha);
    Eigen::Matrix3d Rx;
    Rx << 1, 0, 0, 0, ca, -sa, 0, sa, ca;
    L.M = Rx;
    L.ca = ca;
    L.sa = sa;
    if (ld.dbeta_rad != 0.0) {
      L.beta = true;
      const double cb = std::cos(ld.dbeta_rad), sb = std::sin(ld.dbeta_rad);
      Eigen::Matrix3d Ry;
      Ry << cb, 0, sb, 0, 1, 0, -sb, 0, cb;
      L.M = Rx * Ry;
    }
    L.compliance = dev.compliance[static_cast<size_t>(i)];
    L.joint_scale = dev.joint_scale[static_cast<size_t>(i)];
    L.half_backlash = 0.5 * dev.backlash[static_cast<size_t>(i)];
    if (L.half_backlash != 0.0) backlash_ = true;
    if (L.revolute) {
      for (int h = 0; h < harmonics_; ++h) {
        L.gs[static_cast<size_t>(h)] = dev.gear_sin[static_cast<size_t>(i * harmonics_ + h)];
        L.gc[static_cast<size_t>(h)] = dev.gear_cos[static_cast<size_t>(i * harmonics_ + h)];
        if (L.gs[static_cast<size_t>(h)] != 0.0 || L.gc[static_cast<size_t>(h)] != 0.0) L.gear = true;
      }
    }
    if (L.compliance != 0.0) compliant_ = true;
    if (L.joint_scale != 0.0 || L.gear) any_joint_effect_ = true;
    L.nom_theta0 = j.theta0_deg * kDegToRad;
    L.nom_d = j.d_mm;
    L.nom_a = j.a_mm;
    L.nom_ca = std::cos(j.alpha_deg * kDegToRad);
    L.nom_sa = std::sin(j.alpha_deg * kDegToRad);
    L.mass = j.mass_kg;
    L.com = j.com_mm;
    length += std::abs(j.a_mm) + std::abs(j.d_mm);
  }
  const Eigen::Isometry3d T_wb = model.T_world_base();
  R_world_base_ = T_wb.linear();
  t_world_base_ = T_wb.translation();
  T_flange_tcp_ = model.T_flange_tcp();
  length += T_flange_tcp_.translation().norm();
  length_scale_mm_ = std::max(1.0, length);
  thermal_alpha_ = dev.thermal_alpha_per_k;
  gravity_ = model.nominal.gravity_base;
  payload_com_ = model.nominal.payload_com_mm;
  bool plain = !compliant_ && !any_joint_effect_ && !backlash_ && thermal_alpha_ == 0.0;
  for (const Link& L : links_) plain = plain && L.revolute;
  if (plain) {
    std::vector<double> rho(static_cast<size_t>(n_));
    double reach = T_flange_tcp_.translation().norm();  // >= |p - o_i|, from the tool inwards
    for (int i = n_ - 1; i >= 0; --i) {
      const Link& L = links_[static_cast<size_t>(i)];
      reach += std::abs(L.a) + std::abs(L.d_c);
      rho[static_cast<size_t>(i)] = reach / length_scale_mm_;
    }
    jacobian_lipschitz_.resize(static_cast<size_t>(n_));
    for (int k = 0; k < n_; ++k) {
      const double rk = rho[static_cast<size_t>(k)];
      double sum = (k + 1) * rk * rk;
      for (int i = k + 1; i < n_; ++i) sum += 1 + rho[static_cast<size_t>(i)] * rho[static_cast<size_t>(i)];
      jacobian_lipschitz_[static_cast<size_t>(k)] = std::sqrt(sum);
    }
  }
}

void KinematicChain::gravityLoads(const double* q, double payload_kg, double* load, const ChainFrames& f) const {
  // Nominal geometry, as calib's gravityLoads: frames F_0..F_n in the base frame.
  std::array<Eigen::Matrix3d, kMaxDof + 1> R;
  std::array<Eigen::Vector3d, kMaxDof + 1> o;
  R[0].setIdentity();
  o[0].setZero();
  for (int i = 0; i < n_; ++i) {
    const Link& L = links_[static_cast<size_t>(i)];
    const size_t k = static_cast<size_t>(i);
    const double d = L.revolute ? L.nom_d : L.nom_d + L.dir * q[i];
    const double ct = f.cos_nominal[k], st = f.sin_nominal[k];
    Eigen::Matrix3d A;
    A << ct, -st * L.nom_ca, st * L.nom_sa, st, ct * L.nom_ca, -ct * L.nom_sa, 0, L.nom_sa, L.nom_ca;
    o[i + 1] = o[i] + R[i] * Eigen::Vector3d(L.nom_a * ct, L.nom_a * st, d);
    R[i + 1] = R[i] * A;
  }
  double mass = payload_kg;
  Eigen::Vector3d moment = payload_kg * (R[n_] * payload_com_ + o[n_]);
  for (int i = n_ - 1; i >= 0; --i) {
    const Link& L = links_[static_cast<size_t>(i)];
    mass += L.mass;
    moment += L.mass * (R[i + 1] * L.com + o[i + 1]);
    const Eigen::Vector3d z = R[i].col(2);
    if (L.revolute) {
      const Eigen::Vector3d r = moment - mass * o[i];
      load[i] = z.dot(r.cross(gravity_)) * 1e-3;
    } else {
      load[i] = z.dot(mass * gravity_);
    }
  }
}

void KinematicChain::evaluate(const double* q, const PoseContext& context, ChainFrames& f,
                              const ChainFrames* near) const {
  if (backlash_ && !context.dir.empty() && static_cast<int>(context.dir.size()) < n_)
    throw ArgumentError("pose context: expected " + std::to_string(n_) + " approach directions, got " +
                        std::to_string(context.dir.size()));
  std::array<double, kMaxDof> load{};
  f.nominal_valid = compliant_;
  if (compliant_) {
    // nominal angles (from the near evaluation, else from the library), then the loads
    for (int i = 0; i < n_; ++i) {
      const Link& L = links_[static_cast<size_t>(i)];
      const size_t k = static_cast<size_t>(i);
      const double th = L.revolute ? L.nom_theta0 + L.dir * q[i] * kDegToRad : L.nom_theta0;
      f.theta_nominal[k] = th;
      if (near) {
        cosSinFrom(th, near->theta_nominal[k], near->cos_nominal[k], near->sin_nominal[k], f.cos_nominal[k],
                   f.sin_nominal[k]);
      } else {
        f.cos_nominal[k] = std::cos(th);
        f.sin_nominal[k] = std::sin(th);
      }
    }
    gravityLoads(q, context.payload_kg, load.data(), f);
  }
  const double scale = thermal_alpha_ == 0.0 ? 1.0 : 1.0 + thermal_alpha_ * (context.temp_c - kThermalReferenceC);
  // the frame as plain numbers: columns x, y, z and origin o (scalar code: measurably faster
  // than 3-vector expressions here)
  double x0 = R_world_base_(0, 0), x1 = R_world_base_(1, 0), x2 = R_world_base_(2, 0);
  double y0 = R_world_base_(0, 1), y1 = R_world_base_(1, 1), y2 = R_world_base_(2, 1);
  double z0 = R_world_base_(0, 2), z1 = R_world_base_(1, 2), z2 = R_world_base_(2, 2);
  double o0 = t_world_base_.x(), o1 = t_world_base_.y(), o2 = t_world_base_.z();
  const bool effects = any_joint_effect_ || (backlash_ && !context.dir.empty());
  for (int i = 0; i < n_; ++i) {
    const Link& L = links_[static_cast<size_t>(i)];
    const size_t k = static_cast<size_t>(i);
    f.o[k] = Eigen::Vector3d(o0, o1, o2);
    f.z[k] = Eigen::Vector3d(z0, z1, z2);
    double extra = 0, rate = L.dir;
    if (effects) {
      const double qi = L.revolute ? q[i] * kDegToRad : q[i];
      if (L.joint_scale != 0.0) {
        extra += L.joint_scale * qi;
        rate += L.joint_scale;
      }
      if (L.half_backlash != 0.0 && !context.dir.empty()) extra += L.half_backlash * (context.dir[k] >= 0 ? 1.0 : -1.0);
      if (L.gear) {
        for (int h = 1; h <= harmonics_; ++h) {
          const double gs = L.gs[static_cast<size_t>(h - 1)], gc = L.gc[static_cast<size_t>(h - 1)];
          const double sh = std::sin(h * qi), ch = std::cos(h * qi);
          if (gs != 0.0) extra += gs * sh;
          if (gc != 0.0) extra += gc * ch;
          rate += h * (gs * ch - gc * sh);
        }
      }
    }
    f.rate[k] = rate;
    double theta = L.theta_c, d = L.d_c * scale;
    if (L.revolute) {
      theta += L.dir * q[i] * kDegToRad + L.compliance * load[k] + extra;
    } else {
      d += L.dir * q[i] + L.compliance * load[k] + extra;
    }
    double ct, st;
    if (compliant_) {
      // the link's angle is its nominal one plus small deviations
      cosSinFrom(theta, f.theta_nominal[k], f.cos_nominal[k], f.sin_nominal[k], ct, st);
    } else if (near) {
      cosSinFrom(theta, near->theta[k], near->cos_theta[k], near->sin_theta[k], ct, st);
    } else {
      ct = std::cos(theta);
      st = std::sin(theta);
    }
    f.theta[k] = theta;
    f.cos_theta[k] = ct;
    f.sin_theta[k] = st;
    // R Rz(theta): x' = c x + s y, y' = -s x + c y
    const double xa = ct * x0 + st * y0, xb = ct * x1 + st * y1, xc = ct * x2 + st * y2;
    const double ya = ct * y0 - st * x0, yb = ct * y1 - st * x1, yc = ct * y2 - st * x2;
    const double a = L.a * scale;
    o0 += a * xa + d * z0;
    o1 += a * xb + d * z1;
    o2 += a * xc + d * z2;
    if (L.beta) {
      // (R Rz) M
      const Eigen::Matrix3d& M = L.M;
      const double n00 = xa * M(0, 0) + ya * M(1, 0) + z0 * M(2, 0), n01 = xa * M(0, 1) + ya * M(1, 1) + z0 * M(2, 1),
                   n02 = xa * M(0, 2) + ya * M(1, 2) + z0 * M(2, 2);
      const double n10 = xb * M(0, 0) + yb * M(1, 0) + z1 * M(2, 0), n11 = xb * M(0, 1) + yb * M(1, 1) + z1 * M(2, 1),
                   n12 = xb * M(0, 2) + yb * M(1, 2) + z1 * M(2, 2);
      const double n20 = xc * M(0, 0) + yc * M(1, 0) + z2 * M(2, 0), n21 = xc * M(0, 1) + yc * M(1, 1) + z2 * M(2, 1),
                   n22 = xc * M(0, 2) + yc * M(1, 2) + z2 * M(2, 2);
      x0 = n00; x1 = n10; x2 = n20;
      y0 = n01; y1 = n11; y2 = n21;
      z0 = n02; z1 = n12; z2 = n22;
    } else {
      // (R Rz) Rx(alpha): y'' = ca y' + sa z, z'' = -sa y' + ca z
      const double ca = L.ca, sa = L.sa;
      const double za = ca * z0 - sa * ya, zb = ca * z1 - sa * yb, zc = ca * z2 - sa * yc;
      y0 = ca * ya + sa * z0;
      y1 = ca * yb + sa * z1;
      y2 = ca * yc + sa * z2;
      x0 = xa; x1 = xb; x2 = xc;
      z0 = za; z1 = zb; z2 = zc;
    }
  }
  Eigen::Matrix3d R;
  R << x0, y0, z0, x1, y1, z1, x2, y2, z2;
  f.T_world_tcp.linear().noalias() = R * T_flange_tcp_.linear();
  f.T_world_tcp.translation() = Eigen::Vector3d(o0, o1, o2) + R * T_flange_tcp_.translation();
  f.T_world_tcp.makeAffine();
}

void KinematicChain::fillNominal(const double* q, ChainFrames& f, int count) const {
  if (f.nominal_valid) return;
  for (int i = 0; i < std::min(count, n_); ++i) {
    const Link& L = links_[static_cast<size_t>(i)];
    const size_t k = static_cast<size_t>(i);
    const double th = L.revolute ? L.nom_theta0 + L.dir * q[i] * kDegToRad : L.nom_theta0;
    f.theta_nominal[k] = th;
    cosSinFrom(th, f.theta[k], f.cos_theta[k], f.sin_theta[k], f.cos_nominal[k], f.sin_nominal[k]);
  }
  f.nominal_valid = count >= n_;
}

void KinematicChain::jacobian(const ChainFrames& f, Jac6N& J) const {
  J.resize(6, n_);
  const Eigen::Vector3d p = f.T_world_tcp.translation();
  for (int i = 0; i < n_; ++i) {
    const Link& L = links_[static_cast<size_t>(i)];
    const Eigen::Vector3d& z = f.z[static_cast<size_t>(i)];
    const double rate = f.rate[static_cast<size_t>(i)];
    if (L.revolute) {
      const double k = rate * kDegToRad;
      J.col(i).head<3>() = z.cross(p - f.o[static_cast<size_t>(i)]) * k;
      J.col(i).tail<3>() = z * k;
    } else {
      J.col(i).head<3>() = z * rate;
      J.col(i).tail<3>().setZero();
    }
  }
}

}  // namespace accura::postproc::detail
