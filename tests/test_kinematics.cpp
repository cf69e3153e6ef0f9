// Forward kinematics against an independent DH product, Hayati = DH at nominal, the analytic
// parameter Jacobian and joint Jacobian against finite differences, gravity loads against
// the derivative of the potential energy.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <random>

#include "accura/calib/errors.h"
#include "accura/calib/kinematics.h"
#include "test_util.h"

namespace accura::calib {
namespace {

// Independent, hand-written classic DH product for the KUKA KR 16 (FreeCAD kr_16.csv).
Eigen::Matrix4d dh(double theta_deg, double d, double a, double alpha_deg) {
  const double t = theta_deg * kPi / 180, al = alpha_deg * kPi / 180;
  Eigen::Matrix4d A;
  A << std::cos(t), -std::sin(t) * std::cos(al), std::sin(t) * std::sin(al), a * std::cos(t),
      std::sin(t), std::cos(t) * std::cos(al), -std::cos(t) * std::sin(al), a * std::sin(t),
      0, std::sin(al), std::cos(al), d,
      0, 0, 0, 1;
  return A;
}

Eigen::Matrix4d kr16ByHand(const double q[6]) {
  const double a[6] = {260, 680, -35, 0, 0, 0};
  const double alpha[6] = {-90, 0, 90, -90, 90, 180};
  const double d[6] = {675, 0, 0, -670, 0, -158};
  const double theta0[6] = {0, 0, -90, 0, 0, 180};
  const double dir[6] = {-1, 1, 1, 1, 1, 1};
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  for (int i = 0; i < 6; ++i) T = T * dh(theta0[i] + dir[i] * q[i], d[i], a[i], alpha[i]);
  return T;
}

TEST(Kinematics, Kr16MatchesHandWrittenDhProduct) {
  const RobotModel m = test::loadBundled("kuka_kr16");
  const double poses[6][6] = {{0, 0, 0, 0, 0, 0},
                              {0, -90, 90, 0, 0, 0},
                              {30, -60, 45, 90, -45, 120},
                              {-150, -120, 140, -300, 100, -200},
                              {170, 20, -100, 10, 125, 340},
                              {-45, -10, 10, 200, -120, 5}};
  for (const auto& q : poses) {
    const Eigen::Matrix4d expected = kr16ByHand(q);
    const Eigen::Isometry3d got = forwardKinematics(m, Eigen::Map<const Eigen::VectorXd>(q, 6));
    const double diff = (got.matrix() - expected).topRows(3).cwiseAbs().maxCoeff();
    EXPECT_LT(diff, 1e-9)
        << "q = " << Eigen::Map<const Eigen::VectorXd>(q, 6).transpose();
  }
  // q = 0: arm stretched forward (x = 260 + 680 + 670 + 158, z = 675 - (-35)... = 640)
  const Eigen::Isometry3d home = forwardKinematics(m, Eigen::VectorXd::Zero(6));
  EXPECT_NEAR(home.translation().x(), 1768.0, 1e-9);
  EXPECT_NEAR(home.translation().y(), 0.0, 1e-9);
  EXPECT_NEAR(home.translation().z(), 640.0, 1e-9);
}

TEST(Kinematics, Ur10ZeroPoseIsTheKnownOne) {
  const RobotModel m = test::loadBundled("ur10");
  const Eigen::Vector3d p = forwardKinematics(m, Eigen::VectorXd::Zero(6)).translation();
  // x = a2 + a3, y = -(d4 + d6), z = d1 - d5 (Universal Robots' DH)
  EXPECT_NEAR(p.x(), -612.0 - 572.3, 1e-9);
  EXPECT_NEAR(p.y(), -(163.941 + 92.2), 1e-9);
  EXPECT_NEAR(p.z(), 127.3 - 115.7, 1e-9);
}

TEST(Kinematics, WrongJointCountIsAnArgumentError) {
  const RobotModel m = test::loadBundled("kuka_kr16");
  try {
    forwardKinematics(m, Eigen::VectorXd::Zero(5));
    FAIL() << "expected ArgumentError";
  } catch (const ArgumentError& e) {
    EXPECT_STREQ(e.what(), "expected 6 joint values, got 5");
  }
}

TEST(Kinematics, HayatiFormEqualsDhAtNominal) {
  std::mt19937_64 rng(3);
  for (const char* name : {"kuka_kr16", "ur10", "scara", "abb_irb120"}) {
    const RobotModel autoForm = test::loadBundled(name);
    const RobotModel dhForm = test::loadBundled(name, FormPolicy::kDHOnly);
    int hayati = 0;
    for (LinkForm f : autoForm.forms) hayati += f == LinkForm::kHayati;
    EXPECT_GT(hayati, 0) << name << " has parallel axes, so some link must use the Hayati form";
    for (int k = 0; k < 20; ++k) {
      const Eigen::VectorXd q = test::randomQ(autoForm, rng);
      const Eigen::Matrix4d a = forwardKinematics(autoForm, q).matrix();
      const Eigen::Matrix4d b = forwardKinematics(dhForm, q).matrix();
      EXPECT_LT((a - b).cwiseAbs().maxCoeff(), 1e-9) << name;
    }
  }
}

// Sets every parameter of the layout to a random value of realistic size.
void randomDeviations(RobotModel& m, std::mt19937_64& rng) {
  std::normal_distribution<double> n(0, 1);
  for (const ParamInfo& p : parameterLayout(m)) {
    if (p.group != "base" && p.group != "tool" && p.group != "offsets" && p.group != "lengths" &&
        p.group != "angles" && p.group != "joint_compliance")
      continue;
    double s = p.unit == "deg" ? 0.05 * kDegToRad : 0.5;
    if (p.group == "base" && p.unit == "mm") s = 1000;
    if (p.group == "base" && p.unit == "deg") s = 0.5;  // rad: large base rotation
    if (p.group == "tool" && p.unit == "mm") s = 100;
    if (p.kind == ParamKind::kCompliance) s = p.unit == "urad/Nm" ? 2e-6 : 1e-3;
    setParameter(m.deviations, p, s * n(rng));
  }
}

TEST(Kinematics, ParameterJacobianMatchesCentralDifferences) {
  std::mt19937_64 rng(11);
  for (const char* name : {"kuka_kr16", "ur10", "scara", "abb_irb120"}) {
    for (FormPolicy policy : {FormPolicy::kAuto, FormPolicy::kDHOnly}) {
      RobotModel m = test::loadBundled(name, policy);
      randomDeviations(m, rng);
      // the geometric model and compliance (the effect catalogue has its own test, with
      // steps suited to its units: test_effects.cpp)
      std::vector<ParamInfo> layout;
      for (const ParamInfo& p : parameterLayout(m))
        if (p.group == "base" || p.group == "tool" || p.group == "offsets" || p.group == "lengths" ||
            p.group == "angles" || p.group == "joint_compliance")
          layout.push_back(p);
      KinematicWorkspace ws;
      PoseContext ctx;
      ctx.payload_kg = 7.5;
      for (int trial = 0; trial < 5; ++trial) {
        const Eigen::VectorXd q = test::randomQ(m, rng);
        Eigen::MatrixXd J;
        const Eigen::Isometry3d T0 = parameterJacobian(m, layout, q, ctx, ws, J);
        EXPECT_LT((T0.matrix() - forwardKinematics(m, q, ctx, ws).matrix()).cwiseAbs().maxCoeff(), 1e-9);
        for (size_t k = 0; k < layout.size(); ++k) {
          const double x0 = getParameter(m.deviations, layout[k]);
          // compliance: a step of 1e-6 rad (or mm) in the deflection it causes
          const double load = std::max(1.0, std::abs(gravityLoads(m, q, ctx)[std::max(0, layout[k].joint)]));
          const double h = layout[k].kind == ParamKind::kCompliance ? 1e-6 / load
                                                                    : (layout[k].unit == "mm" ? 1e-4 : 1e-7);
          RobotModel mp = m, mm = m;
          setParameter(mp.deviations, layout[k], x0 + h);
          setParameter(mm.deviations, layout[k], x0 - h);
          const Eigen::Isometry3d Tp = forwardKinematics(mp, q, ctx, ws);
          const Eigen::Isometry3d Tm = forwardKinematics(mm, q, ctx, ws);
          Vector6d fd;
          fd.head<3>() = (Tp.translation() - Tm.translation()) / (2 * h);
          fd.tail<3>() = logSO3(Tp.linear() * Tm.linear().transpose()) / (2 * h);
          const double scale = std::max(1.0, fd.norm());
          EXPECT_LT((J.col(static_cast<Eigen::Index>(k)) - fd).norm() / scale, 1e-6)
              << name << " " << layout[k].name << "\nanalytic " << J.col(static_cast<Eigen::Index>(k)).transpose()
              << "\nnumeric  " << fd.transpose();
        }
      }
    }
  }
}

TEST(Kinematics, JointJacobianMatchesCentralDifferences) {
  std::mt19937_64 rng(5);
  for (const char* name : {"kuka_kr16", "scara"}) {
    RobotModel m = test::loadBundled(name);
    randomDeviations(m, rng);
    for (auto& c : m.deviations.compliance) c = 0;  // jointJacobian neglects compliance
    KinematicWorkspace ws;
    const Eigen::VectorXd q = test::randomQ(m, rng);
    const auto Jq = jointJacobian(m, q, PoseContext{}, ws);
    for (int i = 0; i < m.dof(); ++i) {
      const double h = 1e-5;
      Eigen::VectorXd qp = q, qm = q;
      qp[i] += h;
      qm[i] -= h;
      const Eigen::Isometry3d Tp = forwardKinematics(m, qp), Tm = forwardKinematics(m, qm);
      Vector6d fd;
      fd.head<3>() = (Tp.translation() - Tm.translation()) / (2 * h);
      fd.tail<3>() = logSO3(Tp.linear() * Tm.linear().transpose()) / (2 * h);
      EXPECT_LT((Jq.col(i) - fd).norm() / std::max(1.0, fd.norm()), 1e-6) << name << " joint " << i + 1;
    }
  }
}

// tau_i = -dV/dtheta_i with V = -sum m_j g . c_j (N*m): an independent check of the loads.
TEST(Kinematics, GravityLoadsAreMinusTheGradientOfPotentialEnergy) {
  std::mt19937_64 rng(8);
  for (const char* name : {"kuka_kr16", "ur10", "scara"}) {
    const RobotModel m = test::loadBundled(name);
    PoseContext ctx;
    ctx.payload_kg = 12;
    auto potential = [&](const Eigen::VectorXd& q) {
      // frames of the nominal robot
      KinematicWorkspace ws;
      RobotModel nominal = RobotModel::fromDefinition(m.nominal);
      flangePose(nominal, q, ctx, ws);
      double V = 0;
      const Eigen::Vector3d g = m.nominal.gravity_base;
      for (int j = 0; j < m.dof(); ++j)
        V -= m.nominal.joints[j].mass_kg * g.dot(ws.T_base_frame[j + 1] * m.nominal.joints[j].com_mm) * 1e-3;
      V -= ctx.payload_kg * g.dot(ws.T_base_frame.back() * m.nominal.payload_com_mm) * 1e-3;
      return V;  // J (mm -> m)
    };
    for (int trial = 0; trial < 5; ++trial) {
      const Eigen::VectorXd q = test::randomQ(m, rng);
      const Eigen::VectorXd tau = gravityLoads(m, q, ctx);
      for (int i = 0; i < m.dof(); ++i) {
        const bool revolute = m.nominal.joints[i].type == JointType::kRevolute;
        // derivative with respect to theta_i (rad) / d_i (m): q_i = theta_i / direction
        const double h = revolute ? 1e-4 : 1e-3;  // deg or mm
        Eigen::VectorXd qp = q, qm = q;
        qp[i] += h;
        qm[i] -= h;
        const double dVdq = (potential(qp) - potential(qm)) / (2 * h);
        const double per = revolute ? kDegToRad : 1e-3;  // dtheta/dq (rad/deg) or dd/dq (m/mm)
        const double expected = -dVdq / (per * m.nominal.joints[i].direction);
        const double tol = revolute ? 1e-6 * std::max(1.0, std::abs(expected)) : 1e-3 * std::max(1.0, std::abs(expected));
        // prismatic loads are in N with d in mm: -dV/dd(m) = force (N)
        EXPECT_NEAR(tau[i], expected, tol) << name << " joint " << i + 1;
      }
    }
  }
}

}  // namespace
}  // namespace accura::calib
