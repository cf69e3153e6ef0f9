#include "accura/calib/joint_map.h"
#include "accura/calib/text.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <limits>
#include <Eigen/Cholesky>

#include "accura/calib/errors.h"
#include "accura/calib/geometry.h"
#include "dense_linalg.h"

namespace accura::calib {
namespace {

// Uniform cubic B-spline weights at t in [0, 1] of the interval, and their derivatives d/dt.
void splineWeights(double t, double w[4], double dw[4]) {
  const double u = 1 - t, t2 = t * t, t3 = t2 * t;
  w[0] = u * u * u / 6;
  w[1] = (3 * t3 - 6 * t2 + 4) / 6;
  w[2] = (-3 * t3 + 3 * t2 + 3 * t + 1) / 6;
  w[3] = t3 / 6;
  if (dw) {
    dw[0] = -u * u / 2;
    dw[1] = (3 * t2 - 4 * t) / 2;
    dw[2] = (-3 * t2 + 2 * t + 1) / 2;
    dw[3] = t2 / 2;
  }
}

// Basis weights at q and their derivatives d/dq; returns the first coefficient index.
int basis(const JointMap& m, double q, double w[4], double dw[4]) {
  const int N = m.intervals;
  const double h = (m.upper - m.lower) / N;
  if (m.period > 0) {  // the turn of q nearest the interval's centre (dq/dq unchanged)
    const double centre = 0.5 * (m.lower + m.upper);
    q = centre + std::remainder(q - centre, m.period);
  }
  double taper = 1, dtaper = 0, qe = q;
  if (q < m.lower || q > m.upper) {
    const double s = q < m.lower ? m.lower - q : q - m.upper;  // distance beyond the end
    qe = q < m.lower ? m.lower : m.upper;
    if (s >= m.taper) {
      taper = 0;
    } else {
      taper = 0.5 * (1 + std::cos(kPi * s / m.taper));
      const double dtaper_ds = -0.5 * kPi / m.taper * std::sin(kPi * s / m.taper);
      dtaper = q < m.lower ? -dtaper_ds : dtaper_ds;  // ds/dq = -1 below, +1 above
    }
  }
  const double x = (qe - m.lower) / h;
  const int first = std::clamp(static_cast<int>(std::floor(x)), 0, N - 1);
  const double t = x - first;
  double sw[4], sdw[4];
  splineWeights(t, sw, sdw);
  const bool inside = qe == q;
  for (int k = 0; k < 4; ++k) {
    w[k] = taper * sw[k];
    // inside: d/dq of the spline; outside: the edge value is constant, the taper varies
    if (dw) dw[k] = inside ? sdw[k] / h : dtaper * sw[k];
  }
  return first;
}

}  // namespace

double jointMapValue(const JointMap& map, double q, double* slope) {
  if (map.empty()) {
    if (slope) *slope = 0;
    return 0;
  }
  double w[4], dw[4];
  const int f = basis(map, q, w, dw);
  double v = 0, d = 0;
  for (int k = 0; k < 4; ++k) {
    v += w[k] * map.coef[static_cast<size_t>(f + k)];
    d += dw[k] * map.coef[static_cast<size_t>(f + k)];
  }
  if (slope) *slope = d;
  return v;
}

int jointMapBasis(const JointMap& map, double q, double w[4]) {
  if (map.empty()) return -1;
  return basis(map, q, w, nullptr);
}

double jointMapBasisValue(const JointMap& map, double q, int k) {
  double w[4];
  const int f = jointMapBasis(map, q, w);
  if (f < 0 || k < f || k > f + 3) return 0;
  return w[k - f];
}

namespace {

/// Knot intervals of a map over [lower, upper] with spacing `knot` (at least one; a double, so
/// that an absurd spacing is counted, not overflowed).
double jointMapIntervals(double lower, double upper, double knot) {
  return std::max(1.0, std::ceil((upper - lower) / knot - 1e-9));
}

}  // namespace

JointMap makeJointMap(double lower, double upper, double knot, double period) {
  if (!(std::isfinite(lower) && std::isfinite(upper) && lower < upper))
    throw ArgumentError("joint map: expected a covered interval lower < upper, got " + std::to_string(lower) + ", " +
                        std::to_string(upper));
  if (!(std::isfinite(knot) && knot > 0))
    throw ArgumentError("joint map: expected a knot spacing > 0, got " + std::to_string(knot));
  JointMap m;
  m.lower = lower;
  m.upper = upper;
  m.intervals = static_cast<int>(jointMapIntervals(lower, upper, knot));
  m.taper = m.knot();
  if (!(period == 0 || (std::isfinite(period) && period > 0)))
    throw ArgumentError("joint map: expected a period of 0 (none) or > 0, got " + std::to_string(period));
  if (period > 0 && upper - lower + 2 * knot > period && knot > 0.25 * period) {
    // a knot spacing this coarse would leave less than half a turn: q's own map, as before
    period = 0;
  } else if (period > 0 && upper - lower + 2 * knot > period) {
    // the interval and its tapers within one turn: narrowed about its centre (the data beyond
    // its ends get the tapered map, as everywhere at the ends)
    const double centre = 0.5 * (lower + upper), half = 0.5 * period - knot;
    m.lower = centre - half;
    m.upper = centre + half;
    m.intervals = static_cast<int>(jointMapIntervals(m.lower, m.upper, knot));
    m.taper = m.knot();
  }
  m.period = period;
  m.coef.assign(static_cast<size_t>(m.intervals) + 3, 0.0);
  return m;
}

void checkJointMapSize(const std::vector<JointRange>& ranges, double knot) {
  size_t coefficients = 0;
  double covered = 0;
  for (const JointRange& r : ranges) {
    coefficients += static_cast<size_t>(std::min(jointMapIntervals(r.lower, r.upper, knot), 1e15)) + 3;  // makeJointMap's coef.size()
    covered += r.upper - r.lower;
  }
  if (coefficients <= kMaxJointMapCoefficients) return;
  const double fits = std::ceil(10 * covered / static_cast<double>(kMaxJointMapCoefficients - 4 * ranges.size())) / 10;
  throw InputError("joint_map: a knot spacing of " + formatNumber("%g", knot) + " gives " + std::to_string(coefficients) +
                   " map coefficients over the joints' covered ranges; expected at most " + std::to_string(kMaxJointMapCoefficients) +
                   " (they are solved densely): a spacing of at least " + formatFixed(fits, 1));
}

double jointMapPeriod(const RobotModel& model, int j) {
  if (j < 0 || j >= model.dof())
    throw ArgumentError("jointMapPeriod: expected a joint index 0.." + std::to_string(model.dof() - 1) + ", got " + std::to_string(j));
  return model.nominal.joints[static_cast<size_t>(j)].type == JointType::kRevolute ? 360.0 : 0.0;
}

double jointMapAmplitude(const JointMap& map) {
  if (map.empty()) return 0;
  double a = 0;
  const int samples = 8 * map.intervals;
  for (int s = 0; s <= samples; ++s)
    a = std::max(a, std::abs(jointMapValue(map, map.lower + (map.upper - map.lower) * s / samples)));
  return a;
}

std::vector<std::vector<double>> jointMapSmoothnessRows(const JointMap& map) {
  std::vector<std::vector<double>> rows;
  const size_t K = map.coef.size();
  for (size_t k = 1; k + 1 < K; ++k) {
    std::vector<double> r(K, 0.0);
    r[k - 1] = 1;
    r[k] = -2;
    r[k + 1] = 1;
    rows.push_back(r);
  }
  return rows;
}

std::vector<std::vector<double>> jointMapSparseRows(const JointMap& map, const std::vector<double>& q_fit) {
  std::vector<std::vector<double>> rows;
  const size_t K = map.coef.size();
  if (K == 0 || q_fit.empty() || !(map.upper > map.lower)) return rows;
  // the data mass of each coefficient, and what it would be with the data spread evenly over
  // the map's interval (a boundary coefficient's basis reaches into the interval only in part)
  std::vector<double> mass(K, 0.0), even(K, 0.0);
  double w[4];
  for (double q : q_fit) {
    const int f = jointMapBasis(map, q, w);
    if (f < 0) continue;
    for (int k = 0; k < 4; ++k) mass[static_cast<size_t>(f + k)] += w[k];
  }
  const int samples = 16 * std::max(map.intervals, 1);
  for (int s = 0; s < samples; ++s) {
    const int f = jointMapBasis(map, map.lower + (map.upper - map.lower) * (s + 0.5) / samples, w);
    if (f < 0) continue;
    for (int k = 0; k < 4; ++k) even[static_cast<size_t>(f + k)] += w[k] * double(q_fit.size()) / samples;
  }
  for (size_t k = 0; k < K; ++k) {
    if (!(mass[k] < kJointMapSparseShare * even[k])) continue;
    std::vector<double> r(K, 0.0);
    r[k] = 1.0;
    rows.push_back(r);
  }
  return rows;
}

std::vector<std::vector<double>> jointMapCentringRows(const JointMap& map, const std::vector<double>& q_fit,
                                                      int harmonics) {
  const size_t K = map.coef.size();
  const size_t G = 2 + 2 * static_cast<size_t>(std::max(harmonics, 0));
  std::vector<std::vector<double>> rows(G, std::vector<double>(K, 0.0));
  if (q_fit.empty() || K == 0) return rows;
  double qm = 0;
  for (double q : q_fit) qm += q;
  qm /= double(q_fit.size());
  double var = 0;
  for (double q : q_fit) var += (q - qm) * (q - qm);
  const double sd = std::sqrt(var / double(q_fit.size()));
  const double n = double(q_fit.size());
  double w[4];
  std::vector<double> g(G);
  for (double q : q_fit) {
    // the functions the map must not contain: 1, the trend, sin/cos(h q) (q in rad)
    g[0] = 1;
    g[1] = sd > 0 ? (q - qm) / sd : 0.0;
    for (int h = 1; h <= harmonics; ++h) {
      g[2 * static_cast<size_t>(h)] = std::sin(h * q * kDegToRad);
      g[2 * static_cast<size_t>(h) + 1] = std::cos(h * q * kDegToRad);
    }
    const int f = jointMapBasis(map, q, w);
    for (size_t r = 0; r < G; ++r)
      for (int k = 0; k < 4; ++k) rows[r][static_cast<size_t>(f + k)] += w[k] * g[r] / n;
  }
  return rows;
}

JointRange jointMapSupport(std::vector<double> q, double window, double period) {
  if (q.empty() || !(window > 0) || !std::isfinite(window))
    throw ArgumentError("joint map support: expected fit values and a positive, finite window");
  if (!(period == 0 || (std::isfinite(period) && period > 0)))
    throw ArgumentError("joint map support: expected a period of 0 (none) or > 0, got " + std::to_string(period));
  if (period > 0) {
    // the values as angles of one turn, starting after the widest gap between neighbouring
    // angles (a value already within one turn of that start is left as it is, bit for bit)
    std::vector<std::pair<double, double>> angle(q.size());  // (angle in [0, period), value)
    for (size_t i = 0; i < q.size(); ++i) angle[i] = {q[i] - period * std::floor(q[i] / period), q[i]};
    std::sort(angle.begin(), angle.end());
    size_t start = 0;
    double widest = angle.front().first + period - angle.back().first;  // the gap across the turn's end
    for (size_t i = 1; i < angle.size(); ++i)
      if (angle[i].first - angle[i - 1].first > widest) {
        widest = angle[i].first - angle[i - 1].first;
        start = i;
      }
    const double from = angle[start].second;
    for (double& v : q) v -= period * std::floor((v - from) / period);
  }
  std::sort(q.begin(), q.end());
  const JointRange all{q.front(), q.back()};
  const double width = all.upper - all.lower;
  if (!(width > window)) return all;
  const size_t need = std::max<size_t>(2, static_cast<size_t>(std::ceil(0.2 * double(q.size()) * window / width)));
  JointRange r = all;
  for (size_t i = 0; i < q.size(); ++i) {  // the lowest value with `need` values within one window above it
    const size_t j = static_cast<size_t>(std::upper_bound(q.begin(), q.end(), q[i] + window) - q.begin());
    if (j - i >= need) {
      r.lower = q[i];
      break;
    }
  }
  for (size_t i = q.size(); i-- > 0;) {  // the highest value with `need` values within one window below it
    const size_t j = static_cast<size_t>(std::lower_bound(q.begin(), q.end(), q[i] - window) - q.begin());
    if (i + 1 - j >= need) {
      r.upper = q[i];
      break;
    }
  }
  return r.upper - r.lower >= 2 * window ? r : all;
}

bool jointMapCovers(const JointRange& coverage, const JointRange& support, double need, double* width) {
  const double w = std::min(coverage.upper - coverage.lower, support.upper - support.lower);
  if (width) *width = w;
  return coverage.upper - coverage.lower >= need && w >= std::min(need, 2 * kJointMapSupportWindow);
}

double fitRangePeriod(const RobotModel& model, int j) {
  if (j < 0 || j >= model.dof())
    throw ArgumentError("fitRangePeriod: expected a joint index 0.." + std::to_string(model.dof() - 1) + ", got " + std::to_string(j));
  const size_t J = static_cast<size_t>(j);
  const Deviations& d = model.deviations;
  if (model.nominal.joints[J].type != JointType::kRevolute) return 0.0;
  if (J < d.joint_scale.size() && d.joint_scale[J] != 0) return 0.0;
  if (J < d.joint_map.size() && !d.joint_map[J].empty() && d.joint_map[J].period == 0) return 0.0;
  return 360.0;
}

double beyondFitRange(const JointRange& c, double q, double period) {
  if (period > 0 && c.upper - c.lower >= period) return 0.0;  // every angle of a turn is covered
  if (period > 0) {
    const double centre = 0.5 * (c.lower + c.upper);
    q = centre + std::remainder(q - centre, period);
  }
  return q < c.lower ? c.lower - q : (q > c.upper ? q - c.upper : 0.0);
}

bool periodicTermHoldsOverLimits(const JointSpec& joint, double lower, double upper) {
  if (joint.type != JointType::kRevolute) return false;
  const double width = upper - lower;
  if (width >= kPeriodicCoverageDeg) return true;
  if (!(joint.upper > joint.lower)) return false;  // no limits known: the rest of the turn may be reached
  const double beyond = std::max(lower - joint.lower, joint.upper - upper);
  return width > 0 && beyond <= kPeriodicLimitShare * width;
}

std::vector<OutsideFitRange> outsideFitRanges(const RobotModel& model, const Eigen::VectorXd& q) {
  const int n = model.dof();
  if (q.size() != n)
    throw ArgumentError("outsideFitRanges: expected " + std::to_string(n) + " joint values, got " + std::to_string(q.size()));
  const Deviations& d = model.deviations;
  auto nonzero = [](const std::vector<double>& v, size_t from, size_t count) {
    for (size_t k = from; k < from + count && k < v.size(); ++k)
      if (v[k] != 0) return true;
    return false;
  };
  bool compliance = false;
  for (double c : d.compliance) compliance = compliance || c != 0;
  std::vector<OutsideFitRange> out;
  for (int j = 0; j < n; ++j) {
    const size_t J = static_cast<size_t>(j), H = static_cast<size_t>(d.gear_harmonics);
    const bool map = J < d.joint_map.size() && !d.joint_map[J].empty();
    const bool depends = compliance || map || nonzero(d.gear_sin, J * H, H) || nonzero(d.gear_cos, J * H, H) ||
                         nonzero(d.joint_scale, J, 1);
    if (!depends) continue;
    double lo = 0, hi = 0;
    if (J < d.fit_range.size() && d.fit_range[J].upper > d.fit_range[J].lower) {
      lo = d.fit_range[J].lower;
      hi = d.fit_range[J].upper;
    } else if (map) {
      lo = d.joint_map[J].lower;
      hi = d.joint_map[J].upper;
    } else {
      continue;
    }
    const double beyond = beyondFitRange({lo, hi}, q[j], fitRangePeriod(model, j));
    if (beyond > kFitRangeTolerance) out.push_back({j + 1, q[j], lo, hi, beyond});
  }
  return out;
}

std::string outsideFitRangeMessage(const RobotModel& model, const std::string& what,
                                   const std::vector<OutsideFitRange>& outside) {
  if (outside.empty()) return {};
  std::string list;
  for (const OutsideFitRange& x : outside) {
    const bool known = x.joint >= 1 && x.joint <= model.dof();
    const JointSpec* joint = known ? &model.nominal.joints[static_cast<size_t>(x.joint - 1)] : nullptr;
    const std::string unit = joint && joint->type == JointType::kPrismatic ? " mm" : " deg";
    list += std::string(list.empty() ? " " : "; ") + "joint " + std::to_string(x.joint) +
            (joint && !joint->name.empty() ? " (" + joint->name + ")" : std::string()) + " at " + formatFixed(x.q, 2) + unit +
            " (fitted " + formatFixed(x.lower, 2) + ".." + formatFixed(x.upper, 2) + unit + ", " + formatFixed(x.beyond, 2) + unit +
            " beyond)";
  }
  return what + " lies outside the joint ranges the model was fitted on:" + list + " (its joint-dependent effects are not fitted there)";
}

bool parseJointMapKnot(const std::string& text, double* knot, std::string* unit, std::string* error) {
  std::string num = text, u;
  for (const char* suffix : {"deg", "mm"}) {
    const std::string s(suffix);
    if (text.size() > s.size() && text.compare(text.size() - s.size(), s.size(), s) == 0) {
      num = text.substr(0, text.size() - s.size());
      u = s;
      break;
    }
  }
  char* end = nullptr;
  const double v = std::strtod(num.c_str(), &end);
  if (num.empty() || end == num.c_str() || *end != '\0' || !std::isfinite(v) || !(v > 0)) {
    *error = "joint map knot spacing: expected a positive number with an optional unit deg or mm (e.g. 3deg), found '" +
             text + "'";
    return false;
  }
  *knot = v;
  *unit = u;
  return true;
}

}  // namespace accura::calib

namespace accura::calib {

namespace {

// Solves N delta = -b with a tiny ridge (parameters the data leave undetermined stay at the
// linearisation point); N: the lower triangle of the symmetric matrix, overwritten. rebuild()
// writes the lower triangle again (for the fallback).
template <class Rebuild>
Eigen::VectorXd solveRidged(Eigen::MatrixXd& N, const Eigen::VectorXd& b, const Rebuild& rebuild) {
  const double ridge = 1e-10 * std::max(N.diagonal().maxCoeff(), 1e-300);
  N.diagonal().array() += ridge;
  // Cholesky in place on the lower triangle (several times faster than LDLT at the maps' sizes,
  // and no copy of the matrix)
  if (detail::choleskyInPlace(N)) {
    Eigen::VectorXd delta = -b;
    detail::choleskySolveInPlace(N, delta);
    return delta;
  }
  // not quite positive definite in the rounding: LDLT on the matrix again (it reads the lower
  // triangle)
  rebuild(N);
  N.diagonal().array() += ridge;
  Eigen::LDLT<Eigen::MatrixXd> ldlt(N);
  return Eigen::VectorXd(-ldlt.solve(b));
}

}  // namespace

JointMapCvResult crossValidateJointMap(const std::vector<JointMapCvRow>& rows, const std::vector<JointRange>& ranges,
                                       const std::vector<double>& periods,
                                       const std::vector<int>& centred_harmonics, const std::vector<double>& knots,
                                       const std::vector<double>& smoothings, int folds) {
  if (centred_harmonics.size() != ranges.size() || periods.size() != ranges.size())
    throw ArgumentError("joint map cross-validation: expected one period and one harmonics count per mapped joint, got " +
                        std::to_string(periods.size()) + " and " + std::to_string(centred_harmonics.size()) + " for " +
                        std::to_string(ranges.size()) + " joints");
  if (rows.empty() || knots.empty() || smoothings.empty() || folds < 2)
    throw ArgumentError("joint map cross-validation: expected rows, candidates and >= 2 folds");
  const Eigen::Index p = rows[0].G.cols();
  const int J = static_cast<int>(ranges.size());
  for (const auto& r : rows)
    if (r.G.cols() != p || r.U.cols() != J || r.q.size() != J || r.G.rows() != r.r.size() ||
        r.U.rows() != r.r.size() || r.fold < 0 || r.fold >= folds)
      throw ArgumentError("joint map cross-validation: inconsistent row sizes");
  JointMapCvResult result;

  // Held-out position sum of squares (mm^2) of the solution delta of (N, b) on fold f.
  auto heldOut = [&](const std::vector<JointMap>& maps, const std::vector<Eigen::Index>& col0, int f,
                     const Eigen::VectorXd& delta) {
    double ss = 0;
    double w[4];
    for (const auto& row : rows) {
      if (row.fold != f) continue;
      Eigen::VectorXd e = row.r + row.G * delta.head(p);
      for (int j = 0; j < J && !maps.empty(); ++j) {
        const int first = jointMapBasis(maps[static_cast<size_t>(j)], row.q[j], w);
        for (int k = 0; k < 4; ++k) e += row.U.col(j) * (w[k] * delta[col0[static_cast<size_t>(j)] + first + k]);
      }
      ss += e.head<3>().cwiseQuotient(row.w_pos).squaredNorm();
    }
    return ss;
  };
  // baseline: no maps. Its solution on each fold's training rows is also the first stage of
  // the fit with maps: the maps are fitted to what the other parameters leave, those held
  // (identify, docs/diagnosis.md)
  std::vector<Eigen::VectorXd> delta_g(static_cast<size_t>(folds));
  {
    std::vector<Eigen::MatrixXd> Nf(static_cast<size_t>(folds), Eigen::MatrixXd::Zero(p, p));
    std::vector<Eigen::VectorXd> bf(static_cast<size_t>(folds), Eigen::VectorXd::Zero(p));
    for (const auto& row : rows) {
      Nf[static_cast<size_t>(row.fold)] += row.G.transpose() * row.G;
      bf[static_cast<size_t>(row.fold)] += row.G.transpose() * row.r;
    }
    Eigen::MatrixXd Nt = Eigen::MatrixXd::Zero(p, p);
    Eigen::VectorXd bt = Eigen::VectorXd::Zero(p);
    for (int f = 0; f < folds; ++f) {
      Nt += Nf[static_cast<size_t>(f)];
      bt += bf[static_cast<size_t>(f)];
    }
    double ss = 0;
    for (int f = 0; f < folds; ++f) {
      auto train = [&](Eigen::MatrixXd& N) { N = Nt - Nf[static_cast<size_t>(f)]; };
      Eigen::MatrixXd N;
      train(N);
      delta_g[static_cast<size_t>(f)] = solveRidged(N, bt - bf[static_cast<size_t>(f)], train);
      ss += heldOut({}, {}, f, delta_g[static_cast<size_t>(f)]);
    }
    result.baseline_rms_mm = std::sqrt(ss / double(rows.size()));
  }

  result.best_rms_mm = std::numeric_limits<double>::infinity();
  // coarse to fine: the widest spacing first; a finer one only while the last one gained
  std::vector<double> order = knots;
  std::sort(order.begin(), order.end(), std::greater<double>());
  order.erase(std::unique(order.begin(), order.end()), order.end());
  double wider_best_ss = std::numeric_limits<double>::infinity();
  // the (n x n) matrices, kept from one knot spacing to the next (lower triangles): the normal
  // equations of all rows, a fold's training system, the workspace factorised
  Eigen::MatrixXd Nt, Ntrain, Nwork;
  for (size_t ki = 0; ki < order.size(); ++ki) {
    const double knot = order[ki];
    std::vector<JointMap> maps;
    std::vector<Eigen::Index> col0;
    Eigen::Index n = p;
    for (const JointRange& r : ranges) {
      maps.push_back(makeJointMap(r.lower, r.upper, knot, periods[maps.size()]));
      col0.push_back(n);
      n += static_cast<Eigen::Index>(maps.back().coef.size());
    }
    // the normal equations of all rows, lower triangle only (Cholesky reads no more),
    // accumulated row by row from each row's compact columns (its p, and 4 per joint: idx
    // ascending); a fold's training system is then this minus the fold's own rows (one matrix
    // per fold would be 5 x 10 MB at 2 deg)
    const Eigen::Index nc = p + 4 * J;
    std::vector<Eigen::Index> idx(static_cast<size_t>(nc));
    for (Eigen::Index c = 0; c < p; ++c) idx[static_cast<size_t>(c)] = c;
    Eigen::MatrixXd Ct(nc, rows[0].r.size());  // the row's columns, transposed
    double w[4];
    auto columns = [&](const JointMapCvRow& row) {
      const Eigen::Index dim = row.r.size();
      if (Ct.cols() != dim) Ct.resize(nc, dim);
      Ct.topRows(p) = row.G.transpose();
      for (int j = 0; j < J; ++j) {
        const int first = jointMapBasis(maps[static_cast<size_t>(j)], row.q[j], w);
        for (int k = 0; k < 4; ++k) {
          Ct.row(p + 4 * j + k) = row.U.col(j).transpose() * w[k];
          idx[static_cast<size_t>(p + 4 * j + k)] = col0[static_cast<size_t>(j)] + first + k;
        }
      }
    };
    Nt.setZero(n, n);
    std::vector<Eigen::VectorXd> bf(static_cast<size_t>(folds), Eigen::VectorXd::Zero(n));
    for (const auto& row : rows) {
      columns(row);
      Eigen::VectorXd& b = bf[static_cast<size_t>(row.fold)];
      for (Eigen::Index a = 0; a < nc; ++a) b[idx[static_cast<size_t>(a)]] += Ct.row(a).dot(row.r);
      detail::scatterGramLower(Nt.data(), Nt.outerStride(), Ct.data(), nc, static_cast<int>(row.r.size()), idx.data());
    }
    Eigen::VectorXd bt = Eigen::VectorXd::Zero(n);
    for (int f = 0; f < folds; ++f) bt += bf[static_cast<size_t>(f)];
    // per joint: the scale of its columns, its smoothness penalty D^T D (banded: its lower
    // band, 3 diagonals)
    std::vector<double> scale2(static_cast<size_t>(J));
    for (int j = 0; j < J; ++j) {
      const Eigen::Index K = static_cast<Eigen::Index>(maps[static_cast<size_t>(j)].coef.size());
      scale2[static_cast<size_t>(j)] = std::max(Nt.diagonal().segment(col0[static_cast<size_t>(j)], K).mean(), 1e-300);
    }
    // the smoothness penalty of smoothing sm on the lower triangle of N, whose first column is
    // the full system's column `first`
    auto addSmoothness = [&](Eigen::MatrixXd& N, double sm, Eigen::Index first) {
      for (int j = 0; j < J; ++j) {
        const Eigen::Index K = static_cast<Eigen::Index>(maps[static_cast<size_t>(j)].coef.size());
        const Eigen::Index c0 = col0[static_cast<size_t>(j)] - first;
        const double s = sm * scale2[static_cast<size_t>(j)];
        // D^T D, D the (K-2) x K second differences (D(k, k..k+2) = 1, -2, 1): entry (a, a+o)
        // = sum over D's rows k = max(a+o-2, 0) .. min(a, K-3) of D(k, a) D(k, a+o)
        const double d[3] = {1, -2, 1};
        for (Eigen::Index a = 0; a < K; ++a)
          for (Eigen::Index o = 0; o <= 2 && a + o < K; ++o) {
            double v = 0;
            for (Eigen::Index k = std::max<Eigen::Index>(a + o - 2, 0); k <= std::min(a, K - 3); ++k) v += d[a - k] * d[a + o - k];
            if (v != 0) N(c0 + a + o, c0 + a) += s * v;
          }
      }
    };
    const size_t first_entry = result.table.size();
    for (double sm : smoothings) result.table.push_back({knot, sm, 0.0});
    for (int f = 0; f < folds; ++f) {
      // the training system: all rows' less the fold's own, with the centring taken on the
      // training rows
      Ntrain.resize(n, n);
      Ntrain.triangularView<Eigen::Lower>() = Nt;
      for (const auto& row : rows) {
        if (row.fold != f) continue;
        columns(row);
        detail::scatterGramLower(Ntrain.data(), Ntrain.outerStride(), Ct.data(), nc, static_cast<int>(row.r.size()), idx.data(), -1.0);
      }
      const Eigen::VectorXd btrain = bt - bf[static_cast<size_t>(f)];
      for (int j = 0; j < J; ++j) {
        std::vector<double> qt;
        for (const auto& row : rows)
          if (row.fold != f) qt.push_back(row.q[j]);
        const Eigen::Index K = static_cast<Eigen::Index>(maps[static_cast<size_t>(j)].coef.size());
        const double W = kJointMapCentringWeight * kJointMapCentringWeight * scale2[static_cast<size_t>(j)];
        for (const auto& a : jointMapCentringRows(maps[static_cast<size_t>(j)], qt, centred_harmonics[static_cast<size_t>(j)])) {
          const Eigen::VectorXd av = Eigen::Map<const Eigen::VectorXd>(a.data(), K);
          if (av.norm() == 0) continue;
          Ntrain.block(col0[static_cast<size_t>(j)], col0[static_cast<size_t>(j)], K, K).selfadjointView<Eigen::Lower>().rankUpdate(
              av, W / av.squaredNorm());
        }
        for (const auto& a : jointMapSparseRows(maps[static_cast<size_t>(j)], qt))
          for (Eigen::Index k = 0; k < K; ++k)
            if (a[static_cast<size_t>(k)] != 0)
              Ntrain(col0[static_cast<size_t>(j)] + k, col0[static_cast<size_t>(j)] + k) += kJointMapSparseWeight * kJointMapSparseWeight * scale2[static_cast<size_t>(j)];
      }
      // the maps' right-hand side with the fold's first stage held
      const Eigen::Index nq = n - p;
      const Eigen::VectorXd bq = btrain.tail(nq) + Ntrain.bottomLeftCorner(nq, p) * delta_g[static_cast<size_t>(f)];
      for (size_t si = 0; si < smoothings.size(); ++si) {
        // the maps' block of the training system (lower triangle) with the smoothness penalty
        auto train = [&](Eigen::MatrixXd& N) {
          N.resize(nq, nq);
          N.triangularView<Eigen::Lower>() = Ntrain.bottomRightCorner(nq, nq);
          addSmoothness(N, smoothings[si], p);
        };
        train(Nwork);
        Eigen::VectorXd dl(n);
        dl.head(p) = delta_g[static_cast<size_t>(f)];
        dl.tail(nq) = solveRidged(Nwork, bq, train);
        result.table[first_entry + si].cv_rms_mm += heldOut(maps, col0, f, dl);
      }
    }
    // (the table holds sums of squares until the end)
    double best_ss = std::numeric_limits<double>::infinity();
    for (size_t e = first_entry; e < result.table.size(); ++e) best_ss = std::min(best_ss, result.table[e].cv_rms_mm);
    if (!(best_ss < wider_best_ss)) {
      result.knots_not_tried.assign(order.begin() + static_cast<std::ptrdiff_t>(ki) + 1, order.end());
      break;
    }
    wider_best_ss = best_ss;
  }
  for (auto& c : result.table) {
    c.cv_rms_mm = std::sqrt(c.cv_rms_mm / double(rows.size()));
    if (c.cv_rms_mm < result.best_rms_mm) {
      result.best_rms_mm = c.cv_rms_mm;
      result.knot = c.knot;
      result.smoothing = c.smoothing;
    }
  }
  return result;
}

}  // namespace accura::calib
