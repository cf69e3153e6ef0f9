// Inverse kinematics of the complete model (calib/src/ik.cpp, on the kinematic core): the closed forms, KUKA Status/Turn, round trips FK -> IK (cold and warm) on three
// robots, every branch, and the cases that must be reported instead of solved.
#include <gtest/gtest.h>

#include <limits>

#include <Eigen/Dense>
#include <cmath>
#include <random>
#include <map>
#include <set>

#include "accura/calib/errors.h"
#include "accura/calib/geometry.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/simulate.h"
#include "accura/postproc/compensate.h"
#include "accura/calib/ik.h"
#include "accura/calib/kinematic_core.h"
#include "../calib/src/ik_internal.h"
#include "../calib/src/small_linalg.h"
#include "test_util.h"

namespace accura {
namespace {


/// A "real" robot: every geometric error, joint compliance, the base 3 m away (tracker
/// station) and a tool.
calib::RobotModel realModel(const std::string& name, std::uint64_t seed = 7) {
  calib::RobotModel m = test::loadBundled(name);
  calib::SimulateOptions o;
  o.effects = {"geometric", "joint_compliance"};
  o.seed = seed;
  o.tool = {60, -20, 180, 0, 0, 0};
  o.set_tool = true;
  return calib::perturbModel(m, o);
}

/// The nominal robot with a base and a tool that are not the identity.
calib::RobotModel nominalModel(const std::string& name) {
  calib::RobotModel m = test::loadBundled(name);
  m.nominal.T_world_base = calib::toIsometry({500, -300, 100, 20, 0.5, -0.3});
  m.nominal.T_flange_tcp = calib::toIsometry({60, -20, 180, 10, -5, 0});
  return m;
}

Eigen::VectorXd randomJoints(const calib::RobotModel& m, std::mt19937& rng, double margin = 0.02) {
  std::uniform_real_distribution<double> u(0, 1);
  Eigen::VectorXd q(m.dof());
  for (int i = 0; i < m.dof(); ++i) {
    const calib::JointSpec& j = m.nominal.joints[static_cast<size_t>(i)];
    q[i] = j.lower + (margin + (1 - 2 * margin) * u(rng)) * (j.upper - j.lower);
  }
  return q;
}

double positionError(const calib::RobotModel& m, const Eigen::VectorXd& q, const Eigen::Isometry3d& T, double payload = 0) {
  calib::KinematicWorkspace ws;
  calib::PoseContext c;
  c.payload_kg = payload;
  return (calib::forwardKinematics(m, q, c, ws).translation() - T.translation()).norm();
}

double rotationError(const calib::RobotModel& m, const Eigen::VectorXd& q, const Eigen::Isometry3d& T) {
  calib::KinematicWorkspace ws;
  return calib::logSO3(calib::forwardKinematics(m, q, calib::PoseContext{}, ws).linear() * T.linear().transpose()).norm();
}

/// Smallest singular value of the scaled Jacobian (independent of the solver: calib's
/// jointJacobian, Eigen's SVD). Same scaling as IkOptions::singular_threshold.
double scaledSigmaMin(const calib::RobotModel& m, const Eigen::VectorXd& q) {
  calib::KinematicWorkspace ws;
  Eigen::MatrixXd J = calib::jointJacobian(m, q, calib::PoseContext{}, ws);
  double L = 0;
  for (const calib::JointSpec& j : m.nominal.joints) L += std::abs(j.a_mm) + std::abs(j.d_mm);
  L += m.T_flange_tcp().translation().norm();
  J.topRows(3) /= L;
  J *= calib::kRadToDeg;
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(J);
  return svd.singularValues().minCoeff();
}

// ---------------------------------------------------------------------------------------

TEST(IkChain, ForwardAndJacobianEqualCalibWithEveryEffect) {
  std::mt19937 rng(11);
  for (const std::string name : {"kuka_kr16", "ur10", "scara", "abb_irb120"}) {
    calib::RobotModel m = realModel(name);
    // every effect of the catalogue, non-zero
    calib::Deviations& d = m.deviations;
    for (int i = 0; i < m.dof(); ++i) {
      d.joint_scale[static_cast<size_t>(i)] = 2e-4 * (i + 1);
      d.backlash[static_cast<size_t>(i)] = 1e-4 * (i + 1);
      for (int h = 0; h < d.gear_harmonics; ++h) {
        d.gear_sin[static_cast<size_t>(i * d.gear_harmonics + h)] = 3e-5 * (h + 1);
        d.gear_cos[static_cast<size_t>(i * d.gear_harmonics + h)] = -2e-5 * (i + 1);
      }
    }
    if (m.nominal.joints[2].type == calib::JointType::kPrismatic) {
      d.gear_sin[static_cast<size_t>(2 * d.gear_harmonics)] = 0;  // revolute joints only
    }
    d.thermal_alpha_per_k = 11e-6;
    const calib::KinematicSolver solver(m);
    for (int k = 0; k < 20; ++k) {
      const Eigen::VectorXd q = randomJoints(m, rng);
      calib::PoseContext c;
      c.payload_kg = 5.0 * (k % 3);
      c.temp_c = 15.0 + k;
      if (k % 2) c.dir.assign(static_cast<size_t>(m.dof()), k % 4 == 1 ? 1 : -1);
      calib::KinematicWorkspace ws;
      const Eigen::Isometry3d T_calib = calib::forwardKinematics(m, q, c, ws);
      const Eigen::Isometry3d T = solver.forward(q, c);
      EXPECT_LT((T.translation() - T_calib.translation()).norm(), 1e-9) << name;
      EXPECT_LT((T.linear() - T_calib.linear()).norm(), 1e-12) << name;
      Eigen::Matrix<double, 6, Eigen::Dynamic> J;
      solver.jacobian(q, c, J);
      const Eigen::MatrixXd J_calib = calib::jointJacobian(m, q, c, ws);
      EXPECT_LT((J - J_calib).norm(), 1e-9 * J_calib.norm()) << name;
    }
  }
}

TEST(IkChain, JacobianMatchesFiniteDifferences) {
  // without compliance the joint Jacobian is the exact derivative of the pose
  calib::RobotModel m = realModel("kuka_kr16");
  std::fill(m.deviations.compliance.begin(), m.deviations.compliance.end(), 0.0);
  m.deviations.joint_scale[1] = 3e-4;
  m.deviations.gear_sin[4] = 2e-4;
  const calib::KinematicSolver solver(m);
  std::mt19937 rng(5);
  for (int k = 0; k < 10; ++k) {
    const Eigen::VectorXd q = randomJoints(m, rng);
    Eigen::Matrix<double, 6, Eigen::Dynamic> J;
    const Eigen::Isometry3d T = solver.jacobian(q, calib::PoseContext{}, J);
    const double h = 1e-5;  // deg
    for (int i = 0; i < m.dof(); ++i) {
      Eigen::VectorXd qp = q, qm = q;
      qp[i] += h;
      qm[i] -= h;
      const Eigen::Isometry3d Tp = solver.forward(qp), Tm = solver.forward(qm);
      const Eigen::Vector3d dp = (Tp.translation() - Tm.translation()) / (2 * h);
      const Eigen::Vector3d dr = calib::logSO3(Tp.linear() * Tm.linear().transpose()) / (2 * h);
      EXPECT_LT((dp - J.col(i).head<3>()).norm(), 1e-6 * (1 + dp.norm())) << "joint " << i;
      EXPECT_LT((dr - J.col(i).tail<3>()).norm(), 1e-9) << "joint " << i;
    }
    (void)T;
  }
}

TEST(IkChain, SmallLinearAlgebraEqualsEigen) {
  std::mt19937 rng(3);
  std::normal_distribution<double> g(0, 1);
  int blocks = 0;  // solved in 3x3 blocks (random Gaussian blocks are mostly well conditioned)
  for (int k = 0; k < 50; ++k) {
    Eigen::Matrix<double, 6, 6> A;
    for (int i = 0; i < 36; ++i) A.data()[i] = g(rng);
    Eigen::Matrix<double, 6, 1> b;
    for (int i = 0; i < 6; ++i) b[i] = g(rng);
    calib::detail::Lu6 lu;
    ASSERT_TRUE(lu.factor(A));
    const Eigen::Matrix<double, 6, 1> x = lu.solve(b);
    const Eigen::Matrix<double, 6, 1> x_eigen = A.fullPivLu().solve(b);
    EXPECT_LT((x - x_eigen).norm(), 1e-9 * (1 + x_eigen.norm()));
    calib::detail::Block6 block;
    if (block.factor(A.data())) {
      ++blocks;
      EXPECT_LT((block.solve(b) - x_eigen).norm(), 1e-9 * (1 + x_eigen.norm()));
    }
    // positive definite: A A^T - t^2 I with t below / above the smallest singular value
    const double smin = Eigen::JacobiSVD<Eigen::MatrixXd>(Eigen::MatrixXd(A)).singularValues().minCoeff();
    Eigen::Matrix<double, 6, 6> G = A * A.transpose();
    Eigen::Matrix<double, 6, 6> below = G, above = G;
    below.diagonal().array() -= 0.9 * smin * 0.9 * smin;
    above.diagonal().array() -= 1.1 * smin * 1.1 * smin;
    EXPECT_TRUE(calib::detail::positiveDefinite6(below));
    EXPECT_FALSE(calib::detail::positiveDefinite6(above));
  }
  Eigen::Matrix<double, 6, 6> S = Eigen::Matrix<double, 6, 6>::Identity();
  S.row(3) = S.row(2);
  calib::detail::Lu6 lu;
  EXPECT_FALSE(lu.factor(S));
  EXPECT_GT(blocks, 30);
}

TEST(IkChain, PositiveDefiniteTestsAgreeNearTheBoundary) {
  // positiveDefinite6 (Sylvester's criterion in 3x3 blocks where it is far from the boundary,
  // else the L D L^T) against the singular values: A with prescribed singular values (one or
  // two small: near one singularity or two at once; columns of very different size as a
  // scaled Jacobian's may be), G = A^T A - t^2 I with t 0.1 % below / above the smallest
  // (independent truth: the SVD of A)
  std::mt19937 rng(11);
  std::normal_distribution<double> g(0, 1);
  std::uniform_real_distribution<double> u(-3, 0);
  int cases = 0;
  for (int k = 0; k < 3000; ++k) {
    Eigen::Matrix<double, 6, 6> M;
    for (int i = 0; i < 36; ++i) M.data()[i] = g(rng);
    const Eigen::JacobiSVD<Eigen::Matrix<double, 6, 6>> base(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix<double, 6, 1> s;
    for (int i = 0; i < 6; ++i) s[i] = std::pow(10.0, u(rng) / 3);  // 0.1 .. 1
    if (k % 3 == 1) s[5] = std::pow(10.0, u(rng) - 2);  // 1e-5 .. 1e-2
    if (k % 3 == 2) s.tail<2>() << std::pow(10.0, u(rng) - 1), std::pow(10.0, u(rng) - 2);
    Eigen::Matrix<double, 6, 6> A = base.matrixU() * s.asDiagonal() * base.matrixV().transpose();
    for (int c = 0; c < 6; ++c) A.col(c) *= std::pow(10.0, u(rng) / 3);  // column scaling 0.1 .. 1
    const double smin = Eigen::JacobiSVD<Eigen::Matrix<double, 6, 6>>(A).singularValues().minCoeff();
    const Eigen::Matrix<double, 6, 6> G = A.transpose() * A;
    for (const double f : {0.999, 1.001, 0.5, 2.0}) {
      Eigen::Matrix<double, 6, 6> H = G;
      H.diagonal().array() -= f * smin * f * smin;
      const bool pd = calib::detail::positiveDefinite6(H);
      EXPECT_EQ(pd, f < 1) << "case " << k << " smin " << smin << " factor " << f;
      EXPECT_EQ(pd, calib::detail::positiveDefiniteLdl6(H)) << "case " << k << " factor " << f;
      ++cases;
    }
  }
  EXPECT_EQ(cases, 12000);
  // NaN and non-positive diagonals: not positive definite
  Eigen::Matrix<double, 6, 6> N = Eigen::Matrix<double, 6, 6>::Identity();
  N(3, 1) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(calib::detail::positiveDefinite6(N));
  N.setIdentity();
  N(4, 4) = 0;
  EXPECT_FALSE(calib::detail::positiveDefinite6(N));
  N.setIdentity();
  N(5, 2) = 1.5;  // |G'(5, 2)| > 1
  EXPECT_FALSE(calib::detail::positiveDefinite6(N));
}

TEST(IkChain, TheDeterminantBoundsTheSmallestSingularValueFromBelow) {
  // sigmaMinLowerBound (|det Js| (5 / |Js|_F^2)^(5/2) from the block factorisation) never
  // exceeds the scaled Jacobian's smallest singular value (independent: the SVD that
  // minSingularValue takes), at random joints of the 6-axis bundled robots, near their wrist
  // singularity too; and it is not vacuous away from singularities
  for (const char* name : {"kuka_kr16", "ur10", "abb_irb120"}) {
    const calib::RobotModel m = realModel(name);
    calib::KinematicSolver::Impl impl(m);
    std::mt19937 rng(21);
    int tight = 0, factored = 0;
    for (int k = 0; k < 400; ++k) {
      Eigen::VectorXd q(6);
      for (int i = 0; i < 6; ++i) {
        const calib::JointSpec& j = m.nominal.joints[static_cast<size_t>(i)];
        q[i] = std::uniform_real_distribution<double>(j.lower, j.upper)(rng);
      }
      if (k % 4 == 0) q[4] = std::uniform_real_distribution<double>(-0.5, 0.5)(rng);  // next to A5 = 0
      calib::KinematicFrames f;
      impl.chain.evaluate(q.data(), {}, f);
      calib::Jac6N J;
      impl.chain.jacobian(f, J);
      calib::detail::Block6 block;
      if (!block.factor(J.data())) continue;
      ++factored;
      const double bound = impl.sigmaMinLowerBound(J, block);
      const double smin = impl.minSingularValue(J);
      EXPECT_LE(bound, smin * (1 + 1e-12)) << name << " case " << k;
      EXPECT_GT(bound, 0) << name << " case " << k;
      tight += bound > 0.05 * smin;
    }
    EXPECT_GT(factored, 200) << name;
    EXPECT_GT(tight, factored / 2) << name;  // within a factor 20 of sigma_min mostly
  }
}

TEST(IkChain, PoseErrorEqualsTheLogarithm) {
  // Newton's error: the translation difference and the rotation vector of R_target R^T, from
  // the columns and a series below 5.7 deg; independent: calib's logSO3 of the product
  std::mt19937 rng(6);
  std::normal_distribution<double> g(0, 1);
  for (int k = 0; k < 200; ++k) {
    const double angle = (k % 2 ? 1e-3 : 0.5) * std::abs(g(rng));  // rad: series and logSO3
    const Eigen::Isometry3d T = calib::toIsometry({g(rng), g(rng), g(rng), 100 * g(rng), 100 * g(rng), 100 * g(rng)});
    Eigen::Isometry3d Tt = T;
    Tt.linear() = Eigen::AngleAxisd(angle, Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized()).toRotationMatrix() *
                  T.linear();
    Tt.translation() += Eigen::Vector3d(g(rng), g(rng), g(rng));
    Eigen::Matrix<double, 6, 1> e;
    calib::KinematicSolver::Impl::poseErr(Tt, T, e);
    EXPECT_LT((e.head<3>() - (Tt.translation() - T.translation())).norm(), 1e-12);
    const Eigen::Vector3d w = calib::logSO3(Tt.linear() * T.linear().transpose());
    EXPECT_LT((e.tail<3>() - w).norm(), 1e-9 * angle + 1e-15) << angle;
  }
}

TEST(IkChain, BlockSolveRefusesIllConditionedBlocks) {
  // the bottom right block singular (a wrist singularity: two wrist axes parallel), the
  // whole matrix regular: refused
  Eigen::Matrix<double, 6, 6> W = Eigen::Matrix<double, 6, 6>::Identity();
  W(3, 5) = 1;
  W(5, 5) = 0;
  W(0, 5) = 1;
  W(5, 0) = 1;
  ASSERT_GT(std::abs(W.determinant()), 0.5);
  calib::detail::Block6 block;
  EXPECT_FALSE(block.factor(W.data()));
  // the Schur complement nearly singular (two columns nearly parallel; the whole matrix
  // regular): refused
  Eigen::Matrix<double, 6, 6> T = Eigen::Matrix<double, 6, 6>::Identity();
  T(0, 1) = 1;
  T(1, 1) = 1e-9;
  EXPECT_FALSE(block.factor(T.data()));
  // a short column alone is no ill conditioning (the ratio is per column): accepted, exact
  T = Eigen::Matrix<double, 6, 6>::Identity();
  T(2, 2) = 0.5;
  ASSERT_TRUE(block.factor(T.data()));
  const Eigen::Matrix<double, 6, 1> one = Eigen::Matrix<double, 6, 1>::Ones();
  EXPECT_NEAR(block.solve(one)[2], 2.0, 1e-15);
}

// ---------------------------------------------------------------------------------------

TEST(IkClosedForm, ExactForNominalRobots) {
  std::mt19937 rng(21);
  for (const std::string name : {"kuka_kr16", "abb_irb120", "ur10"}) {
    const calib::RobotModel m = nominalModel(name);
    const calib::KinematicSolver solver(m);
    EXPECT_STREQ(solver.closedForm(), name == "ur10" ? "three_parallel" : "spherical_wrist");
    int poses = 0;
    for (int k = 0; k < 100; ++k) {
      const Eigen::VectorXd q = randomJoints(m, rng);
      if (scaledSigmaMin(m, q) < 1e-3) continue;
      ++poses;
      const Eigen::Isometry3d T = solver.forward(q);
      const std::vector<Eigen::VectorXd> sols = solver.closedFormSolutions(T);
      bool found = false;
      std::set<int> statuses;
      for (const Eigen::VectorXd& s : sols) {
        EXPECT_LT(positionError(m, s, T), 1e-8) << name;
        EXPECT_LT(rotationError(m, s, T), 1e-11) << name;
        found = found || (s - q).cwiseAbs().maxCoeff() < 1e-7;
        statuses.insert(calib::kukaConfiguration(m, s).status);
      }
      EXPECT_TRUE(found) << name << " q = " << q.transpose();
    }
    EXPECT_GT(poses, 80) << name;
  }
}

TEST(IkClosedForm, NoneForAScara) {
  const calib::KinematicSolver solver(test::loadBundled("scara"));
  EXPECT_STREQ(solver.closedForm(), "none");
}

// ---------------------------------------------------------------------------------------

TEST(KukaConfiguration, HomeAndBitsByDefinition) {
  const calib::RobotModel m = test::loadBundled("kuka_kr16");
  Eigen::VectorXd home(6);
  home << 0, -90, 90, 0, 0, 0;
  // KUKA's usual home: basic area, A3 above the stretched angle, A5 = 0 (not negative);
  // Turn: only A2 negative. Programs carry S 'B010' T 'B000010' there.
  const calib::Configuration c = calib::kukaConfiguration(m, home);
  EXPECT_EQ(c.status, 2);
  EXPECT_EQ(c.turn, 2);
  Eigen::VectorXd q = home;
  q[4] = -30;  // A5 negative: bit 2, and Turn bit 4
  EXPECT_EQ(calib::kukaConfiguration(m, q).status, 6);
  EXPECT_EQ(calib::kukaConfiguration(m, q).turn, 2 | 16);
  q[4] = 200;  // A5 = 200 = -160 in [-180, 180): negative
  EXPECT_EQ(calib::kukaConfiguration(m, q).status & 4, 4);
  EXPECT_EQ(calib::kukaConfiguration(m, q).turn & 16, 0);
}

TEST(KukaConfiguration, MatchesAGeometricComputation) {
  // bit 0: the wrist point (DH frame 5 of calib's nominal FK) in the base turned by A1;
  // bit 1: A3 against the angle at which the origin of DH frame 4 (the wrist point on a
  // spherical wrist) is farthest from the A2 axis (a search over A3); bit 2: the sign of A5.
  std::mt19937 rng(8);
  for (const std::string name : {"kuka_kr16", "abb_irb120", "ur10"}) {
    const calib::RobotModel m = test::loadBundled(name);
    const calib::JointSpec& j1 = m.nominal.joints[0];
    calib::KinematicWorkspace ws;
    // the stretched A3: maximise |o5 - o1| over q3 (golden section on the nominal FK)
    auto reach = [&](double q3) {
      Eigen::VectorXd q = Eigen::VectorXd::Zero(6);
      q[2] = q3;
      calib::forwardKinematics(m, q, calib::PoseContext{}, ws);
      return (ws.T_base_frame[4].translation() - ws.T_base_frame[1].translation()).norm();
    };
    double a = -180, b = 180;
    // coarse scan then golden section
    double best = a;
    for (double x = -180; x < 180; x += 1)
      if (reach(x) > reach(best)) best = x;
    a = best - 1;
    b = best + 1;
    for (int it = 0; it < 100; ++it) {
      const double c1 = b - 0.618033988749895 * (b - a), c2 = a + 0.618033988749895 * (b - a);
      if (reach(c1) > reach(c2)) b = c2; else a = c1;
    }
    const double phi = 0.5 * (a + b);
    if (name == "kuka_kr16") {
      EXPECT_NEAR(phi, -std::atan2(35, 670) * calib::kRadToDeg, 1e-4);
    }
    for (int k = 0; k < 200; ++k) {
      const Eigen::VectorXd q = randomJoints(m, rng);
      calib::forwardKinematics(m, q, calib::PoseContext{}, ws);
      const Eigen::Vector3d w = ws.T_base_frame[5].translation();
      const double a1 = j1.direction * q[0] * calib::kDegToRad;  // the base turned with A1
      const double x_a1 = std::cos(a1) * w.x() + std::sin(a1) * w.y();
      if (std::abs(x_a1) < 1e-6 || std::abs(q[2] - phi) < 1e-3) continue;
      int s = 0;
      if (x_a1 < 0) s |= 1;
      double d3 = std::remainder(q[2] - phi, 360.0);
      if (d3 >= 0) s |= 2;
      if (std::remainder(q[4], 360.0) < 0) s |= 4;
      int t = 0;
      for (int i = 0; i < 6; ++i)
        if (q[i] < 0) t |= 1 << i;
      const calib::Configuration c = calib::kukaConfiguration(m, q);
      EXPECT_EQ(c.status, s) << name << " q " << q.transpose();
      EXPECT_EQ(c.turn, t) << name;
    }
  }
}

TEST(KukaConfiguration, UndefinedStatusWithoutSixRevoluteJoints) {
  const calib::RobotModel m = test::loadBundled("scara");
  Eigen::VectorXd q(4);
  q << -10, 20, 50, -30;
  const calib::Configuration c = calib::kukaConfiguration(m, q);
  EXPECT_EQ(c.status, -1);
  EXPECT_EQ(c.turn, 1 | 8);
  EXPECT_THROW(calib::kukaConfiguration(m, Eigen::VectorXd(3)), calib::ArgumentError);
}

// ---------------------------------------------------------------------------------------
// Round trips

struct RoundTripStats {
  int well_conditioned = 0, ok = 0, near_singular = 0, near_singular_ok = 0;
};

/// FK -> IK on random joints: cold (S/T of the joints asked for, no seed) and warm (seed a
/// few degrees away, any configuration). Well-conditioned targets (scaled sigma_min >= 1e-3)
/// must all be solved, to 1 um and 1 urad, on the configuration asked for and on the joints
/// they came from; near-singular ones must never give a wrong point.
RoundTripStats roundTrip(const calib::RobotModel& m, int count, std::uint64_t seed, bool warm) {
  const calib::KinematicSolver solver(m);
  std::mt19937 rng(static_cast<unsigned>(seed));
  std::uniform_real_distribution<double> u(-1, 1);
  const calib::IkOptions o;
  RoundTripStats st;
  for (int k = 0; k < count; ++k) {
    const Eigen::VectorXd q = randomJoints(m, rng);
    const Eigen::Isometry3d T = solver.forward(q);
    const calib::Configuration c = calib::kukaConfiguration(m, q);
    Eigen::VectorXd s;
    if (warm) {
      s = q;
      for (int i = 0; i < m.dof(); ++i) s[i] += 3.0 * u(rng);
    }
    const calib::IkResult r = solver.inverse(T, warm ? calib::Configuration{} : c, s, o);
    const bool well = scaledSigmaMin(m, q) >= 1e-3;
    if (r.status == calib::IkStatus::kOk) {
      // never a wrong point: checked with calib's FK, not the solver's
      EXPECT_LE(positionError(m, r.q, T), o.tol_mm);
      EXPECT_LE(rotationError(m, r.q, T), o.tol_rad * 1.0001);
      EXPECT_TRUE(calib::configurationMatches(warm ? calib::Configuration{} : c, r.configuration));
    }
    if (well) {
      ++st.well_conditioned;
      if (r.status == calib::IkStatus::kOk) {
        ++st.ok;
        if (warm) {
          // the solution nearest to the seed: at least as near as the joints the pose came
          // from (next to a singularity another branch can be nearer)
          EXPECT_LE((r.q - s).norm(), (q - s).norm() + 0.02) << "q " << q.transpose() << " got " << r.q.transpose();
        } else {
          // the joints the pose came from: S/T fix them up to 360 deg on a joint whose range
          // exceeds 360 deg without a sign change (ABB axis 6: -400..400)
          for (int i = 0; i < m.dof(); ++i)
            EXPECT_LT(std::abs(std::remainder(r.q[i] - q[i], 360.0)), 0.06)
                << "joint " << i + 1 << ": q " << q.transpose() << " got " << r.q.transpose();
        }
      } else {
        ADD_FAILURE() << toString(r.status) << ": " << r.message << " for q " << q.transpose();
      }
    } else {
      ++st.near_singular;
      if (r.status == calib::IkStatus::kOk) ++st.near_singular_ok;
      if (r.q.size()) {
        EXPECT_LE(positionError(m, r.q, T), o.tol_mm);
      }
    }
  }
  return st;
}

class IkRoundTrip : public ::testing::TestWithParam<std::string> {};

TEST_P(IkRoundTrip, ColdOnNominalAndRealModels) {
  for (const bool real : {false, true}) {
    const calib::RobotModel m = real ? realModel(GetParam()) : nominalModel(GetParam());
    const RoundTripStats st = roundTrip(m, 300, 100 + real, false);
    EXPECT_EQ(st.ok, st.well_conditioned) << GetParam() << (real ? " real" : " nominal");
    EXPECT_GT(st.well_conditioned, 250);
  }
}

TEST_P(IkRoundTrip, WarmOnNominalAndRealModels) {
  for (const bool real : {false, true}) {
    const calib::RobotModel m = real ? realModel(GetParam()) : nominalModel(GetParam());
    const RoundTripStats st = roundTrip(m, 300, 200 + real, true);
    EXPECT_EQ(st.ok, st.well_conditioned) << GetParam() << (real ? " real" : " nominal");
  }
}

INSTANTIATE_TEST_SUITE_P(Robots, IkRoundTrip, ::testing::Values("kuka_kr16", "abb_irb120", "ur10"));

TEST(Ik, WithPayloadTheCompliantModelIsSolved) {
  const calib::RobotModel m = realModel("kuka_kr16");
  const calib::KinematicSolver solver(m);
  std::mt19937 rng(9);
  calib::PoseContext c;
  c.payload_kg = 16;
  for (int k = 0; k < 30; ++k) {
    const Eigen::VectorXd q = randomJoints(m, rng, 0.1);
    if (scaledSigmaMin(m, q) < 1e-3) continue;
    const Eigen::Isometry3d T = solver.forward(q, c);
    const calib::IkResult r = solver.inverse(T, calib::kukaConfiguration(m, q), Eigen::VectorXd(), calib::IkOptions{}, c);
    ASSERT_EQ(r.status, calib::IkStatus::kOk) << r.message;
    EXPECT_LE(positionError(m, r.q, T, 16), 1e-3);
    // the same pose without the payload needs other joints (the arm sags less)
    const calib::IkResult r0 = solver.inverse(T, calib::kukaConfiguration(m, q), Eigen::VectorXd(), calib::IkOptions{});
    ASSERT_EQ(r0.status, calib::IkStatus::kOk);
    EXPECT_GT((r0.q - r.q).norm(), 1e-3);
  }
}

TEST(Ik, ScaraWithoutClosedFormByMultiStart) {
  const calib::RobotModel m = realModel("scara");
  const calib::KinematicSolver solver(m);
  std::mt19937 rng(4);
  int ok = 0;
  for (int k = 0; k < 40; ++k) {
    const Eigen::VectorXd q = randomJoints(m, rng, 0.05);
    const Eigen::Isometry3d T = solver.forward(q);
    const calib::IkResult r = solver.inverse(T, calib::Configuration{}, Eigen::VectorXd(), calib::IkOptions{});
    if (r.status == calib::IkStatus::kOk) {
      ++ok;
      EXPECT_LE(positionError(m, r.q, T), 1e-3);
      EXPECT_LE(rotationError(m, r.q, T), 1e-6);
    }
  }
  EXPECT_EQ(ok, 40);
}

TEST(Ik, WarmStartFromTheSolutionTakesNoIteration) {
  const calib::RobotModel m = realModel("kuka_kr16");
  const calib::KinematicSolver solver(m);
  Eigen::VectorXd q(6);
  q << 20, -80, 100, 30, 45, -60;
  const calib::IkResult r = solver.inverse(solver.forward(q), calib::Configuration{}, q, calib::IkOptions{});
  ASSERT_EQ(r.status, calib::IkStatus::kOk);
  EXPECT_EQ(r.iterations, 0);
  EXPECT_EQ((r.q - q).norm(), 0.0);
}

// ---------------------------------------------------------------------------------------
// Every branch

TEST(Ik, EveryStatusBranchIsReproducedOnTheRealRobot) {
  // poses where all eight Status values exist within the limits: each asked for with its
  // Turn gives the real robot's solution on that branch, distinct from the others
  const calib::RobotModel real = realModel("kuka_kr16");
  const calib::RobotModel nominal = test::loadBundled("kuka_kr16");
  const calib::KinematicSolver solver(real);
  std::mt19937 rng(12);
  int poses = 0;
  for (int k = 0; k < 4000 && poses < 3; ++k) {
    const Eigen::VectorXd q0 = randomJoints(real, rng, 0.05);
    const Eigen::Isometry3d T = solver.forward(q0);
    // the configurations that exist: from the closed form (nominal links, real base/tool)
    std::map<int, int> turn_of_status;
    bool well = true;
    for (const Eigen::VectorXd& s : solver.closedFormSolutions(T)) {
      const calib::Configuration c = calib::kukaConfiguration(nominal, s);
      if (!turn_of_status.count(c.status)) turn_of_status[c.status] = c.turn;
      well = well && scaledSigmaMin(real, s) > 1e-2;
    }
    if (turn_of_status.size() != 8 || !well) continue;
    ++poses;
    std::vector<Eigen::VectorXd> solutions;
    for (const auto& [status, turn] : turn_of_status) {
      const calib::IkResult r = solver.inverse(T, calib::Configuration{status, turn}, Eigen::VectorXd(), calib::IkOptions{});
      ASSERT_EQ(r.status, calib::IkStatus::kOk) << "S " << status << " T " << turn << ": " << r.message;
      EXPECT_EQ(r.configuration.status, status);
      EXPECT_EQ(r.configuration.turn, turn);
      EXPECT_LE(positionError(real, r.q, T), 1e-3);
      EXPECT_LE(rotationError(real, r.q, T), 1e-6);
      solutions.push_back(r.q);
    }
    for (size_t i = 0; i < solutions.size(); ++i)
      for (size_t j = i + 1; j < solutions.size(); ++j) EXPECT_GT((solutions[i] - solutions[j]).norm(), 1.0);
  }
  EXPECT_EQ(poses, 3);
}

// ---------------------------------------------------------------------------------------
// Reported, not solved

TEST(Ik, UnreachableTargetIsReported) {
  for (const std::string name : {"kuka_kr16", "ur10", "abb_irb120"}) {
    const calib::RobotModel m = realModel(name);
    const calib::KinematicSolver solver(m);
    Eigen::Isometry3d T = m.T_world_base() * calib::toIsometry({5000, 0, 500, 0, 90, 0});
    for (const Eigen::VectorXd& seed : std::vector<Eigen::VectorXd>{Eigen::VectorXd(), Eigen::VectorXd::Zero(6)}) {
      const calib::IkResult r = solver.inverse(T, calib::Configuration{}, seed, calib::IkOptions{});
      EXPECT_EQ(r.status, calib::IkStatus::kUnreachable) << name << ": " << r.message;
      EXPECT_EQ(r.q.size(), 0);
      EXPECT_FALSE(r.message.empty());
    }
  }
  // just beyond the stretched arm: 5 mm further than the real robot reaches
  const calib::RobotModel m = realModel("kuka_kr16");
  const calib::KinematicSolver solver(m);
  Eigen::VectorXd q(6);
  q << 0, -30, -2.99, 0, 60, 0;
  // stretch: search A3 for the farthest flange, then push the target outwards
  double best = -2.99, far = 0;
  for (double a3 = -4; a3 <= -2; a3 += 0.01) {
    q[2] = a3;
    const double r = (solver.forward(q).translation() - m.T_world_base().translation()).norm();
    if (r > far) {
      far = r;
      best = a3;
    }
  }
  q[2] = best;
  Eigen::Isometry3d T = solver.forward(q);
  const Eigen::Vector3d out = (T.translation() - m.T_world_base().translation()).normalized();
  T.translation() += 5 * out;
  const calib::IkResult r = solver.inverse(T, calib::Configuration{}, Eigen::VectorXd(), calib::IkOptions{});
  EXPECT_EQ(r.status, calib::IkStatus::kUnreachable) << toString(r.status) << ": " << r.message;
}

TEST(Ik, TargetBeyondTheJointLimitsIsReported) {
  calib::RobotModel m = nominalModel("kuka_kr16");
  Eigen::VectorXd q(6);
  q << 30, -70, 80, 20, 40, 10;
  const Eigen::Isometry3d T = calib::KinematicSolver(m).forward(q);
  // A1 limited to +-10 deg: both A1 solutions (30 and 30 + 180 - ...) are outside
  m.nominal.joints[0].lower = -10;
  m.nominal.joints[0].upper = 10;
  const calib::KinematicSolver solver(m);
  for (const Eigen::VectorXd& seed : std::vector<Eigen::VectorXd>{Eigen::VectorXd(), q}) {
    const calib::IkResult r = solver.inverse(T, calib::Configuration{}, seed, calib::IkOptions{});
    EXPECT_EQ(r.status, calib::IkStatus::kJointLimits) << toString(r.status) << ": " << r.message;
    EXPECT_EQ(r.q.size(), 0);
  }
  // a joint margin: A5 = 115 is within -130..130, not with 20 deg of margin: on the
  // configuration asked for there is no solution (another configuration may have one)
  const calib::RobotModel full = nominalModel("kuka_kr16");
  Eigen::VectorXd q5 = q;
  q5[4] = 115;
  const calib::KinematicSolver full_solver(full);
  const Eigen::Isometry3d T5 = full_solver.forward(q5);
  calib::IkOptions o;
  o.joint_margin = 20;
  const calib::IkResult r = full_solver.inverse(T5, calib::kukaConfiguration(full, q5), Eigen::VectorXd(), o);
  EXPECT_TRUE(r.status == calib::IkStatus::kJointLimits || r.status == calib::IkStatus::kNoConfiguration) << toString(r.status);
  if (r.q.size()) {
    EXPECT_NE(r.configuration, calib::kukaConfiguration(full, q5));
    for (int i = 0; i < 6; ++i) {
      EXPECT_GE(r.q[i], full.nominal.joints[i].lower + 20);
      EXPECT_LE(r.q[i], full.nominal.joints[i].upper - 20);
    }
  }
  // without the margin it is solved
  const calib::IkResult r0 = full_solver.inverse(T5, calib::kukaConfiguration(full, q5), Eigen::VectorXd(), calib::IkOptions{});
  EXPECT_EQ(r0.status, calib::IkStatus::kOk);
}

TEST(Ik, ConfigurationThatDoesNotExistIsReported) {
  const calib::RobotModel m = realModel("kuka_kr16");
  const calib::KinematicSolver solver(m);
  Eigen::VectorXd q(6);
  q << 100, -80, 90, 20, 40, 10;
  const Eigen::Isometry3d T = solver.forward(q);
  calib::Configuration c = calib::kukaConfiguration(m, q);
  // A1 = 100 cannot be negative within -185..185 (-260 is outside): Turn bit 0 set is
  // impossible on this branch
  c.turn |= 1;
  const calib::IkResult r = solver.inverse(T, c, Eigen::VectorXd(), calib::IkOptions{});
  EXPECT_NE(r.status, calib::IkStatus::kOk);
  if (r.q.size()) {
    EXPECT_EQ(r.status, calib::IkStatus::kNoConfiguration);
    EXPECT_FALSE(calib::configurationMatches(c, r.configuration));
    EXPECT_LE(positionError(m, r.q, T), 1e-3);  // a valid solution, on another configuration
  }
}

// The configuration a solution has instead of the one asked for is said as the arm's posture,
// which every controller's user reads (an ABB or UR program's error said only "S 6 T 25").
TEST(Ik, AConfigurationDifferenceIsSaidAsThePosture) {
  EXPECT_EQ(calib::configurationDifference({2, 2}, {2, 2}), "");
  EXPECT_EQ(calib::configurationDifference({-1, -1}, {6, 25}), "");
  EXPECT_EQ(calib::configurationDifference({2, -1}, {7, 25}),
            "the side of axis 1 the wrist point lies on (overhead area), the wrist flip (the sign of joint 5)");
  EXPECT_EQ(calib::configurationDifference({0, 0b010010}, {2, 0b000011}),
            "the elbow (joint 3 on the other side of the stretched arm), the sign of joint 1, the sign of joint 5");
  EXPECT_EQ(calib::configurationDifference({2, 2}, {-1, -1}), "the Status, the Turn");
  // with KUKA's numbers, a part left open not written (it said "T -1")
  EXPECT_EQ(calib::configurationMismatch({2, -1}, {6, 25}),
            "S 6 T 25, not with the configuration asked for (S 2): it differs in the wrist flip (the sign of joint 5)");
  EXPECT_EQ(calib::configurationMismatch({-1, 0b10}, {2, 0b11}),
            "S 2 T 3, not with the configuration asked for (T 2): it differs in the sign of joint 1");
  // in the solver's message, after KUKA's numbers (the KR 16 reached with joint 1 positive where a
  // negative one was asked for: ConfigurationThatDoesNotExistIsReported's case)
  const calib::RobotModel m = realModel("kuka_kr16");
  const calib::KinematicSolver solver(m);
  Eigen::VectorXd q(6);
  q << 100, -80, 90, 20, 40, 10;
  calib::Configuration c = calib::kukaConfiguration(m, q);
  c.turn |= 1;
  const calib::IkResult r = solver.inverse(solver.forward(q), c, Eigen::VectorXd(), calib::IkOptions{});
  ASSERT_EQ(r.status, calib::IkStatus::kNoConfiguration) << r.message;
  EXPECT_NE(r.message.find("): it differs in the sign of joint 1"), std::string::npos) << r.message;
}

TEST(Ik, SingularPosesAreReportedWithACorrectSolution) {
  for (const bool real : {false, true}) {
    const calib::RobotModel m = real ? realModel("kuka_kr16") : nominalModel("kuka_kr16");
    const calib::KinematicSolver solver(m);
    // wrist: A5 = 0 (A4 and A6 aligned); elbow: A3 at the stretched angle
    Eigen::VectorXd wrist(6), elbow(6);
    wrist << 20, -70, 80, 30, 0, 40;
    elbow << 20, -40, -std::atan2(35, 670) * calib::kRadToDeg, 30, 50, 40;
    for (const Eigen::VectorXd& q : std::vector<Eigen::VectorXd>{wrist, elbow}) {
      const Eigen::Isometry3d T = solver.forward(q);
      const calib::IkResult r = solver.inverse(T, calib::Configuration{}, Eigen::VectorXd(), calib::IkOptions{});
      if (!real) {
        EXPECT_EQ(r.status, calib::IkStatus::kSingular) << toString(r.status) << " " << r.message;
      }
      if (r.status == calib::IkStatus::kSingular) {
        EXPECT_LT(r.min_singular_value, calib::IkOptions{}.singular_threshold);
        ASSERT_EQ(r.q.size(), 6);
        EXPECT_LE(positionError(m, r.q, T), 1e-3);
      } else {
        // the real robot's singularity is elsewhere: then the point must be right
        ASSERT_EQ(r.status, calib::IkStatus::kOk) << r.message;
        EXPECT_LE(positionError(m, r.q, T), 1e-3);
      }
    }
    // next to the wrist singularity but above the threshold: solved
    Eigen::VectorXd q = wrist;
    q[4] = 3;
    const calib::IkResult r = solver.inverse(solver.forward(q), calib::kukaConfiguration(m, q), Eigen::VectorXd(), calib::IkOptions{});
    EXPECT_EQ(r.status, calib::IkStatus::kOk) << r.message;
  }
}

TEST(Ik, SingularValueGrowsWithA5) {
  // the scale the threshold refers to: sigma_min against A5 near the wrist singularity
  const calib::RobotModel m = test::loadBundled("kuka_kr16");
  calib::IkOptions o;
  o.compute_singular_value = true;
  o.singular_threshold = 0;
  const calib::KinematicSolver solver(m);
  double prev = 0;
  for (const double a5 : {0.05, 0.2, 1.0, 5.0}) {
    Eigen::VectorXd q(6);
    q << 20, -70, 80, 30, a5, 40;
    const calib::IkResult r = solver.inverse(solver.forward(q), calib::kukaConfiguration(m, q), q, o);
    ASSERT_EQ(r.status, calib::IkStatus::kOk);
    EXPECT_NEAR(r.min_singular_value, scaledSigmaMin(m, r.q), 1e-9);
    EXPECT_GT(r.min_singular_value, prev);
    prev = r.min_singular_value;
  }
}

TEST(Ik, BadArgumentsThrow) {
  const calib::KinematicSolver solver(test::loadBundled("kuka_kr16"));
  const Eigen::Isometry3d T = solver.forward(Eigen::VectorXd::Zero(6));
  EXPECT_THROW(solver.inverse(T, calib::Configuration{}, Eigen::VectorXd::Zero(5), calib::IkOptions{}), calib::ArgumentError);
  calib::IkOptions o;
  o.tol_mm = 0;
  EXPECT_THROW(solver.inverse(T, calib::Configuration{}, Eigen::VectorXd(), o), calib::ArgumentError);
  std::string why;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("tolerance"), std::string::npos);
  o = calib::IkOptions{};
  o.max_iterations = 0;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_THROW(solver.forward(Eigen::VectorXd::Zero(4)), calib::ArgumentError);
  Eigen::Isometry3d bad = T;
  bad.translation().x() = std::nan("");
  EXPECT_THROW(solver.inverse(bad, calib::Configuration{}, Eigen::VectorXd(), calib::IkOptions{}), calib::ArgumentError);
}

TEST(Ik, FreeFunctionEqualsSolver) {
  const calib::RobotModel m = realModel("abb_irb120");
  Eigen::VectorXd q(6);
  q << 10, 20, -30, 40, 50, 60;
  const Eigen::Isometry3d T = calib::KinematicSolver(m).forward(q);
  const calib::Configuration c = calib::kukaConfiguration(m, q);
  const calib::IkResult a = calib::inverseKinematics(m, T, c, Eigen::VectorXd(), calib::IkOptions{});
  const calib::IkResult b = calib::KinematicSolver(m).inverse(T, c, Eigen::VectorXd(), calib::IkOptions{});
  ASSERT_EQ(a.status, calib::IkStatus::kOk);
  EXPECT_EQ((a.q - b.q).norm(), 0.0);
  EXPECT_LT((a.q - q).cwiseAbs().maxCoeff(), 1e-3);
}

// ---------------------------------------------------------------------------------------
// IkWorkspace: path following that reuses the previous solution's frames and Jacobian, and
// the singularity certificate it carries along (KinematicModel::scaledJacobianLipschitz)

/// Joint-space path from qa to qb in `steps` steps, as Cartesian targets of model m.
std::vector<Eigen::Isometry3d> jointLineTargets(const calib::KinematicSolver& s, const Eigen::VectorXd& qa,
                                                const Eigen::VectorXd& qb, int steps) {
  std::vector<Eigen::Isometry3d> out;
  for (int i = 0; i <= steps; ++i) out.push_back(s.forward(qa + (qb - qa) * (double(i) / steps)));
  return out;
}

/// A joint-space line from qa on which A5 goes from 25 to -25 deg through the wrist
/// singularity (`steps` + 1 targets), and IK options with a singularity threshold high
/// enough that a band of points is singular.
struct WristCrossing {
  Eigen::VectorXd qa;
  std::vector<Eigen::Isometry3d> targets;
  calib::IkOptions o;
};
WristCrossing wristCrossing(const calib::KinematicSolver& s, int steps) {
  WristCrossing w;
  w.qa.resize(6);
  Eigen::VectorXd qb(6);
  w.qa << 20, -70, 80, 30, 25, 40;
  qb << 35, -60, 70, 45, -25, 60;
  w.targets = jointLineTargets(s, w.qa, qb, steps);
  w.o.singular_threshold = 0.03;
  return w;
}

/// Follows `targets` from q0, each solve seeded with the last kOk solution, with or without a
/// workspace.
std::vector<calib::IkResult> follow(const calib::KinematicSolver& s, const std::vector<Eigen::Isometry3d>& targets,
                             const Eigen::VectorXd& q0, const calib::IkOptions& o, bool workspace,
                             const calib::PoseContext& ctx = {}) {
  calib::IkWorkspace ws;
  std::vector<calib::IkResult> out;
  Eigen::VectorXd q = q0;
  for (const Eigen::Isometry3d& T : targets) {
    out.push_back(workspace ? s.inverse(T, calib::Configuration{}, q, o, ctx, ws) : s.inverse(T, calib::Configuration{}, q, o, ctx));
    if (out.back().status == calib::IkStatus::kOk) q = out.back().q;
  }
  return out;
}

TEST(IkWorkspace, PathFollowingEqualsTheStatelessSolveThroughAWristSingularity) {
  // A5 from 25 to -25 deg through the wrist singularity, 0.1 deg per step, with a threshold
  // high enough that a band of points is singular: the certificate carried in the workspace
  // must never hide one. Geometric model (the certificate's shortcut applies) and the
  // compliant one (only the frames are reused).
  calib::RobotModel geometric = test::loadBundled("kuka_kr16");
  {
    calib::SimulateOptions so;
    so.effects = {"geometric"};
    so.seed = 11;
    geometric = calib::perturbModel(geometric, so);
  }
  for (const calib::RobotModel& m : {geometric, realModel("kuka_kr16", 5)}) {
    const calib::KinematicSolver s(m);
    const WristCrossing w = wristCrossing(s, 500);
    const std::vector<Eigen::Isometry3d>& targets = w.targets;
    const calib::IkOptions& o = w.o;
    const Eigen::VectorXd& qa = w.qa;
    const std::vector<calib::IkResult> with = follow(s, targets, qa, o, true);
    const std::vector<calib::IkResult> without = follow(s, targets, qa, o, false);
    int singular = 0, ok = 0;
    for (size_t k = 0; k < targets.size(); ++k) {
      ASSERT_EQ(with[k].status, without[k].status) << k;
      if (with[k].status == calib::IkStatus::kSingular) ++singular;
      if (with[k].status != calib::IkStatus::kOk) continue;
      ++ok;
      EXPECT_LT((with[k].q - without[k].q).cwiseAbs().maxCoeff(), 1e-9) << k;
      EXPECT_EQ(with[k].configuration.status, without[k].configuration.status) << k;
      EXPECT_EQ(with[k].configuration.turn, without[k].configuration.turn) << k;
      // independent: calib's Jacobian and Eigen's SVD
      EXPECT_GT(scaledSigmaMin(m, with[k].q), o.singular_threshold * (1 - 1e-9)) << k;
      EXPECT_LE(positionError(m, with[k].q, targets[k]), 1e-3);
    }
    // every point is solved or reported singular (the band around A5 = 0)
    EXPECT_EQ(ok + singular, static_cast<int>(targets.size()));
    EXPECT_GT(singular, 5);
    EXPECT_GT(ok, 250);
  }
}

TEST(IkWorkspace, LongStepsThroughAWristSingularityEqualTheStatelessSolve) {
  // The same crossing in steps of 2.5 to 5 deg of A5: a warm solve that moves a joint more than
  // 2 deg passes a singularity test at the move (in rad) before it is taken, which answers the
  // one at the threshold and becomes the workspace's certificate. Statuses and joint values
  // equal the stateless solve's, and every solution is regular by Eigen's SVD.
  const calib::RobotModel m = test::loadBundled("kuka_kr16");
  const calib::KinematicSolver s(m);
  for (int steps : {10, 14, 20}) {
    const WristCrossing w = wristCrossing(s, steps);
    const std::vector<calib::IkResult> with = follow(s, w.targets, w.qa, w.o, true);
    const std::vector<calib::IkResult> without = follow(s, w.targets, w.qa, w.o, false);
    int ok = 0, long_steps = 0;
    for (size_t k = 0; k < w.targets.size(); ++k) {
      ASSERT_EQ(with[k].status, without[k].status) << steps << " " << k;
      if (with[k].status != calib::IkStatus::kOk) continue;
      ++ok;
      if (k > 0 && with[k - 1].status == calib::IkStatus::kOk &&
          (with[k].q - with[k - 1].q).cwiseAbs().maxCoeff() > 2.0)
        ++long_steps;
      EXPECT_LT((with[k].q - without[k].q).cwiseAbs().maxCoeff(), 1e-9) << steps << " " << k;
      EXPECT_GT(scaledSigmaMin(m, with[k].q), w.o.singular_threshold * (1 - 1e-9)) << steps << " " << k;
      EXPECT_LE(positionError(m, with[k].q, w.targets[k]), 1e-3);
    }
    // the long warm steps were taken (6, 8 and 13 of them; ok: 8 of 11, 10 of 15, 15 of 21)
    EXPECT_GE(2 * long_steps, steps) << steps;
    EXPECT_GE(3 * ok, 2 * steps) << steps;
  }
}

TEST(IkWorkspace, FollowIsTheWorkspaceSolveWritingIntoTheSeed) {
  // the same path through the wrist singularity: follow() gives the same statuses and joint
  // values as inverse(..., workspace) (the same solve, bit for bit); on failure the seed is
  // left alone and the answer says why
  const calib::RobotModel m = realModel("kuka_kr16", 5);
  const calib::KinematicSolver s(m);
  const WristCrossing w = wristCrossing(s, 200);
  const std::vector<Eigen::Isometry3d>& targets = w.targets;
  const calib::IkOptions& o = w.o;
  const std::vector<calib::IkResult> expected = follow(s, targets, w.qa, o, true);
  calib::IkWorkspace ws;
  Eigen::VectorXd q = w.qa;
  int singular = 0;
  for (size_t k = 0; k < targets.size(); ++k) {
    const Eigen::VectorXd before = q;
    calib::IkResult answer;
    const calib::IkStatus st = s.follow(targets[k], calib::Configuration{}, q, o, calib::PoseContext{}, ws, &answer);
    ASSERT_EQ(st, expected[k].status) << k;
    if (st == calib::IkStatus::kOk) {
      EXPECT_EQ((q - expected[k].q).cwiseAbs().maxCoeff(), 0.0) << k;
      EXPECT_LE(positionError(m, q, targets[k]), 1e-3);  // independent: calib's FK
    } else {
      ++singular;
      EXPECT_EQ(st, calib::IkStatus::kSingular) << k;
      EXPECT_EQ((q - before).cwiseAbs().maxCoeff(), 0.0) << k;
      EXPECT_EQ(answer.status, st);
      EXPECT_NE(answer.message.find("singular"), std::string::npos);
      EXPECT_EQ((answer.q - expected[k].q).cwiseAbs().maxCoeff(), 0.0) << k;
    }
  }
  EXPECT_GT(singular, 2);
  // cold: an empty q becomes the solution
  Eigen::VectorXd cold;
  ASSERT_EQ(s.follow(targets.front(), calib::Configuration{}, cold, calib::IkOptions{}, calib::PoseContext{}, ws),
            calib::IkStatus::kOk);
  ASSERT_EQ(cold.size(), 6);
  EXPECT_LE(positionError(m, cold, targets.front()), 1e-3);
  // a seed of the wrong size throws, as inverse() does
  Eigen::VectorXd wrong(5);
  wrong.setZero();
  EXPECT_THROW(s.follow(targets.front(), calib::Configuration{}, wrong, o, calib::PoseContext{}, ws), calib::ArgumentError);
}

TEST(IkWorkspace, NonFiniteTargetOrSeedIsRefused) {
  // each entry of the target (all 16 of the matrix) and of the seed, NaN or infinite: an
  // ArgumentError from follow() and inverse(), also while the workspace holds a solution (a
  // seed it holds, bit for bit, is a solution found and not tested again)
  const calib::RobotModel m = realModel("kuka_kr16", 5);
  const calib::KinematicSolver s(m);
  const calib::IkOptions o;
  const calib::Configuration any;
  const calib::PoseContext ctx;
  Eigen::VectorXd q(6);
  q << 10, -80, 95, 20, 40, -30;
  const Eigen::Isometry3d T = s.forward(q);
  calib::IkWorkspace ws;
  ASSERT_EQ(s.follow(T, any, q, o, ctx, ws), calib::IkStatus::kOk);  // q: the held solution
  for (const double bad : {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity(),
                           -std::numeric_limits<double>::infinity()}) {
    for (int k = 0; k < 16; ++k) {
      Eigen::Isometry3d Tb = T;
      Tb.matrix().data()[k] = bad;
      Eigen::VectorXd seed = q;
      EXPECT_THROW(s.follow(Tb, any, seed, o, ctx, ws), calib::ArgumentError) << k;
      EXPECT_THROW(s.inverse(Tb, any, q, o), calib::ArgumentError) << k;
    }
    for (int i = 0; i < 6; ++i) {
      Eigen::VectorXd seed = q;
      seed[i] = bad;
      EXPECT_THROW(s.follow(T, any, seed, o, ctx, ws), calib::ArgumentError) << i;
      EXPECT_THROW(s.inverse(T, any, seed, o, ctx, ws), calib::ArgumentError) << i;
    }
  }
  // the held solution still seeds the next solve
  ASSERT_TRUE(ws.holdsSolution());
  Eigen::VectorXd seed = q;
  ASSERT_EQ(s.follow(T, any, seed, o, ctx, ws), calib::IkStatus::kOk);
  EXPECT_LE(positionError(m, seed, T), 1e-3);  // independent: calib's FK
}

TEST(IkWorkspace, NotUsedForAnotherSolverOrContext) {
  const calib::RobotModel a = realModel("kuka_kr16", 3), b = realModel("kuka_kr16", 4);
  const calib::KinematicSolver sa(a), sb(b);
  Eigen::VectorXd q(6);
  q << 10, -80, 95, 20, 40, -30;
  calib::IkWorkspace ws;
  const calib::IkResult ra = sa.inverse(sa.forward(q), calib::Configuration{}, q, calib::IkOptions{}, calib::PoseContext{}, ws);
  ASSERT_EQ(ra.status, calib::IkStatus::kOk);
  EXPECT_TRUE(ws.holdsSolution());
  // b's target from a's solution as the seed: the stored frames are a's, not b's
  Eigen::VectorXd q2 = q;
  q2[0] += 1;
  const Eigen::Isometry3d Tb = sb.forward(q2);
  const calib::IkResult rb = sb.inverse(Tb, calib::Configuration{}, ra.q, calib::IkOptions{}, calib::PoseContext{}, ws);
  ASSERT_EQ(rb.status, calib::IkStatus::kOk);
  EXPECT_LE(positionError(b, rb.q, Tb), 1e-3);
  EXPECT_LT((rb.q - q2).cwiseAbs().maxCoeff(), 1e-4);  // deg (1 um at ~1 m: 6e-5 deg)
  // the same solver with another payload (the compliant model bends differently)
  calib::PoseContext heavy;
  heavy.payload_kg = 16;
  const calib::IkResult rh = sb.inverse(Tb, calib::Configuration{}, rb.q, calib::IkOptions{}, heavy, ws);
  ASSERT_EQ(rh.status, calib::IkStatus::kOk);
  EXPECT_LE(positionError(b, rh.q, Tb, 16), 1e-3);
  EXPECT_GT((rh.q - rb.q).cwiseAbs().maxCoeff(), 1e-4);  // the payload moved the solution
  // a failed solve clears it
  Eigen::Isometry3d far = Tb;
  far.translation() *= 10;
  EXPECT_NE(sb.inverse(far, calib::Configuration{}, rh.q, calib::IkOptions{}, heavy, ws).status, calib::IkStatus::kOk);
  EXPECT_FALSE(ws.holdsSolution());
}

TEST(IkChain, ScaledJacobianLipschitzBoundHolds) {
  // ||Js(q1) - Js(q0)||_2 <= sum_k B_k |dq_k| (rad), with Js from calib's jointJacobian; the
  // bound is what lets a path skip the singularity test, so it must hold everywhere.
  for (const char* name : {"kuka_kr16", "ur10", "abb_irb120"}) {
    calib::RobotModel m = nominalModel(name);
    calib::SimulateOptions so;
    so.effects = {"geometric"};
    so.seed = 2;
    m = calib::perturbModel(m, so);
    const calib::KinematicModel chain(m);
    const std::vector<double>& B = chain.scaledJacobianLipschitz();
    ASSERT_EQ(static_cast<int>(B.size()), m.dof()) << name;
    const double L = chain.length_scale_mm();
    auto scaledJ = [&](const Eigen::VectorXd& q) {
      calib::KinematicWorkspace ws;
      Eigen::MatrixXd J = calib::jointJacobian(m, q, calib::PoseContext{}, ws);
      J.topRows(3) /= L;
      return Eigen::MatrixXd(J * calib::kRadToDeg);
    };
    std::mt19937 rng(5);
    std::normal_distribution<double> step(0, 3);  // deg
    double tightest = 0;
    for (int k = 0; k < 300; ++k) {
      const Eigen::VectorXd q0 = randomJoints(m, rng);
      Eigen::VectorXd q1 = q0;
      double bound = 0;
      for (int i = 0; i < m.dof(); ++i) {
        q1[i] += step(rng);
        bound += B[static_cast<size_t>(i)] * std::abs(q1[i] - q0[i]) * calib::kDegToRad;
      }
      const double change = (scaledJ(q1) - scaledJ(q0)).jacobiSvd().singularValues()[0];
      EXPECT_LE(change, bound) << name << " sample " << k;
      tightest = std::max(tightest, change / bound);
    }
    EXPECT_GT(tightest, 0.1) << name;  // a bound, not a wild overestimate
  }
  // a compliant model has no such bound (its angles depend on the gravity load)
  EXPECT_TRUE(calib::KinematicModel(realModel("kuka_kr16")).scaledJacobianLipschitz().empty());
}

}  // namespace
}  // namespace accura
