// accura post-processor benchmarks: the IK of the complete model next to orocos KDL's
// ChainIkSolverPos_NR_JL (Newton-Raphson with joint limits, the pseudo-inverse velocity
// solver) on the same chain and the same targets, and the compensation throughput (points per
// second on one core). Single-threaded.
//
// The chain: a KUKA KR 16 with every geometric error of simulate.h (error scale 1, the base
// registered in the cell to 0.5 mm, a 250 mm torch), built for KDL from the same DH values
// (Rz(theta0 + dtheta) Tz(d) Tx(a) Rx(alpha) Ry(beta) per link, base and tool as fixed
// segments, metres). Joint compliance is left out of the IK comparison (KDL cannot represent a
// load-dependent joint angle); the compensation benchmarks include it. Both solvers converge to
// 1 um and 1 urad (KDL: eps = 1e-6 per twist component, in metres and radians).
//
// Targets: (a) path-following: three LIN moves across the workspace (4.4 m, 70-100 deg of
// reorientation each) every 1 mm (PathWarm) and every 20 mm (Path20Warm: program targets
// along a seam), each solve seeded with the previous solution; (b) random
// well-conditioned poses, seeded 0.5 deg per joint away from the joints they came from;
// (c) the same poses cold: accura with the Status/Turn of the joints and no seed, KDL (which
// has no notion of a configuration) from the middle of the joint ranges. A solve succeeds
// when the solver says so and the pose is within 1 um / 1 urad (checked with accura's FK,
// and for KDL also within the joint limits).
//
// accura runs with its default options, which include the singularity certificate
// (IkOptions::singular_threshold); the *_AccuraNoSingularCheck variants turn it off to do
// exactly KDL's job (converge within the limits). Path following uses the path API
// (KinematicSolver::follow with an IkWorkspace: the seed array becomes the solution, as KDL's
// CartToJnt fills its output array); *_AccuraResult is the same solve returning an IkResult,
// *_AccuraStateless the stateless inverse() from the seed alone. The run ends with the ratios of the
// side-by-side pairs (KDL time / accura time).
#include <benchmark/benchmark.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <kdl/chain.hpp>
#include <kdl/chainfksolverpos_recursive.hpp>
#include <kdl/chainiksolverpos_nr_jl.hpp>
#include <kdl/chainiksolvervel_pinv.hpp>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "accura/calib/geometry.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/robot_io.h"
#include "accura/calib/simulate.h"
#include "accura/postproc/compensate.h"

namespace {

using accura::calib::RobotModel;
using accura::postproc::Compensator;
using accura::calib::Configuration;
using accura::calib::IkOptions;
using accura::calib::IkResult;
using accura::calib::IkStatus;
using accura::calib::KinematicSolver;

constexpr double kDeg = accura::calib::kDegToRad;
// The success checks' bounds in units of 1 um / 1 urad: accura's answers, and KDL's held to
// the same bound, within 1 (+1e-4: the two FKs agree to ~1e-7 um); KDL's own criterion (eps
// per twist component) within sqrt(3) (1.8).
constexpr double kSameBound = 1.0001;
constexpr double kKdlBound = 1.8;

RobotModel controllerModel() {
  RobotModel m = accura::calib::readRobotFile(accura::calib::resolveRobotPath("kuka_kr16"));
  m.nominal.T_flange_tcp = accura::calib::toIsometry({20, 0, 250, 0, -30, 0});
  return m;
}

/// The real robot: every geometric error; `compliance` adds joint compliance.
RobotModel realModel(bool compliance) {
  accura::calib::SimulateOptions o;
  o.effects = compliance ? std::vector<std::string>{"geometric", "joint_compliance"}
                         : std::vector<std::string>{"geometric"};
  o.seed = 3;
  o.set_station = false;  // the cell frame: the robot registered in it to 0.5 mm
  RobotModel m = accura::calib::perturbModel(controllerModel(), o);
  m.deviations.base_mm = Eigen::Vector3d(0.4, -0.3, 0.2);
  m.deviations.base_rot_rad = Eigen::Vector3d(1e-4, -5e-5, 2e-4);
  return m;
}

KDL::Frame toKdl(const Eigen::Isometry3d& T) {
  const Eigen::Matrix3d& R = T.linear();
  return KDL::Frame(KDL::Rotation(R(0, 0), R(0, 1), R(0, 2), R(1, 0), R(1, 1), R(1, 2), R(2, 0), R(2, 1), R(2, 2)),
                    KDL::Vector(T.translation().x() * 1e-3, T.translation().y() * 1e-3, T.translation().z() * 1e-3));
}

/// The same chain for KDL (metres, radians).
KDL::Chain kdlChain(const RobotModel& m) {
  KDL::Chain chain;
  chain.addSegment(KDL::Segment(KDL::Joint(KDL::Joint::None), toKdl(m.T_world_base())));
  for (int i = 0; i < m.dof(); ++i) {
    const accura::calib::JointSpec& j = m.nominal.joints[static_cast<size_t>(i)];
    const accura::calib::LinkDeviation& d = m.deviations.links[static_cast<size_t>(i)];
    // KDL's joint offset does not enter Joint::pose in this version: theta0 goes into the tip
    const KDL::Frame tip = KDL::Frame(KDL::Rotation::RotZ(j.theta0_deg * kDeg + d.dtheta_rad)) *
                           KDL::Frame(KDL::Vector(0, 0, (j.d_mm + d.dd_mm) * 1e-3)) *
                           KDL::Frame(KDL::Vector((j.a_mm + d.da_mm) * 1e-3, 0, 0)) *
                           KDL::Frame(KDL::Rotation::RotX(j.alpha_deg * kDeg + d.dalpha_rad)) *
                           KDL::Frame(KDL::Rotation::RotY(d.dbeta_rad));
    chain.addSegment(KDL::Segment(KDL::Joint(KDL::Joint::RotZ, j.direction), tip));
  }
  chain.addSegment(KDL::Segment(KDL::Joint(KDL::Joint::None), toKdl(m.T_flange_tcp())));
  return chain;
}

Eigen::Isometry3d pose(double x, double y, double z, double a, double b, double c) {
  return accura::calib::toIsometry({x, y, z, a, b, c});
}

/// Everything built once: models, solvers, targets.
struct Setup {
  RobotModel controller = controllerModel();
  RobotModel real = realModel(false);
  RobotModel real_compliant = realModel(true);
  KinematicSolver solver{real};
  Compensator compensator{controller, real_compliant};
  KDL::Chain chain = kdlChain(real);
  KDL::JntArray q_min, q_max, q_mid;
  Eigen::VectorXd q_mid_deg;     ///< the middle of the joint ranges (deg): KDL's cold seed
  std::unique_ptr<KDL::ChainFkSolverPos_recursive> kdl_fk;
  std::unique_ptr<KDL::ChainIkSolverVel_pinv> kdl_vel;
  std::unique_ptr<KDL::ChainIkSolverPos_NR_JL> kdl_ik;
  /// The same solver held to accura's bound: eps = 1e-6 / sqrt(3) per twist component, so that
  /// its answers are within 1 um and 1 urad as norms, as accura's are (KDL's `eps` bounds each
  /// component: with 1e-6 a position error of up to 1.73 um is accepted).
  std::unique_ptr<KDL::ChainIkSolverPos_NR_JL> kdl_ik_bound;
  // (a) path-following: every 1 mm, and every 20 mm (program targets along a seam)
  std::vector<Eigen::Isometry3d> path, path20;
  Eigen::VectorXd path_q0;        ///< the real solution at the first point (accura, KDL)
  Eigen::VectorXd path_q0_comp;   ///< the same for the compliant model
  // (b), (c) random poses
  std::vector<Eigen::Isometry3d> targets;
  std::vector<Eigen::VectorXd> truth, nearby;
  std::vector<Configuration> configs;
  std::string error;

  Setup() {
    const int n = real.dof();
    q_min.resize(n);
    q_max.resize(n);
    q_mid.resize(n);
    q_mid_deg.resize(n);
    for (int i = 0; i < n; ++i) {
      const accura::calib::JointSpec& j = real.nominal.joints[static_cast<size_t>(i)];
      q_min(i) = j.lower * kDeg;
      q_max(i) = j.upper * kDeg;
      q_mid(i) = 0.5 * (j.lower + j.upper) * kDeg;
      q_mid_deg[i] = 0.5 * (j.lower + j.upper);
    }
    kdl_fk = std::make_unique<KDL::ChainFkSolverPos_recursive>(chain);
    kdl_vel = std::make_unique<KDL::ChainIkSolverVel_pinv>(chain);
    kdl_ik = std::make_unique<KDL::ChainIkSolverPos_NR_JL>(chain, q_min, q_max, *kdl_fk, *kdl_vel, 100, 1e-6);
    kdl_ik_bound = std::make_unique<KDL::ChainIkSolverPos_NR_JL>(chain, q_min, q_max, *kdl_fk, *kdl_vel, 100,
                                                                 1e-6 / std::sqrt(3.0));

    // the same chain: KDL's FK equals accura's at random joints
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(0.1, 0.9), v(-1, 1);
    for (int k = 0; k < 100; ++k) {
      Eigen::VectorXd q(n);
      for (int i = 0; i < n; ++i) q[i] = (q_min(i) + u(rng) * (q_max(i) - q_min(i))) / kDeg;
      KDL::Frame f;
      kdl_fk->JntToCart(toKdlJoints(q), f);
      const Eigen::Vector3d p = solver.forward(q).translation() * 1e-3;
      if ((p - Eigen::Vector3d(f.p.x(), f.p.y(), f.p.z())).norm() > 1e-10) error = "the KDL chain differs from accura's";
    }

    // (a) three LIN moves every 1 mm
    const std::vector<Eigen::Isometry3d> corners = {pose(900, -1100, 300, -30, 150, 10), pose(1000, 1000, 700, 40, 120, -20),
                                                    pose(1250, 300, 1150, 0, 110, 30), pose(700, -900, 900, -60, 170, 0)};
    for (size_t c = 0; c + 1 < corners.size(); ++c) {
      accura::postproc::PathSegment s;
      s.T_world_start = corners[c];
      s.T_world_end = corners[c + 1];
      const int m = static_cast<int>(std::ceil(accura::postproc::pathLength(s)));
      for (int i = (c == 0 ? 0 : 1); i <= m; ++i) path.push_back(accura::postproc::interpolate(s, double(i) / m));
    }
    for (size_t i = 0; i < path.size(); i += 20) path20.push_back(path[i]);
    const IkResult r0 = solver.inverse(path.front(), Configuration{}, Eigen::VectorXd(), IkOptions{});
    const IkResult r0c =
        compensator.real().inverse(path.front(), Configuration{}, Eigen::VectorXd(), IkOptions{});
    if (r0.status != IkStatus::kOk || r0c.status != IkStatus::kOk) error = "the path start is not reachable";
    path_q0 = r0.q;
    path_q0_comp = r0c.q;

    // (b), (c) random well-conditioned poses (10% margin from the limits, scaled sigma_min
    // >= 1e-3) and seeds 0.5 deg per joint away
    IkOptions o;
    o.compute_singular_value = true;
    while (targets.size() < 1000) {
      Eigen::VectorXd q(n);
      for (int i = 0; i < n; ++i) q[i] = (q_min(i) + u(rng) * (q_max(i) - q_min(i))) / kDeg;
      const Eigen::Isometry3d T = solver.forward(q);
      const IkResult check = solver.inverse(T, Configuration{}, q, o);
      if (check.status != IkStatus::kOk || check.min_singular_value < 1e-3) continue;
      Eigen::VectorXd s = q;
      for (int i = 0; i < n; ++i) s[i] += 0.5 * v(rng);
      targets.push_back(T);
      truth.push_back(q);
      nearby.push_back(s);
      configs.push_back(accura::calib::kukaConfiguration(real, q));
    }
  }

  static KDL::JntArray toKdlJoints(const Eigen::VectorXd& q_deg) {
    KDL::JntArray q(static_cast<unsigned>(q_deg.size()));
    for (int i = 0; i < q_deg.size(); ++i) q(i) = q_deg[i] * kDeg;
    return q;
  }

  /// Within the joint limits and `bound` times 1 um / 1 urad (accura's FK; 1.8 for KDL's
  /// per-component criterion, 1 + 1e-4 for accura and for KDL held to the same bound: the two
  /// FKs agree to 1e-7 um).
  bool reached(const Eigen::VectorXd& q_deg, const Eigen::Isometry3d& T, double bound) const {
    for (int i = 0; i < q_deg.size(); ++i)
      if (q_deg[i] * kDeg < q_min(i) - 1e-12 || q_deg[i] * kDeg > q_max(i) + 1e-12) return false;
    const Eigen::Isometry3d F = solver.forward(q_deg);
    return (F.translation() - T.translation()).norm() <= bound * 1e-3 &&
           accura::calib::logSO3(F.linear() * T.linear().transpose()).norm() <= bound * 1e-6;
  }

  /// KDL's solve alone (the timed part): true when KDL reports success.
  bool kdlSolve(const KDL::JntArray& seed, const Eigen::Isometry3d& T, KDL::JntArray& out, bool same_bound) const {
    out.resize(seed.rows());
    return (same_bound ? kdl_ik_bound : kdl_ik)->CartToJnt(seed, toKdl(T), out) >= 0;
  }
  static Eigen::VectorXd fromKdl(const KDL::JntArray& q) {
    Eigen::VectorXd v(q.rows());
    for (unsigned i = 0; i < q.rows(); ++i) v[i] = q(i) / kDeg;
    return v;
  }
};

const Setup& setup() {
  static const Setup s;
  return s;
}

void rate(benchmark::State& state, long ok, long total) {
  state.counters["success_%"] = total ? 100.0 * ok / total : 0;
  state.SetItemsProcessed(total);
}

// ---------------------------------------------------------------------------------------
// (a) path-following, seeded with the previous solution

/// accura's IK options: the defaults, or without the singularity check (`check` false: the
/// same job as KDL's solver, which does not look for singularities).
IkOptions ikOptions(bool check) {
  IkOptions o;
  if (!check) o.singular_threshold = 0;
  return o;
}

/// One pass over `path` as the timed loop does it (each solve seeded with the previous
/// solution), untimed, every solution checked with reached(): the success rate reported.
/// `solve(seed, target, out)` returns whether the solver claimed success.
template <class Solve>
double verifiedPathPass(const std::vector<Eigen::Isometry3d>& path, const Eigen::VectorXd& q0, Solve solve,
                        double bound, double* evals = nullptr) {
  const Setup& s = setup();
  Eigen::VectorXd q = q0, out;
  long ok = 0, n_evals = 0;
  for (const Eigen::Isometry3d& T : path) {
    int e = 0;
    if (solve(q, T, out, e)) {
      if (s.reached(out, T, bound)) ++ok;
      q = out;
    }
    n_evals += e;
  }
  if (evals) *evals = path.empty() ? 0 : static_cast<double>(n_evals) / static_cast<double>(path.size());
  return path.empty() ? 0 : 100.0 * static_cast<double>(ok) / static_cast<double>(path.size());
}

/// How accura follows the path: `kFollow` KinematicSolver::follow with an IkWorkspace carried
/// along (the path API: the seed array becomes the solution, no allocation); `kResult` the
/// same solve through inverse(..., workspace), which returns an IkResult; `kStateless` the
/// stateless inverse(), seed only.
enum class PathApi { kFollow, kResult, kStateless };

void pathWarmAccura(benchmark::State& state, const std::vector<Eigen::Isometry3d>& path, bool check = true,
                    PathApi api = PathApi::kFollow) {
  const Setup& s = setup();
  if (!s.error.empty()) return state.SkipWithError(s.error.c_str());
  const IkOptions o = ikOptions(check);
  accura::calib::IkWorkspace ws;
  // one solve from `q` (updated to the solution on success); `evals` FK evaluations (with a
  // reused workspace, one of them stored), known for the IkResult calls
  auto solve = [&](const Eigen::Isometry3d& T, Eigen::VectorXd& q, int* evals) {
    if (api == PathApi::kFollow) return s.solver.follow(T, Configuration{}, q, o, {}, ws) == IkStatus::kOk;
    const IkResult r = api == PathApi::kResult ? s.solver.inverse(T, Configuration{}, q, o, {}, ws)
                                               : s.solver.inverse(T, Configuration{}, q, o);
    if (evals) *evals = 1 + r.iterations;
    if (r.status != IkStatus::kOk) return false;
    q = r.q;
    return true;
  };
  double evals = 0;
  const double verified = verifiedPathPass(
      path, s.path_q0,
      [&](const Eigen::VectorXd& seed, const Eigen::Isometry3d& T, Eigen::VectorXd& out, int& e) {
        out = seed;
        return solve(T, out, &e);
      },
      kSameBound, &evals);
  ws.clear();
  Eigen::VectorXd q = s.path_q0;
  size_t k = 0;
  long total = 0;
  for (auto _ : state) {
    solve(path[k], q, nullptr);
    benchmark::DoNotOptimize(q.data());
    ++total;
    if (++k == path.size()) {
      k = 0;
      q = s.path_q0;
    }
  }
  state.counters["success_%"] = verified;
  if (api != PathApi::kFollow) state.counters["fk_evals"] = evals;
  state.SetItemsProcessed(total);
}

void pathWarmKdl(benchmark::State& state, const std::vector<Eigen::Isometry3d>& path, bool same_bound = false) {
  const Setup& s = setup();
  if (!s.error.empty()) return state.SkipWithError(s.error.c_str());
  const double verified = verifiedPathPass(
      path, s.path_q0, [&](const Eigen::VectorXd& seed, const Eigen::Isometry3d& T, Eigen::VectorXd& out, int&) {
        KDL::JntArray o;
        const bool good = s.kdlSolve(Setup::toKdlJoints(seed), T, o, same_bound);
        out = Setup::fromKdl(o);
        return good;
      },
      same_bound ? kSameBound : kKdlBound);
  KDL::JntArray q = Setup::toKdlJoints(s.path_q0), out;
  size_t k = 0;
  long total = 0;
  for (auto _ : state) {
    const bool good = s.kdlSolve(q, path[k], out, same_bound);
    benchmark::DoNotOptimize(out.data.data());
    ++total;
    if (good) q = out;
    if (++k == path.size()) {
      k = 0;
      q = Setup::toKdlJoints(s.path_q0);
    }
  }
  state.counters["success_%"] = verified;
  state.SetItemsProcessed(total);
}

void BM_PathWarm_Accura(benchmark::State& state) { pathWarmAccura(state, setup().path); }
BENCHMARK(BM_PathWarm_Accura);
void BM_PathWarm_AccuraNoSingularCheck(benchmark::State& state) { pathWarmAccura(state, setup().path, false); }
BENCHMARK(BM_PathWarm_AccuraNoSingularCheck);
void BM_PathWarm_AccuraResult(benchmark::State& state) { pathWarmAccura(state, setup().path, true, PathApi::kResult); }
BENCHMARK(BM_PathWarm_AccuraResult);
void BM_PathWarm_AccuraStateless(benchmark::State& state) {
  pathWarmAccura(state, setup().path, true, PathApi::kStateless);
}
BENCHMARK(BM_PathWarm_AccuraStateless);
void BM_PathWarm_KDL(benchmark::State& state) { pathWarmKdl(state, setup().path); }
BENCHMARK(BM_PathWarm_KDL);
void BM_PathWarm_KDLSameBound(benchmark::State& state) { pathWarmKdl(state, setup().path, true); }
BENCHMARK(BM_PathWarm_KDLSameBound);
void BM_Path20Warm_Accura(benchmark::State& state) { pathWarmAccura(state, setup().path20); }
BENCHMARK(BM_Path20Warm_Accura);
void BM_Path20Warm_AccuraNoSingularCheck(benchmark::State& state) { pathWarmAccura(state, setup().path20, false); }
BENCHMARK(BM_Path20Warm_AccuraNoSingularCheck);
void BM_Path20Warm_AccuraResult(benchmark::State& state) {
  pathWarmAccura(state, setup().path20, true, PathApi::kResult);
}
BENCHMARK(BM_Path20Warm_AccuraResult);
void BM_Path20Warm_AccuraStateless(benchmark::State& state) {
  pathWarmAccura(state, setup().path20, true, PathApi::kStateless);
}
BENCHMARK(BM_Path20Warm_AccuraStateless);
void BM_Path20Warm_KDL(benchmark::State& state) { pathWarmKdl(state, setup().path20); }
BENCHMARK(BM_Path20Warm_KDL);
void BM_Path20Warm_KDLSameBound(benchmark::State& state) { pathWarmKdl(state, setup().path20, true); }
BENCHMARK(BM_Path20Warm_KDLSameBound);

// ---------------------------------------------------------------------------------------
// (b) random poses, seeded 0.5 deg per joint away

/// One untimed pass over the 1 000 targets, every solution checked with reached(): the
/// success rate reported. `solve(k, out)` returns whether the solver claimed success.
template <class Solve>
double verifiedPass(Solve solve, double bound) {
  const Setup& s = setup();
  long ok = 0;
  Eigen::VectorXd out;
  for (size_t k = 0; k < s.targets.size(); ++k)
    if (solve(k, out) && s.reached(out, s.targets[k], bound)) ++ok;
  return s.targets.empty() ? 0 : 100.0 * static_cast<double>(ok) / static_cast<double>(s.targets.size());
}

/// accura on the 1 000 targets: seeded with `seeds` (empty vectors: cold, with the targets'
/// Status/Turn).
void targetsAccura(benchmark::State& state, const std::vector<Eigen::VectorXd>& seeds, bool cold, bool check) {
  const Setup& s = setup();
  if (!s.error.empty()) return state.SkipWithError(s.error.c_str());
  const IkOptions o = ikOptions(check);
  const Eigen::VectorXd none;
  auto solve = [&](size_t k) {
    return s.solver.inverse(s.targets[k], cold ? s.configs[k] : Configuration{}, cold ? none : seeds[k], o);
  };
  const double verified = verifiedPass([&](size_t k, Eigen::VectorXd& out) {
    const IkResult r = solve(k);
    out = r.q;
    return r.status == IkStatus::kOk;
  }, kSameBound);
  size_t k = 0;
  long total = 0;
  for (auto _ : state) {
    const IkResult r = solve(k);
    benchmark::DoNotOptimize(r.q.data());
    ++total;
    if (++k == s.targets.size()) k = 0;
  }
  state.counters["success_%"] = verified;
  state.SetItemsProcessed(total);
}

/// KDL on the 1 000 targets from `seeds` (one seed for all when it has one element).
void targetsKdl(benchmark::State& state, const std::vector<Eigen::VectorXd>& seeds, bool same_bound = false) {
  const Setup& s = setup();
  if (!s.error.empty()) return state.SkipWithError(s.error.c_str());
  std::vector<KDL::JntArray> kdl_seeds;
  for (const Eigen::VectorXd& q : seeds) kdl_seeds.push_back(Setup::toKdlJoints(q));
  auto seedOf = [&](size_t k) -> const KDL::JntArray& { return kdl_seeds[kdl_seeds.size() == 1 ? 0 : k]; };
  const double verified = verifiedPass([&](size_t k, Eigen::VectorXd& out) {
    KDL::JntArray o;
    const bool good = s.kdlSolve(seedOf(k), s.targets[k], o, same_bound);
    out = Setup::fromKdl(o);
    return good;
  }, same_bound ? kSameBound : kKdlBound);
  KDL::JntArray out;
  size_t k = 0;
  long total = 0;
  for (auto _ : state) {
    const bool good = s.kdlSolve(seedOf(k), s.targets[k], out, same_bound);
    benchmark::DoNotOptimize(good);
    benchmark::DoNotOptimize(out.data.data());
    ++total;
    if (++k == s.targets.size()) k = 0;
  }
  state.counters["success_%"] = verified;
  state.SetItemsProcessed(total);
}

// (b) random poses, seeded 0.5 deg per joint away
void BM_NearbyWarm_Accura(benchmark::State& state) { targetsAccura(state, setup().nearby, false, true); }
BENCHMARK(BM_NearbyWarm_Accura);
void BM_NearbyWarm_AccuraNoSingularCheck(benchmark::State& state) {
  targetsAccura(state, setup().nearby, false, false);
}
BENCHMARK(BM_NearbyWarm_AccuraNoSingularCheck);
void BM_NearbyWarm_KDL(benchmark::State& state) { targetsKdl(state, setup().nearby); }
BENCHMARK(BM_NearbyWarm_KDL);
void BM_NearbyWarm_KDLSameBound(benchmark::State& state) { targetsKdl(state, setup().nearby, true); }
BENCHMARK(BM_NearbyWarm_KDLSameBound);

// (c) the same poses, cold: accura with the targets' Status/Turn and no seed, KDL from the
// middle of the joint ranges
void BM_Cold_Accura(benchmark::State& state) { targetsAccura(state, {}, true, true); }
BENCHMARK(BM_Cold_Accura);
void BM_Cold_KDL(benchmark::State& state) { targetsKdl(state, {setup().q_mid_deg}); }
BENCHMARK(BM_Cold_KDL);
void BM_Cold_KDLSameBound(benchmark::State& state) { targetsKdl(state, {setup().q_mid_deg}, true); }
BENCHMARK(BM_Cold_KDLSameBound);

// ---------------------------------------------------------------------------------------
// Compensation throughput (the real model with joint compliance)

/// Points along the path, each compensated continuing from the previous point's joints:
/// q' = IK_real(target), command = FK_controller(q').
void BM_Compensation_PathPoints(benchmark::State& state) {
  const Setup& s = setup();
  if (!s.error.empty()) return state.SkipWithError(s.error.c_str());
  const IkOptions o;
  Eigen::VectorXd q = s.path_q0_comp;
  size_t k = 0;
  long ok = 0, total = 0;
  for (auto _ : state) {
    const accura::postproc::PoseCompensation r = s.compensator.pose(s.path[k], Configuration{}, q, o);
    benchmark::DoNotOptimize(r.T_world_tcp_command.data());
    ++total;
    if (r.status == IkStatus::kOk) {
      ++ok;
      q = r.q_real;
    }
    if (++k == s.path.size()) {
      k = 0;
      q = s.path_q0_comp;
    }
  }
  rate(state, ok, total);
}
BENCHMARK(BM_Compensation_PathPoints);

/// Program targets with their Status/Turn and no seed (PTP targets after an unknown position).
void BM_Compensation_ColdTargets(benchmark::State& state) {
  const Setup& s = setup();
  if (!s.error.empty()) return state.SkipWithError(s.error.c_str());
  const IkOptions o;
  size_t k = 0;
  long ok = 0, total = 0;
  for (auto _ : state) {
    const accura::postproc::PoseCompensation r = s.compensator.pose(s.targets[k], s.configs[k], Eigen::VectorXd(), o);
    benchmark::DoNotOptimize(r.T_world_tcp_command.data());
    ++total;
    if (r.status == IkStatus::kOk) ++ok;
    if (++k == s.targets.size()) k = 0;
  }
  rate(state, ok, total);
}
BENCHMARK(BM_Compensation_ColdTargets);

/// One long LIN (2.1 m, 97 deg of reorientation) with its auxiliary points for 0.05 mm:
/// items = mm of path.
void BM_Compensation_LongLinSegment(benchmark::State& state) {
  const Setup& s = setup();
  if (!s.error.empty()) return state.SkipWithError(s.error.c_str());
  accura::postproc::PathSegment seg;
  seg.T_world_start = pose(900, -1100, 300, -30, 150, 10);
  seg.T_world_end = pose(1000, 1000, 700, 40, 120, -20);
  const accura::postproc::DensifyOptions o;
  long ok = 0, total = 0;
  int points = 0;
  for (auto _ : state) {
    const accura::postproc::SegmentCompensation r = s.compensator.segment(seg, Configuration{}, s.path_q0_comp, o);
    benchmark::DoNotOptimize(r.commanded.data());
    ++total;
    if (r.status == IkStatus::kOk) ++ok;
    points = r.points_added;
  }
  state.counters["success_%"] = total ? 100.0 * ok / total : 0;
  state.counters["points_added"] = points;
  state.SetItemsProcessed(static_cast<int64_t>(total * accura::postproc::pathLength(seg)));
}
BENCHMARK(BM_Compensation_LongLinSegment)->Unit(benchmark::kMillisecond);

// ---------------------------------------------------------------------------------------

/// The console output, plus the CPU time per solve of every benchmark for the ratios.
class RatioReporter : public benchmark::ConsoleReporter {
 public:
  std::map<std::string, double> ns;
  void ReportRuns(const std::vector<Run>& runs) override {
    // with --benchmark_repetitions the medians are used
    for (const Run& r : runs) {
      if (r.error_occurred || r.iterations <= 0) continue;
      std::string name = r.benchmark_name();
      const bool median = name.size() > 7 && name.compare(name.size() - 7, 7, "_median") == 0;
      if (median) name.resize(name.size() - 7);
      // CPU time: single-threaded, and the machine may be shared (other jobs preempt us)
      if (median || !medians_.count(name)) ns[name] = r.GetAdjustedCPUTime();
      if (median) medians_.insert(name);
    }
    ConsoleReporter::ReportRuns(runs);
  }

 private:
  std::set<std::string> medians_;
};

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  RatioReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  std::printf("\nKDL CPU time / accura CPU time (same chain, same targets, same tolerance):\n");
  // KDL: its eps per twist component (KDL), and held to accura's bound as norms (KDLSameBound)
  for (const char* peer : {"_KDL", "_KDLSameBound"}) {
    for (const char* pair : {"PathWarm", "Path20Warm", "NearbyWarm", "Cold"}) {
      const std::string k = std::string("BM_") + pair + peer;
      for (const char* variant : {"_Accura", "_AccuraNoSingularCheck", "_AccuraResult", "_AccuraStateless"}) {
        const std::string a = std::string("BM_") + pair + variant;
        if (reporter.ns.count(a) && reporter.ns.count(k) && reporter.ns[a] > 0)
          std::printf("  %-10s %-22s %6.1f x   (accura %.2f us, %s %.2f us per solve)\n", pair, variant + 1,
                      reporter.ns[k] / reporter.ns[a], reporter.ns[a] * 1e-3, peer + 1, reporter.ns[k] * 1e-3);
      }
    }
  }
  benchmark::Shutdown();
  return 0;
}
