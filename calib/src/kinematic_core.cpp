// The kinematic core: the one forward kinematics of the complete model (see kinematic_core.h).
#include "accura/calib/kinematic_core.h"

#include <algorithm>
#include <cmath>

#include <string>

#include "accura/calib/errors.h"
#include "accura/calib/joint_map.h"
#include "accura/calib/geometry.h"
#include "accura/calib/kinematics.h"

namespace accura::calib {
namespace {

/// sin and cos of x (rad) together, inline: the reduction by pi/2 in three parts (Cody-Waite,
/// exact for |x| < 2^19 rad) and fdlibm's minimax polynomials on [-pi/4, pi/4] (error below
/// 1e-16 absolute; compared with the library in tests/test_effects.cpp); beyond 1e5 rad the
/// library. About a third of the library's sincos on the FK's six angles.
inline void fastSinCos(double x, double& s, double& c) {
  if (!(std::abs(x) < 1e5)) {
    s = std::sin(x);
    c = std::cos(x);
    return;
  }
  constexpr double kInvPio2 = 6.36619772367581382433e-01;
  constexpr double kPio2_1 = 1.57079632673412561417e+00;   // first 33 bits of pi/2
  constexpr double kPio2_2 = 6.07710050630396597660e-11;   // next 33 bits
  constexpr double kPio2_2t = 2.02226624879595063154e-21;  // pi/2 - kPio2_1 - kPio2_2
  // the nearest integer (1.5 * 2^52: the addition rounds away the fraction; no libm call)
  constexpr double kRound = 6755399441055744.0;
  const double n = (x * kInvPio2 + kRound) - kRound;
  const double r = ((x - n * kPio2_1) - n * kPio2_2) - n * kPio2_2t;
  const double z = r * r;
  // fdlibm __kernel_sin / __kernel_cos
  constexpr double S1 = -1.66666666666666324348e-01, S2 = 8.33333333332248946124e-03,
                   S3 = -1.98412698298579493134e-04, S4 = 2.75573137070700676789e-06,
                   S5 = -2.50507602534068634195e-08, S6 = 1.58969099521155010221e-10;
  constexpr double C1 = 4.16666666666666019037e-02, C2 = -1.38888888888741095749e-03,
                   C3 = 2.48015872894767294178e-05, C4 = -2.75573143513906633035e-07,
                   C5 = 2.08757232129817482790e-09, C6 = -1.13596475577881948265e-11;
  // Estrin's scheme (shorter dependency chains than Horner's; the same polynomials)
  const double z2 = z * z, z4 = z2 * z2;
  const double ps = (S1 + z * S2) + z2 * (S3 + z * S4) + z4 * (S5 + z * S6);
  const double pc = (C1 + z * C2) + z2 * (C3 + z * C4) + z4 * (C5 + z * C6);
  const double sr = r + r * z * ps;
  const double cz = z * pc;
  const double cr = 1.0 - (0.5 * z - z * cz);
  // quadrant q = n mod 4 without branches (the angles are random: a branch mispredicts):
  // (s, c) = (sr, cr), (cr, -sr), (-sr, -cr), (-cr, sr)
  const long long quadrant = static_cast<long long>(n) & 3;
  const double v[2] = {sr, cr};
  const int swap = static_cast<int>(quadrant & 1);
  s = v[swap] * (1.0 - static_cast<double>(quadrant & 2));
  c = v[swap ^ 1] * (1.0 - static_cast<double>((quadrant + 1) & 2));
}

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
  fastSinCos(theta, s, c);
}

/// Link k's angle theta with its cosine and sine into f: from the nearby evaluation `near`
/// (the angle-addition series) when there is one, else computed.
inline void setLinkAngle(KinematicFrames& f, size_t k, double theta, const KinematicFrames* near) {
  double ct, st;
  if (near) {
    cosSinFrom(theta, near->theta[k], near->cos_theta[k], near->sin_theta[k], ct, st);
  } else {
    fastSinCos(theta, st, ct);
  }
  f.theta[k] = theta;
  f.cos_theta[k] = ct;
  f.sin_theta[k] = st;
}

/// The joint-space effects of the catalogue (docs/diagnosis.md) on link L at joint value
/// `qi` (rad for a revolute joint, mm for a prismatic one; `q` the same value as the
/// controller reads it: deg or mm) with approach direction `dir`
/// (+1 / -1; 0 when unknown): returns the term added to theta_i (rad) or d_i (mm), and adds
/// its derivative with respect to qi to `rate`. Every joint-space effect is written here
/// once (its table in KinematicModel::Link; its parameter columns in parameterJacobian).
inline double jointEffects(const KinematicModel::Link& L, int harmonics, double qi, double q, double dir,
                           double& rate) {
  double t = 0;
  // joint_scale: k_i q_i
  if (L.joint_scale != 0.0) {
    t += L.joint_scale * qi;
    rate += L.joint_scale;
  }
  // backlash: (b_i / 2) dir_i
  if (L.half_backlash != 0.0) t += L.half_backlash * dir;
  // gear_periodic: sum_h s_h sin(h q_i) + c_h cos(h q_i)
  if (L.gear) {
    for (int h = 1; h <= harmonics; ++h) {
      const double gs = L.gs[static_cast<size_t>(h - 1)], gc = L.gc[static_cast<size_t>(h - 1)];
      double sh, ch;
      fastSinCos(h * qi, sh, ch);
      t += gs * sh + gc * ch;
      rate += h * (gs * ch - gc * sh);
    }
  }
  // joint_map: m_i(q) over the covered range (joint_map.h); its slope is per deg (revolute)
  if (!L.map.empty()) {
    double slope = 0;
    t += jointMapValue(L.map, q, &slope);
    rate += L.revolute ? slope * kRadToDeg : slope;
  }
  return t;
}

}  // namespace

KinematicModel::KinematicModel(const RobotModel& model) {
  model.validate();
  n_ = model.dof();
  if (n_ > kMaxDof)
    throw ArgumentError("kinematic model: at most " + std::to_string(kMaxDof) + " joints, got " +
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
    if (!dev.joint_map.empty()) L.map = dev.joint_map[static_cast<size_t>(i)];
    L.any_effect = L.joint_scale != 0.0 || L.half_backlash != 0.0 || L.gear || !L.map.empty();
    if (L.compliance != 0.0) compliant_ = true;
    if (L.joint_scale != 0.0 || L.gear || !L.map.empty()) any_joint_effect_ = true;
    L.nom_theta0 = j.theta0_deg * kDegToRad;
    L.nom_d = j.d_mm;
    L.nom_a = j.a_mm;
    L.nom_ca = std::cos(j.alpha_deg * kDegToRad);
    L.nom_sa = std::sin(j.alpha_deg * kDegToRad);
    L.mass = j.mass_kg;
    L.com = j.com_mm;
    length += std::abs(j.a_mm) + std::abs(j.d_mm);
  }
  T_world_base_ = model.T_world_base();
  R_world_base_ = T_world_base_.linear();
  t_world_base_ = T_world_base_.translation();
  T_flange_tcp_ = model.T_flange_tcp();
  R_world_basenom_ = model.nominal.T_world_base.linear();
  R_flange_toolnom_ = model.nominal.T_flange_tcp.linear();
  Jr_base_ = rightJacobianSO3(dev.base_rot_rad);
  Jr_tool_ = rightJacobianSO3(dev.tool_rot_rad);
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

void KinematicModel::gravityLoads(const double* q, double payload_kg, double* load, const KinematicFrames& f) const {
  // Nominal geometry: frames F_0..F_n in the base frame; from the tip inwards the total mass
  // and first moment (kg*mm) of links i..n and the payload.
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
      // sum m_j (c_j - o) x g, in N*mm -> N*m
      const Eigen::Vector3d r = moment - mass * o[i];
      load[i] = z.dot(r.cross(gravity_)) * 1e-3;
    } else {
      load[i] = z.dot(mass * gravity_);
    }
  }
}

void KinematicModel::evaluate(const double* q, const PoseContext& context, KinematicFrames& f,
                              const KinematicFrames* near, LinkFrames* links, bool need_loads) const {
  if (backlash_ && !context.dir.empty() && static_cast<int>(context.dir.size()) < n_)
    throw ArgumentError("pose context: expected " + std::to_string(n_) + " approach directions, got " +
                        std::to_string(context.dir.size()));
  // The plain chain (no compliance, joint-space effect, backlash or thermal scale, every
  // joint revolute: the geometric model the IK, the controller and most identifications use)
  // is the one whose Jacobian bound the constructor computed: the same computation as below
  // without its tests per link.
  const bool plain = !jacobian_lipschitz_.empty();
  if (plain && !(links && need_loads)) {
    f.nominal_valid = false;
    std::array<double, kMaxDof> d_link;
    for (int i = 0; i < n_; ++i) {
      const Link& L = links_[static_cast<size_t>(i)];
      const size_t k = static_cast<size_t>(i);
      f.rate[k] = L.dir;
      d_link[k] = L.d_c;
      setLinkAngle(f, k, L.theta_c + L.dir * q[i] * kDegToRad, near);
    }
    if (links) {
      std::fill(links->load.begin(), links->load.begin() + n_, 0.0);
      chain<true>(f, d_link.data(), 1.0, links);
    } else {
      chain<false>(f, d_link.data(), 1.0, nullptr);
    }
    return;
  }
  std::array<double, kMaxDof> load_local{};
  double* load = links ? links->load.data() : load_local.data();
  f.nominal_valid = compliant_;
  const bool loads = compliant_ || (need_loads && links);
  if (loads) {
    // nominal angles (from the near evaluation, else from the library), then the loads
    for (int i = 0; i < n_; ++i) {
      const Link& L = links_[static_cast<size_t>(i)];
      const size_t k = static_cast<size_t>(i);
      const double th = L.revolute ? L.nom_theta0 + L.dir * q[i] * kDegToRad : L.nom_theta0;
      f.theta_nominal[k] = th;
      if (near && near->nominal_valid) {
        cosSinFrom(th, near->theta_nominal[k], near->cos_nominal[k], near->sin_nominal[k], f.cos_nominal[k],
                   f.sin_nominal[k]);
      } else {
        fastSinCos(th, f.sin_nominal[k], f.cos_nominal[k]);
      }
    }
    f.nominal_valid = true;
    gravityLoads(q, context.payload_kg, load, f);
  } else if (links) {
    std::fill(links->load.begin(), links->load.begin() + n_, 0.0);
  }
  const double scale = thermal_alpha_ == 0.0 ? 1.0 : 1.0 + thermal_alpha_ * (context.temp_c - kThermalReferenceC);
  // the frame as plain numbers: columns x, y, z and origin o (scalar code: measurably faster
  // than 3-vector expressions here)
  const bool effects = any_joint_effect_ || (backlash_ && !context.dir.empty());
  // 1. the link angles and lengths with their cosines and sines (independent of each other:
  //    the processor overlaps them), 2. the frames along the chain
  std::array<double, kMaxDof> d_link;
  for (int i = 0; i < n_; ++i) {
    const Link& L = links_[static_cast<size_t>(i)];
    const size_t k = static_cast<size_t>(i);
    double extra = 0, rate = L.dir;
    if (effects && L.any_effect) {
      const double qi = L.revolute ? q[i] * kDegToRad : q[i];
      const double dir = context.dir.empty() ? 0.0 : (context.dir[k] >= 0 ? 1.0 : -1.0);
      extra = jointEffects(L, harmonics_, qi, q[i], dir, rate);
    }
    f.rate[k] = rate;
    double theta = L.theta_c, d = L.d_c * scale;
    if (L.revolute) {
      theta += L.dir * q[i] * kDegToRad + L.compliance * load[k] + extra;
    } else {
      d += L.dir * q[i] + L.compliance * load[k] + extra;
    }
    d_link[k] = d;
    if (loads) {
      // the link's angle is its nominal one plus small deviations
      double ct, st;
      cosSinFrom(theta, f.theta_nominal[k], f.cos_nominal[k], f.sin_nominal[k], ct, st);
      f.theta[k] = theta;
      f.cos_theta[k] = ct;
      f.sin_theta[k] = st;
    } else {
      setLinkAngle(f, k, theta, near);
    }
  }
  if (links) {
    chain<true>(f, d_link.data(), scale, links);
  } else {
    chain<false>(f, d_link.data(), scale, nullptr);
  }
}

template <bool kLinks>
void KinematicModel::chain(KinematicFrames& f, const double* d_link, double scale, LinkFrames* links) const {
  // the frame as plain numbers: columns x, y, z and origin o (scalar code: measurably faster
  // than 3-vector expressions here). With links, the chain runs in the base frame (the frames
  // LinkFrames keeps) and is carried to the world at the end; else in the world from the start.
  double x0 = 1, x1 = 0, x2 = 0, y0 = 0, y1 = 1, y2 = 0, z0 = 0, z1 = 0, z2 = 1, o0 = 0, o1 = 0, o2 = 0;
  if constexpr (!kLinks) {
    x0 = R_world_base_(0, 0), x1 = R_world_base_(1, 0), x2 = R_world_base_(2, 0);
    y0 = R_world_base_(0, 1), y1 = R_world_base_(1, 1), y2 = R_world_base_(2, 1);
    z0 = R_world_base_(0, 2), z1 = R_world_base_(1, 2), z2 = R_world_base_(2, 2);
    o0 = t_world_base_.x(), o1 = t_world_base_.y(), o2 = t_world_base_.z();
  }
  for (int i = 0; i < n_; ++i) {
    const Link& L = links_[static_cast<size_t>(i)];
    const size_t k = static_cast<size_t>(i);
    f.o[k] = Eigen::Vector3d(o0, o1, o2);
    f.z[k] = Eigen::Vector3d(z0, z1, z2);
    if constexpr (kLinks) {
      Eigen::Isometry3d& T = links->T_base_frame[k];
      T.linear() << x0, y0, z0, x1, y1, z1, x2, y2, z2;
      T.translation() = Eigen::Vector3d(o0, o1, o2);
      T.makeAffine();
    }
    const double ct = f.cos_theta[k], st = f.sin_theta[k], d = d_link[k];
    [[maybe_unused]] const double theta = f.theta[k];
    // R Rz(theta): x' = c x + s y, y' = -s x + c y
    const double xa = ct * x0 + st * y0, xb = ct * x1 + st * y1, xc = ct * x2 + st * y2;
    const double ya = ct * y0 - st * x0, yb = ct * y1 - st * x1, yc = ct * y2 - st * x2;
    const double a = L.a * scale;
    o0 += a * xa + d * z0;
    o1 += a * xb + d * z1;
    o2 += a * xc + d * z2;
    if constexpr (kLinks) {
      links->x_after_theta[k] = Eigen::Vector3d(xa, xb, xc);
      links->y_after_alpha[k] =
          Eigen::Vector3d(L.ca * ya + L.sa * z0, L.ca * yb + L.sa * z1, L.ca * yc + L.sa * z2);
      links->theta_rad[k] = theta;
      links->d_mm[k] = d;
    }
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
  if constexpr (kLinks) {
    Eigen::Isometry3d& T = links->T_base_frame[static_cast<size_t>(n_)];
    T.linear() = R;
    T.translation() = Eigen::Vector3d(o0, o1, o2);
    T.makeAffine();
    // to the world: T_world_tcp = T_world_base T_base_flange T_flange_tcp, the axes too
    f.T_world_tcp = (T_world_base_ * T) * T_flange_tcp_;
    for (int i = 0; i < n_; ++i) {
      const size_t k = static_cast<size_t>(i);
      f.o[k] = R_world_base_ * f.o[k] + t_world_base_;
      f.z[k] = R_world_base_ * f.z[k];
    }
    return;
  }
  f.T_world_tcp.linear().noalias() = R * T_flange_tcp_.linear();
  f.T_world_tcp.translation() = Eigen::Vector3d(o0, o1, o2) + R * T_flange_tcp_.translation();
  f.T_world_tcp.makeAffine();
}

void KinematicModel::fillNominal(const double* q, KinematicFrames& f, int count) const {
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

void KinematicModel::jacobian(const KinematicFrames& f, Jac6N& J) const {
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

Eigen::Isometry3d KinematicModel::parameterJacobian(const std::vector<ParamInfo>& layout, const double* q,
                                                    const PoseContext& context, KinematicFrames& f,
                                                    LinkFrames& lf, Eigen::MatrixXd& J) const {
  bool compliance_columns = false;
  for (const ParamInfo& P : layout) compliance_columns = compliance_columns || P.kind == ParamKind::kCompliance;
  evaluate(q, context, f, nullptr, &lf, compliance_columns);
  const Eigen::Isometry3d& T_w_tcp = f.T_world_tcp;
  const Eigen::Vector3d p = T_w_tcp.translation();
  const double scale = thermal_alpha_ == 0.0 ? 1.0 : 1.0 + thermal_alpha_ * (context.temp_c - kThermalReferenceC);

  J.setZero(6, static_cast<Eigen::Index>(layout.size()));
  // Each column is the small motion of one intermediate frame carried to the tool: a
  // translation along unit axis u adds u to dp; a rotation about u through point o adds
  // u x (p_tcp - o) to dp and u to dphi.
  auto translation = [&](Eigen::Index col, const Eigen::Vector3d& u) { J.col(col).head<3>() = u; };
  auto rotation = [&](Eigen::Index col, const Eigen::Vector3d& u, const Eigen::Vector3d& o) {
    J.col(col).head<3>() = u.cross(p - o);
    J.col(col).tail<3>() = u;
  };
  for (size_t k = 0; k < layout.size(); ++k) {
    const ParamInfo& P = layout[k];
    const Eigen::Index col = static_cast<Eigen::Index>(k);
    switch (P.kind) {
      case ParamKind::kBaseX:
      case ParamKind::kBaseY:
      case ParamKind::kBaseZ:
        translation(col, R_world_basenom_.col(static_cast<int>(P.kind) - static_cast<int>(ParamKind::kBaseX)));
        continue;
      case ParamKind::kBaseRx:
      case ParamKind::kBaseRy:
      case ParamKind::kBaseRz: {
        const int a = static_cast<int>(P.kind) - static_cast<int>(ParamKind::kBaseRx);
        rotation(col, R_world_base_ * Jr_base_.col(a), t_world_base_);
        continue;
      }
      case ParamKind::kToolX:
      case ParamKind::kToolY:
      case ParamKind::kToolZ:
        translation(col, R_world_base_ * (lf.T_base_frame[static_cast<size_t>(n_)].linear() *
                                          R_flange_toolnom_.col(static_cast<int>(P.kind) -
                                                                static_cast<int>(ParamKind::kToolX))));
        continue;
      case ParamKind::kToolRx:
      case ParamKind::kToolRy:
      case ParamKind::kToolRz: {
        const int a = static_cast<int>(P.kind) - static_cast<int>(ParamKind::kToolRx);
        rotation(col, T_w_tcp.linear() * Jr_tool_.col(a), p);
        continue;
      }
      case ParamKind::kThermal: {
        // d/d alpha: every link length moves by (temp_c - T_ref) times its value
        const double dT = context.temp_c - kThermalReferenceC;
        Eigen::Vector3d u = Eigen::Vector3d::Zero();
        for (int i = 0; i < n_; ++i) {
          const Link& L = links_[static_cast<size_t>(i)];
          u += L.a * lf.x_after_theta[static_cast<size_t>(i)];
          u += L.d_c * lf.T_base_frame[static_cast<size_t>(i)].linear().col(2);
        }
        translation(col, dT * (R_world_base_ * u));
        continue;
      }
      default:
        break;
    }
    const int i = P.joint;
    if (i < 0 || i >= n_)
      throw ArgumentError("parameterJacobian: parameter " + P.name + " has no joint of this robot");
    const size_t ki = static_cast<size_t>(i);
    const Link& L = links_[ki];
    const Eigen::Vector3d& z0 = f.z[ki];
    const Eigen::Vector3d& o0 = f.o[ki];
    const Eigen::Vector3d x1 = R_world_base_ * lf.x_after_theta[ki];
    // origin after Rz(theta) Tz(d) Tx(a): the origin of frame i+1
    const Eigen::Vector3d o2 = T_world_base_ * lf.T_base_frame[ki + 1].translation();
    // the joint's own motion: rotation about z0 through o0, or translation along z0
    auto jointMotion = [&](double factor) {
      if (L.revolute) rotation(col, z0, o0); else translation(col, z0);
      J.col(col) *= factor;
    };
    const double q_joint = L.revolute ? q[i] * kDegToRad : q[i];
    switch (P.kind) {
      case ParamKind::kOffset:
      case ParamKind::kTheta:
        rotation(col, z0, o0);
        break;
      case ParamKind::kD:
        translation(col, scale * z0);
        break;
      case ParamKind::kA:
        translation(col, scale * x1);
        break;
      case ParamKind::kAlpha:
        rotation(col, x1, o2);
        break;
      case ParamKind::kBeta:
        rotation(col, R_world_base_ * lf.y_after_alpha[ki], o2);
        break;
      case ParamKind::kCompliance:
        jointMotion(lf.load[ki]);
        break;
      case ParamKind::kGearSin:
        jointMotion(std::sin(P.harmonic * q_joint));
        break;
      case ParamKind::kGearCos:
        jointMotion(std::cos(P.harmonic * q_joint));
        break;
      case ParamKind::kJointScale:
        jointMotion(q_joint);
        break;
      case ParamKind::kJointMap:
        jointMotion(jointMapBasisValue(L.map, q[i], P.index));
        break;
      case ParamKind::kBacklash: {
        if (!context.dir.empty() && static_cast<int>(context.dir.size()) <= i)
          throw ArgumentError("pose context: expected " + std::to_string(i + 1) +
                              " or more approach directions, got " + std::to_string(context.dir.size()));
        const double dir = context.dir.empty() ? 0.0 : (context.dir[ki] >= 0 ? 1.0 : -1.0);
        jointMotion(0.5 * dir);
        break;
      }
      default:
        throw ArgumentError("parameterJacobian: unexpected parameter " + P.name);
    }
  }
  return T_w_tcp;
}

}  // namespace accura::calib
