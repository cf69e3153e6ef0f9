// accura cell checks: clearance queries against a cell of about 100k triangles: the exact
// query, the bounded query the checks use, and a brute-force peer, side by side in one run, at
// several distances from the surface. Single-threaded.
//
// The cell: one tessellated surface, a 2.4 m x 2.4 m patch of z = 250 + 60 sin(x/90) cos(y/130)
// mm on a 224 x 224 grid (100,352 triangles), under and in front of a KUKA KR 16 (base at the
// origin). The robot: a sphere of radius 20 mm on the flange (the tool geometry), or a capsule
// (radius 20 mm, 200 mm along the flange's z axis).
//
// The bound: a check with the default thresholds needs a distance exactly only below
// B = min_clearance 5 mm + exact_band 100 mm = 105 mm (docs/checks.md, "Distance queries").
//
//   *_Exact       CellGeometry::distances with exact_below_mm = infinity: forward kinematics,
//                 the bounding-box cull, one unbounded FCL distance query on the BVH of OBBRSS
//                 (what the checks did before: the old query).
//   *_Bounded     CellGeometry::distances with exact_below_mm = B: the same, FCL's traversal
//                 started from B instead of infinity (the new query). Counters: `exact_below_B`
//                 (fraction of its queries whose distance is below B), `mismatch` (queries
//                 below B whose answer differs from the exact one in any bit, or at/above B whose
//                 answer is not in [B, exact]: must be 0).
//   *_BruteForce  point/triangle distance (Ericson's closest point) to every triangle, minus the
//                 radius: what a hand-written check without a hierarchy does (sphere only; the
//                 first 20 queries of a set, cycled: it is slow). Counter: max difference from
//                 the exact query (mm).
//
// Query sets: BM_Mixed_*: 1000 random joint vectors within the limits whose flange is within
// 300 mm of the surface's bounding box (the set of the first measurement). BM_Band_*/lo/hi:
// 200 random joint vectors whose sphere is lo..hi mm from the surface (exact distance): near
// (below B: 0-5, 5-50, 50-105) and far (105-200, 200-400, 400-1000). BM_Check_*/z: a whole
// checkMotions of a 1200 mm LIN at height z over the ripples (1 mm sampling plus subdivision),
// exact_band_mm = infinity (every query exact) vs the default 100 mm; counters: samples and
// violations (equal in both: the same subdivision), FCL queries. BM_CellGeometry_Build: the
// BVH construction every check starts with. The run ends with the ratios.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <cstdio>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "accura/calib/geometry.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/robot_io.h"
#include "accura/postproc/cell.h"
#include "accura/postproc/check.h"

namespace {

using accura::postproc::Cell;
using accura::postproc::CellGeometry;
using accura::postproc::CellShape;
using accura::postproc::Mesh;

constexpr double kRadius = 20;

Mesh terrain() {
  Mesh m;
  const int n = 225;  // vertices per side: 224 x 224 cells x 2 = 100,352 triangles
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const double x = -200 + 2400.0 * i / (n - 1), y = -1200 + 2400.0 * j / (n - 1);
      m.vertices_mm.emplace_back(x, y, 250 + 60 * std::sin(x / 90) * std::cos(y / 130));
    }
  for (int i = 0; i + 1 < n; ++i)
    for (int j = 0; j + 1 < n; ++j) {
      const int a = i * n + j, b = a + 1, c = a + n, d = c + 1;
      m.triangles.push_back({a, c, d});
      m.triangles.push_back({a, d, b});
    }
  m.file = "terrain";
  return m;
}

Eigen::Vector3d closestOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + d1 / (d1 - d3) * ab;
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + d2 / (d2 - d6) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
  const double denom = 1.0 / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

constexpr double kBoundMm = 5.0 + 100.0;  // min_clearance + exact_band (check defaults)
constexpr double kInfMm = std::numeric_limits<double>::infinity();

struct QuerySet {
  std::vector<Eigen::VectorXd> q;
  std::vector<double> exact_mm;  // the exact query's answer per q
};

struct Band {
  double lo, hi;
  QuerySet set;
};

struct Setup {
  accura::calib::RobotModel robot, flange;
  Mesh mesh;
  std::unique_ptr<CellGeometry> geometry, geometry_capsule;
  Cell cell;
  QuerySet mixed, mixed_capsule;
  std::vector<Band> bands;
  Setup() {
    robot = accura::calib::readRobotFile(accura::calib::resolveRobotPath("kuka_kr16"));
    flange = robot;
    flange.nominal.T_flange_tcp = Eigen::Isometry3d::Identity();
    mesh = terrain();
    CellShape s;
    s.mesh = mesh;
    s.name = "terrain";
    cell.objects.push_back(s);
    CellShape tool;
    tool.capsule = accura::postproc::Capsule{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), kRadius};
    tool.name = "tool";
    cell.tool_shapes.push_back(tool);
    geometry = std::make_unique<CellGeometry>(cell, robot);
    Cell capsule_cell = cell;
    capsule_cell.tool_shapes[0].capsule->p1_mm = Eigen::Vector3d(0, 0, 200);
    geometry_capsule = std::make_unique<CellGeometry>(capsule_cell, robot);
    std::mt19937_64 rng(17);
    auto random_q = [&]() {
      Eigen::VectorXd x(6);
      for (int i = 0; i < 6; ++i) {
        std::uniform_real_distribution<double> u(robot.nominal.joints[i].lower, robot.nominal.joints[i].upper);
        x[i] = u(rng);
      }
      return x;
    };
    auto exact = [&](const CellGeometry& g, const Eigen::VectorXd& x) { return g.distances(x, accura::calib::PoseContext{}, kInfMm)[0].mm; };
    while (mixed.q.size() < 1000) {
      const Eigen::VectorXd x = random_q();
      const Eigen::Vector3d c = accura::calib::forwardKinematics(flange, x).translation();
      if (c.x() < -500 || c.x() > 2500 || std::fabs(c.y()) > 1500 || c.z() > 610) continue;
      mixed.q.push_back(x);
      mixed.exact_mm.push_back(exact(*geometry, x));
      mixed_capsule.q.push_back(x);
      mixed_capsule.exact_mm.push_back(exact(*geometry_capsule, x));
    }
    // bands of the exact distance: candidates by the vertical gap to the surface (an upper
    // bound of the distance over the patch, within a factor ~2 of it), then the exact query
    bands = {{0, 5, {}}, {5, 50, {}}, {50, 105, {}}, {105, 200, {}}, {200, 400, {}}, {400, 1000, {}}};
    const size_t per_band = 200;
    for (long attempt = 0; attempt < 20000000; ++attempt) {
      bool full = true;
      for (const auto& b : bands) full = full && b.set.q.size() >= per_band;
      if (full) break;
      const Eigen::VectorXd x = random_q();
      const Eigen::Vector3d c = accura::calib::forwardKinematics(flange, x).translation();
      if (c.x() < -600 || c.x() > 2600 || std::fabs(c.y()) > 1600) continue;
      const double h = 250 + 60 * std::sin(std::clamp(c.x(), -200.0, 2200.0) / 90) * std::cos(std::clamp(c.y(), -1200.0, 1200.0) / 130);
      const double gap = std::fabs(c.z() - h) - kRadius;
      Band* want = nullptr;
      for (auto& b : bands)
        if (b.set.q.size() < per_band && gap >= b.lo * 0.9 && gap < 2.5 * b.hi + 20) want = &b;
      if (!want) continue;
      const double d = exact(*geometry, x);
      for (auto& b : bands)
        if (d >= b.lo && d < b.hi && b.set.q.size() < per_band) {
          b.set.q.push_back(x);
          b.set.exact_mm.push_back(d);
        }
    }
  }
};

Setup& setup() {
  static Setup s;
  return s;
}

// The query: CellGeometry::distances with exact_below_mm = `bound`; counters compare the
// answers with the exact ones.
void query(benchmark::State& state, const CellGeometry& g, const QuerySet& set, double bound) {
  if (set.q.empty()) {
    state.SkipWithError("no query in this set");
    return;
  }
  size_t k = 0;
  long mismatch = 0, below = 0, n = 0;
  for (auto _ : state) {
    const auto d = g.distances(set.q[k], accura::calib::PoseContext{}, bound);
    const double e = set.exact_mm[k];
    if (e < bound) {
      ++below;
      if (d[0].mm != e || d[0].lower_bound) ++mismatch;
    } else if (!(d[0].mm >= bound && d[0].mm <= e)) {
      ++mismatch;
    }
    ++n;
    benchmark::DoNotOptimize(d);
    k = (k + 1) % set.q.size();
  }
  state.SetItemsProcessed(state.iterations());
  state.counters["exact_below_B"] = n ? static_cast<double>(below) / static_cast<double>(n) : 0.0;
  state.counters["mismatch"] = static_cast<double>(mismatch);
}

void bruteForce(benchmark::State& state, const QuerySet& set) {
  if (set.q.empty()) {
    state.SkipWithError("no query in this set");
    return;
  }
  Setup& s = setup();
  const size_t n = std::min<size_t>(20, set.q.size());
  size_t k = 0;
  double max_diff = 0;
  for (auto _ : state) {
    const Eigen::Vector3d p = accura::calib::forwardKinematics(s.flange, set.q[k]).translation();
    double best = 1e300;
    for (const auto& t : s.mesh.triangles)
      best = std::min(best, (closestOnTriangle(p, s.mesh.vertices_mm[static_cast<size_t>(t[0])], s.mesh.vertices_mm[static_cast<size_t>(t[1])],
                                               s.mesh.vertices_mm[static_cast<size_t>(t[2])]) - p).squaredNorm());
    const double d = std::max(0.0, std::sqrt(best) - kRadius);
    max_diff = std::max(max_diff, std::fabs(d - set.exact_mm[k]));
    benchmark::DoNotOptimize(d);
    k = (k + 1) % n;
  }
  state.SetItemsProcessed(state.iterations());
  state.counters["max_diff_vs_exact_mm"] = max_diff;
}

void BM_Mixed_Exact(benchmark::State& state) { query(state, *setup().geometry, setup().mixed, kInfMm); }
void BM_Mixed_Bounded(benchmark::State& state) { query(state, *setup().geometry, setup().mixed, kBoundMm); }
void BM_Mixed_BruteForce(benchmark::State& state) { bruteForce(state, setup().mixed); }
void BM_MixedCapsule_Exact(benchmark::State& state) { query(state, *setup().geometry_capsule, setup().mixed_capsule, kInfMm); }
void BM_MixedCapsule_Bounded(benchmark::State& state) { query(state, *setup().geometry_capsule, setup().mixed_capsule, kBoundMm); }

const Band& band(const benchmark::State& state) {
  for (const auto& b : setup().bands)
    if (b.lo == static_cast<double>(state.range(0))) return b;
  return setup().bands.front();
}
void BM_Band_Exact(benchmark::State& state) { query(state, *setup().geometry, band(state).set, kInfMm); }
void BM_Band_Bounded(benchmark::State& state) { query(state, *setup().geometry, band(state).set, kBoundMm); }
void BM_Band_BruteForce(benchmark::State& state) { bruteForce(state, band(state).set); }

// A whole check: PTP to the start, then a LIN of 1200 mm along x at height z_mm, the tool
// pointing down: at z 400 mm the sphere passes 70..190 mm over the ripples (the surface's z
// 190..310; near: mostly below B), at z 600 mm 270..390 mm (far), sampled every 1 mm and
// subdivided where the proof needs it. The CellGeometry (the BVH of the 100k triangles) is
// built once per check: BM_CellGeometry_Build measures that part alone.
void check(benchmark::State& state, double band_mm) {
  Setup& s = setup();
  const double z = static_cast<double>(state.range(0));
  std::vector<accura::postproc::WorldMotion> motions(2);
  motions[0].type = accura::postproc::MotionType::kPtp;
  motions[0].T_world_tcp_end = accura::calib::toIsometry(accura::calib::XyzAbc{700, -300, z, 0, 180, 0});
  motions[0].label = "PTP";
  motions[1].type = accura::postproc::MotionType::kLin;
  motions[1].T_world_tcp_end = accura::calib::toIsometry(accura::calib::XyzAbc{1900, -300, z, 0, 180, 0});
  motions[1].label = "LIN";
  accura::postproc::CheckOptions o;
  o.exact_band_mm = band_mm;
  o.thresholds.singular_threshold = 0;
  accura::postproc::CheckReport r;
  for (auto _ : state) {
    r = accura::postproc::checkMotions(s.robot, s.robot, s.cell, motions, o);
    benchmark::DoNotOptimize(r);
  }
  state.counters["samples"] = r.samples;
  state.counters["queries"] = static_cast<double>(r.distance_queries);
  state.counters["violations"] = static_cast<double>(r.violations.size());
  state.counters["min_clearance_mm"] = r.min_clearance_mm;
}
void BM_Check_Exact(benchmark::State& state) { check(state, kInfMm); }
void BM_Check_Bounded(benchmark::State& state) { check(state, 100.0); }
void BM_CellGeometry_Build(benchmark::State& state) {
  Setup& s = setup();
  for (auto _ : state) {
    CellGeometry g(s.cell, s.robot);
    benchmark::DoNotOptimize(g);
  }
}

BENCHMARK(BM_Mixed_Exact)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Mixed_Bounded)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Mixed_BruteForce)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_MixedCapsule_Exact)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_MixedCapsule_Bounded)->Unit(benchmark::kMicrosecond);
#define ACCURA_BANDS ->Args({0, 5})->Args({5, 50})->Args({50, 105})->Args({105, 200})->Args({200, 400})->Args({400, 1000})
BENCHMARK(BM_Band_Exact) ACCURA_BANDS->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Band_Bounded) ACCURA_BANDS->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Band_BruteForce) ACCURA_BANDS->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Check_Exact)->Arg(400)->Arg(600)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Check_Bounded)->Arg(400)->Arg(600)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_CellGeometry_Build)->Unit(benchmark::kMillisecond);

// Prints the CPU time per query of each set for the three queries, and their ratios.
class RatioReporter : public benchmark::ConsoleReporter {
 public:
  void ReportRuns(const std::vector<Run>& runs) override {
    for (const auto& r : runs)
      if (r.run_type == Run::RT_Iteration && r.iterations > 0 && !r.error_occurred)
        per_query_s_[r.benchmark_name()] = r.cpu_accumulated_time / static_cast<double>(r.iterations);
    ConsoleReporter::ReportRuns(runs);
  }
  void Finalize() override {
    ConsoleReporter::Finalize();
    std::printf("\nmesh: %zu triangles; bound B = %.0f mm\n", setup().mesh.triangles.size(), kBoundMm);
    std::printf("%-22s %12s %12s %12s %10s %10s %10s\n", "set", "exact us", "bounded us", "brute us", "ex/bnd", "brute/bnd", "brute/ex");
    auto row = [&](const std::string& name, const std::string& e, const std::string& b, const std::string& f) {
      const auto ie = per_query_s_.find(e), ib = per_query_s_.find(b), iff = per_query_s_.find(f);
      if (ie == per_query_s_.end() || ib == per_query_s_.end()) return;
      const double te = ie->second, tb = ib->second, tf = iff == per_query_s_.end() ? 0.0 : iff->second;
      if (tf > 0)
        std::printf("%-22s %12.2f %12.2f %12.1f %10.2f %10.1f %10.1f\n", name.c_str(), te * 1e6, tb * 1e6, tf * 1e6, te / tb, tf / tb, tf / te);
      else
        std::printf("%-22s %12.2f %12.2f %12s %10.2f %10s %10s\n", name.c_str(), te * 1e6, tb * 1e6, "-", te / tb, "-", "-");
    };
    row("mixed (sphere)", "BM_Mixed_Exact", "BM_Mixed_Bounded", "BM_Mixed_BruteForce");
    row("mixed (capsule)", "BM_MixedCapsule_Exact", "BM_MixedCapsule_Bounded", "");
    for (const auto& b : setup().bands) {
      const std::string args = "/" + std::to_string(static_cast<int>(b.lo)) + "/" + std::to_string(static_cast<int>(b.hi));
      row("band " + args.substr(1) + " mm", "BM_Band_Exact" + args, "BM_Band_Bounded" + args, "BM_Band_BruteForce" + args);
    }
    row("check, LIN z 400 (near)", "BM_Check_Exact/400", "BM_Check_Bounded/400", "");
    row("check, LIN z 600 (far)", "BM_Check_Exact/600", "BM_Check_Bounded/600", "");
    const auto build = per_query_s_.find("BM_CellGeometry_Build");
    if (build != per_query_s_.end()) {
      std::printf("CellGeometry build (BVH of the 100k triangles): %.1f ms per check; the checks without it:\n", build->second * 1e3);
      for (const char* z : {"/400", "/600"}) {
        const auto e = per_query_s_.find(std::string("BM_Check_Exact") + z), b = per_query_s_.find(std::string("BM_Check_Bounded") + z);
        if (e != per_query_s_.end() && b != per_query_s_.end())
          std::printf("  LIN z %s: exact %.1f ms, bounded %.1f ms: %.2fx\n", z + 1, (e->second - build->second) * 1e3,
                      (b->second - build->second) * 1e3, (e->second - build->second) / (b->second - build->second));
      }
    }
  }

 private:
  std::map<std::string, double> per_query_s_;
};

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  RatioReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  benchmark::Shutdown();
  return 0;
}
