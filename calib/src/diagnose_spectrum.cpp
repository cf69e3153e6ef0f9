// accura: where real errors hide (diagnose.h, docs/diagnosis.md): the per-joint spectrum of the
// residual (its projection onto each joint's angle, amplitude against cycles per revolution)
// and the orientation residual of 6D data.
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>

#include "accura/calib/geometry.h"
#include "accura/calib/identify.h"
#include "diagnose_internal.h"

namespace accura::calib {
namespace diagnose_detail {

namespace {

// Survival function of Fisher's F distribution with (2, nu) degrees of freedom (closed form).
double fTail2(double f, double nu) { return f > 0 ? std::pow(1.0 + 2.0 * f / nu, -0.5 * nu) : 1.0; }

struct Periodogram {
  std::vector<double> amp_urad, share, p;  // per k = 1..K
};

// x_i (rad) with weights w_i, regressed on [1, cos k q, sin k q] for each k: amplitude, share of
// the weighted variance explained, and the F test's p value (not yet corrected).
Periodogram periodogram(const Eigen::VectorXd& x, const Eigen::VectorXd& w, const Eigen::VectorXd& q, int K) {
  Periodogram out;
  const Eigen::Index N = x.size();
  const double W = w.sum();
  const double xm = w.dot(x) / W;
  const Eigen::VectorXd xc = x.array() - xm;
  const double T = (w.array() * xc.array().square()).sum();
  for (int k = 1; k <= K; ++k) {
    const Eigen::VectorXd c = (double(k) * q).array().cos(), s = (double(k) * q).array().sin();
    // weighted, centred basis: the constant is projected out
    const Eigen::VectorXd cc = c.array() - w.dot(c) / W, sc = s.array() - w.dot(s) / W;
    Eigen::Matrix2d A;
    A << (w.array() * cc.array() * cc.array()).sum(), (w.array() * cc.array() * sc.array()).sum(),
        (w.array() * cc.array() * sc.array()).sum(), (w.array() * sc.array() * sc.array()).sum();
    const Eigen::Vector2d b((w.array() * cc.array() * xc.array()).sum(), (w.array() * sc.array() * xc.array()).sum());
    Eigen::Vector2d ab = Eigen::Vector2d::Zero();
    if (A.determinant() > 1e-12 * A.trace() * A.trace()) ab = A.ldlt().solve(b);
    const double ss = std::max(0.0, ab.dot(b));
    const double nu = double(N) - 3.0;
    const double F = T > ss && nu > 0 ? (ss / 2.0) / ((T - ss) / nu) : 0.0;
    out.amp_urad.push_back(ab.norm() * 1e6);
    out.share.push_back(T > 0 ? ss / T : 0.0);
    out.p.push_back(nu > 0 ? fTail2(F, nu) : 1.0);
  }
  return out;
}

}  // namespace

void Diagnoser::spectra() {
  const MeasurementSet& set = has_val_ ? val_ : fit_;
  const int n = M0_.dof();
  const int N = static_cast<int>(set.rows.size());
  const int K = o_.spectrum_max_cycles;
  if (K < 1 || N < 10) return;
  std::vector<Eigen::Matrix<double, 3, Eigen::Dynamic>> Jq(static_cast<size_t>(N));
  KinematicWorkspace ws;
  for (int i = 0; i < N; ++i) {
    const Measurement& r = set.rows[static_cast<size_t>(i)];
    Jq[static_cast<size_t>(i)] = jointJacobian(M0_, r.q, r.context, ws).topRows(3);
  }
  int revolute = 0;
  for (int j = 0; j < n; ++j) revolute += M0_.nominal.joints[static_cast<size_t>(j)].type == JointType::kRevolute;
  const double tests = double(std::max(1, revolute)) * K;  // Bonferroni over every joint and k
  for (int j = 0; j < n; ++j) {
    if (M0_.nominal.joints[static_cast<size_t>(j)].type != JointType::kRevolute) continue;
    Eigen::VectorXd q(N), w(N), x0(N), x1(N);
    for (int i = 0; i < N; ++i) {
      const Eigen::Vector3d g = Jq[static_cast<size_t>(i)].col(j) * kRadToDeg;  // mm per rad
      q[i] = set.rows[static_cast<size_t>(i)].q[j] * kDegToRad;
      w[i] = g.squaredNorm();
      // the joint motion that best explains this pose's residual alone (rad)
      x0[i] = w[i] > 1e-12 ? g.dot(E0_[static_cast<size_t>(i)]) / w[i] : 0.0;
      x1[i] = w[i] > 1e-12 ? g.dot(E1_[static_cast<size_t>(i)]) / w[i] : 0.0;
    }
    // a joint whose axis passes (nearly) through the measured point cannot be seen: a lever arm
    // below 10 mm turns 1 mrad into less than 0.01 mm
    if (!(std::sqrt(w.mean()) > 10.0) || q.maxCoeff() - q.minCoeff() < 1e-6) continue;
    JointSpectrum sp;
    sp.joint = j + 1;
    sp.range_deg = (q.maxCoeff() - q.minCoeff()) * kRadToDeg;
    for (int k = 1; k <= K; ++k) sp.cycles.push_back(k);
    const Periodogram before = periodogram(x0, w, q, K), after = periodogram(x1, w, q, K);
    sp.amplitude_urad_before = before.amp_urad;
    sp.amplitude_urad_after = after.amp_urad;
    auto peak = [&](const Periodogram& pg, int* k, double* amp, double* share, double* p) {
      // the largest share of the variance (the amplitude alone favours poorly determined k)
      size_t best = 0;
      for (size_t c = 1; c < pg.share.size(); ++c)
        if (pg.share[c] > pg.share[best]) best = c;
      *k = static_cast<int>(best) + 1;
      *amp = pg.amp_urad[best];
      if (share) *share = pg.share[best];
      *p = std::min(1.0, pg.p[best] * tests);
    };
    peak(before, &sp.peak_cycles_before, &sp.peak_amplitude_urad_before, nullptr, &sp.peak_p_before);
    peak(after, &sp.peak_cycles, &sp.peak_amplitude_urad, &sp.peak_share, &sp.peak_p);
    out_.spectra.push_back(sp);
  }
}

// Orientation residual of 6D data on the fit rows, comparable with identify's: the baseline's
// parameter groups (and the final model's, identify_params) identified on the fit rows with
// their orientations (identify() on 6D data: the tool rotation identified with the rest), and
// identify's orientation fit RMS. The diagnosis' own models are fitted on positions alone, so
// the parameters positions barely determine (with the measured point on the last axis, the
// last link's angle, offset and lengths against the tool length: sigmas of degrees and tens of
// millimetres on Series_C) wander to whatever the position noise makes them; their orientation
// residual measured that wandering (6.68 deg on Series_C against identify's 0.057 deg), not the
// robot. NaN when the identification fails or the rows lack orientations.
void Diagnoser::orientation() {
  if (!fit_has_rot_) return;
  MeasurementSet six = fit_;
  six.rows.clear();
  bool std_rot = true;
  for (int i = 0; i < m_; ++i) {
    if (!rot_ok_[static_cast<size_t>(i)]) continue;
    Measurement r = fit_.rows[static_cast<size_t>(i)];
    r.has_orientation = true;
    r.R_world_tcp = R_fit_[static_cast<size_t>(i)];
    std_rot = std_rot && r.std_rot_deg.allFinite();
    six.rows.push_back(r);
  }
  if (six.rows.size() < 30) return;
  six.has_orientation = true;
  six.has_std_orientation = std_rot;
  auto rms = [&](const std::string& params) {
    IdentifyOptions io;
    io.groups.clear();
    std::string g;
    for (char c : params + ",") {
      if (c != ',') {
        g += c;
      } else if (!g.empty()) {
        io.groups.push_back(g);
        g.clear();
      }
    }
    io.joint_map_knot = o_.joint_map_knot;
    io.joint_map_smoothing = o_.joint_map_smoothing;
    try {
      IdentifySummary s;
      identify(start_, six, io, &s);
      return s.fit.has_orientation ? s.fit.rot_rms_deg : kNaN;
    } catch (const std::exception&) {
      return kNaN;  // (the orientation residual is a report, not part of the diagnosis)
    }
  };
  out_.orientation_rms_before_deg = rms("geometric");
  out_.orientation_rms_after_deg =
      out_.identify_params == "geometric" ? out_.orientation_rms_before_deg : rms(out_.identify_params);
}

}  // namespace diagnose_detail
}  // namespace accura::calib
