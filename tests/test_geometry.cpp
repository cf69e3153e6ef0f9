#include <gtest/gtest.h>

#include <random>

#include "accura/calib/errors.h"
#include "accura/calib/geometry.h"

namespace accura::calib {
namespace {

TEST(Geometry, AbcIsRzRyRx) {
  // A = 90 deg alone maps x to y; B = 90 alone maps x to -z; C = 90 alone maps y to z.
  const Eigen::Vector3d x = Eigen::Vector3d::UnitX(), y = Eigen::Vector3d::UnitY();
  EXPECT_TRUE((toIsometry({0, 0, 0, 90, 0, 0}).linear() * x).isApprox(Eigen::Vector3d(0, 1, 0), 1e-12));
  EXPECT_TRUE((toIsometry({0, 0, 0, 0, 90, 0}).linear() * x).isApprox(Eigen::Vector3d(0, 0, -1), 1e-12));
  EXPECT_TRUE((toIsometry({0, 0, 0, 0, 0, 90}).linear() * y).isApprox(Eigen::Vector3d(0, 0, 1), 1e-12));
}

TEST(Geometry, AbcRoundTrip) {
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> ang(-179, 179), b(-89, 89), len(-2000, 2000);
  for (int k = 0; k < 200; ++k) {
    const XyzAbc p{len(rng), len(rng), len(rng), ang(rng), b(rng), ang(rng)};
    const XyzAbc r = toXyzAbc(toIsometry(p));
    EXPECT_NEAR(r.x_mm, p.x_mm, 1e-9);
    EXPECT_NEAR(r.a_deg, p.a_deg, 1e-9);
    EXPECT_NEAR(r.b_deg, p.b_deg, 1e-9);
    EXPECT_NEAR(r.c_deg, p.c_deg, 1e-9);
  }
  // gimbal lock: the rotation survives even though the angles are not unique
  const Eigen::Isometry3d T = toIsometry({0, 0, 0, 30, 90, 20});
  EXPECT_TRUE(toIsometry(toXyzAbc(T)).linear().isApprox(T.linear(), 1e-9));
}

TEST(Geometry, ExpLogAndRightJacobian) {
  std::mt19937_64 rng(2);
  std::normal_distribution<double> n(0, 1);
  for (int k = 0; k < 50; ++k) {
    const Eigen::Vector3d r(n(rng), n(rng), n(rng));
    const Eigen::Vector3d rr = r.norm() > 3.0 ? Eigen::Vector3d(r * (3.0 / r.norm())) : r;
    EXPECT_TRUE(logSO3(expSO3(rr)).isApprox(rr, 1e-9));
    const Eigen::Matrix3d Jr = rightJacobianSO3(rr);
    for (int j = 0; j < 3; ++j) {
      const double h = 1e-6;
      const Eigen::Vector3d e = Eigen::Vector3d::Unit(j) * h;
      const Eigen::Vector3d fd = logSO3(expSO3(rr).transpose() * expSO3(rr + e)) / h;
      EXPECT_LT((fd - Jr.col(j)).norm(), 1e-5);
    }
  }
}

TEST(Geometry, ParseXyzAbcRejectsBadLists) {
  EXPECT_NO_THROW(parseXyzAbc("1,2,3", "--tool"));
  const XyzAbc p = parseXyzAbc("1, 2,3,4,5,6", "--base");
  EXPECT_DOUBLE_EQ(p.c_deg, 6);
  try {
    parseXyzAbc("1,2,x", "--base");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "--base: expected a number, found 'x'");
  }
  EXPECT_THROW(parseXyzAbc("1,2,3,4", "--base"), InputError);
}

}  // namespace
}  // namespace accura::calib
