// accura: the floors of the diagnosis (diagnose.h, docs/diagnosis.md): the instrument's stated
// uncertainty, the repeatability from repeated joint configurations, measurement glitches
// (repeat pairs that disagree grossly), the noise floor the verdict is judged against, and the
// robust weights of the fit rows.
#include <algorithm>
#include <cmath>
#include <numeric>

#include "accura/calib/geometry.h"
#include "diagnose_internal.h"

namespace accura::calib {
namespace diagnose_detail {

namespace {

double median(std::vector<double> v) {
  if (v.empty()) return kNaN;
  const size_t h = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(h), v.end());
  const double hi = v[h];
  if (v.size() % 2) return hi;
  return 0.5 * (hi + *std::max_element(v.begin(), v.begin() + static_cast<long>(h)));
}

// Median of the chi distribution with 3 degrees of freedom: |n| of a 3D standard normal vector.
constexpr double kChi3Median = 1.5382;

}  // namespace

// Repeated configurations of the fit data and of the validation set, each within its own file
// (the validation set is, by the contract of --validate, the same robot from the same station):
// pairs, their distances, glitches, and the pooled within-configuration scatter without them.
// Both files are screened alike against one threshold, glitch_factor times the median distance
// of all their pairs: in a configuration measured twice the pair (which row is wrong cannot be
// told), in one measured three times or more each row against the configuration's robust centre
// (the per-axis median of its points), so that the odd row is named once, not in a pair with
// every other measurement.
void Diagnoser::repeats() {
  Floors& fl = out_.floors;
  fl.repeat_tol = o_.repeat_tol;
  if (fit_.has_std_position && (!has_val_ || val_.has_std_position)) {
    fl.instrument_rms_mm = statedPositionNoiseRms({&fit_, has_val_ ? &val_ : nullptr});
    fl.instrument_known = std::isfinite(fl.instrument_rms_mm);
  }
  struct Source {
    const MeasurementSet* set;
    const std::vector<Eigen::Quaterniond>* R;
    const std::vector<bool>* rot_ok;
    bool validation;
    std::vector<std::vector<int>> groups;
    std::vector<std::pair<int, int>> pairs;
    std::vector<double> dist;
    std::vector<bool> glitch_row;
  };
  std::vector<Source> src;
  src.push_back({&fit_, &R_fit_, &rot_ok_, false, {}, {}, {}, {}});
  src.back().groups = repeatGroups(fit_, o_.repeat_tol, &src.back().pairs, set_of_row_.empty() ? nullptr : &set_of_row_);
  groups_ = src.back().groups;  // the folds keep every row of a configuration together
  if (has_val_) {
    src.push_back({&val_, &R_val_, &rot_ok_val_, true, {}, {}, {}, {}});
    src.back().groups = repeatGroups(val_, o_.repeat_tol, &src.back().pairs);
  }
  // (rows written twice, the same measurement as an earlier row, were left out before: diagnose()
  // with removeDuplicatedRows, Floors::duplicated_rows)
  std::vector<double> dist_all;
  fl.repeat_pairs = 0;
  fl.repeat_min_gap = 1 << 30;
  fl.repeat_max_gap = 0;
  for (Source& sc : src) {
    for (const auto& pr : sc.pairs) {
      sc.dist.push_back((sc.set->rows[pr.first].p_world_mm - sc.set->rows[pr.second].p_world_mm).norm());
      fl.repeat_min_gap = std::min(fl.repeat_min_gap, pr.second - pr.first);
      fl.repeat_max_gap = std::max(fl.repeat_max_gap, pr.second - pr.first);
    }
    dist_all.insert(dist_all.end(), sc.dist.begin(), sc.dist.end());
    fl.repeat_pairs += static_cast<int>(sc.pairs.size());
    if (sc.validation) fl.repeat_pairs_validation = static_cast<int>(sc.pairs.size());
  }
  if (fl.repeat_pairs == 0) fl.repeat_min_gap = 0;
  fl.glitch_threshold_mm = o_.glitch_factor * median(dist_all);
  for (Source& sc : src) {
    const MeasurementSet& set = *sc.set;
    const std::vector<Eigen::Quaterniond>& R = *sc.R;
    sc.glitch_row.assign(set.rows.size(), false);
    auto rotation = [&](int i) { return (*sc.rot_ok)[static_cast<size_t>(i)]; };
    for (const std::vector<int>& g : sc.groups) {
      if (g.size() < 2) continue;
      if (g.size() == 2) {
        const int a = g[0], b = g[1];
        const double d = (set.rows[a].p_world_mm - set.rows[b].p_world_mm).norm();
        if (!(d > fl.glitch_threshold_mm)) continue;
        RepeatPair e;
        e.index_a = a;
        e.index_b = b;
        e.line_a = set.rows[a].line;
        e.line_b = set.rows[b].line;
        e.distance_mm = d;
        e.validation = sc.validation;
        if (rotation(a) && rotation(b)) e.rotation_deg = R[a].angularDistance(R[b]) * kRadToDeg;
        fl.glitches.push_back(e);
        sc.glitch_row[a] = sc.glitch_row[b] = true;
        continue;
      }
      Eigen::Vector3d centre;
      for (int k = 0; k < 3; ++k) {
        std::vector<double> c;
        for (int i : g) c.push_back(set.rows[static_cast<size_t>(i)].p_world_mm[k]);
        centre[k] = median(c);
      }
      std::vector<int> odd, good;
      for (int i : g)
        ((set.rows[static_cast<size_t>(i)].p_world_mm - centre).norm() > fl.glitch_threshold_mm ? odd : good).push_back(i);
      // the orientation of the configuration: the chordal mean of its rows that are not odd
      Eigen::Vector4d qsum = Eigen::Vector4d::Zero();
      int nrot = 0;
      for (int i : good) {
        if (!rotation(i)) continue;
        Eigen::Vector4d q = R[static_cast<size_t>(i)].coeffs();
        if (nrot > 0 && q.dot(qsum) < 0) q = -q;
        qsum += q;
        ++nrot;
      }
      for (int i : odd) {
        RepeatPair e;
        e.index_a = i;
        e.index_b = -1;
        e.line_a = set.rows[static_cast<size_t>(i)].line;
        e.line_b = 0;
        e.distance_mm = (set.rows[static_cast<size_t>(i)].p_world_mm - centre).norm();
        e.measurements = static_cast<int>(g.size());
        e.validation = sc.validation;
        if (rotation(i) && nrot > 0) {
          Eigen::Quaterniond mean;
          mean.coeffs() = qsum.normalized();
          e.rotation_deg = R[static_cast<size_t>(i)].angularDistance(mean) * kRadToDeg;
        }
        fl.glitches.push_back(e);
        sc.glitch_row[static_cast<size_t>(i)] = true;
      }
    }
  }
  std::vector<double> clean;
  for (const Source& sc : src)
    for (size_t k = 0; k < sc.pairs.size(); ++k)
      if (!sc.glitch_row[static_cast<size_t>(sc.pairs[k].first)] && !sc.glitch_row[static_cast<size_t>(sc.pairs[k].second)])
        clean.push_back(sc.dist[k]);
  std::stable_sort(fl.glitches.begin(), fl.glitches.end(),
                   [](const RepeatPair& a, const RepeatPair& b) { return a.distance_mm > b.distance_mm; });
  fl.median_pair_mm = median(clean);
  // pooled within-configuration scatter, glitch rows left out (a configuration measured twice
  // with a glitch pair drops out)
  double ss = 0, dof = 0;
  fl.repeat_groups = 0;
  for (const Source& sc : src) {
    for (const auto& g0 : sc.groups) {
      std::vector<int> g;
      for (int i : g0)
        if (!sc.glitch_row[static_cast<size_t>(i)]) g.push_back(i);
      if (g.size() < 2) continue;
      Eigen::Vector3d mean = Eigen::Vector3d::Zero();
      for (int i : g) mean += sc.set->rows[static_cast<size_t>(i)].p_world_mm;
      mean /= double(g.size());
      for (int i : g) ss += (sc.set->rows[static_cast<size_t>(i)].p_world_mm - mean).squaredNorm();
      dof += 3.0 * double(g.size() - 1);
      ++fl.repeat_groups;
      if (sc.validation) ++fl.repeat_groups_validation;
    }
  }
  fl.repeat_dof = dof;
  if (dof > 0) {
    fl.repeat_std_axis_mm = std::sqrt(ss / dof);
    fl.repeat_rms_mm = std::sqrt(3.0) * fl.repeat_std_axis_mm;
  }
}

void Diagnoser::noiseFloor() {
  repeats();
  const Floors& fl = out_.floors;
  if (has_val_) {
    // The validation set's glitch rows (both rows of a glitch pair: which is wrong cannot be
    // told) are left out of the held-out statistics, as the rows the robust estimation
    // down-weights are under cross-validation; unless fewer than 20 poses would remain.
    std::vector<bool> drop(val_.rows.size(), false);
    for (const RepeatPair& g : fl.glitches)
      if (g.validation) {
        drop[static_cast<size_t>(g.index_a)] = true;
        if (g.index_b >= 0) drop[static_cast<size_t>(g.index_b)] = true;
      }
    const int n_drop = static_cast<int>(std::count(drop.begin(), drop.end(), true));
    if (n_drop > 0 && nv_ - n_drop >= 20) {
      std::vector<Measurement> kept;
      for (size_t i = 0; i < val_.rows.size(); ++i)
        if (!drop[i]) kept.push_back(val_.rows[i]);
      val_.rows = std::move(kept);
      nv_ = static_cast<int>(val_.rows.size());
      out_.validation_poses = nv_;
      out_.validation_glitch_rows_left_out = n_drop;
    }
  }
  // Folds: repeated configurations stay together.
  folds_ = o_.folds;
  fold_.assign(m_, 0);
  for (size_t g = 0; g < groups_.size(); ++g)
    for (int i : groups_[g]) fold_[i] = static_cast<int>(g % static_cast<size_t>(folds_));
  fold_poses_.assign(folds_, {});
  for (int i = 0; i < m_; ++i) fold_poses_[fold_[i]].push_back(i);
  interleaved_.name = "interleaved";
  interleaved_.poses = fold_poses_;
  if (!has_val_) out_.validation_method = std::to_string(folds_) + "-fold cross-validation over the poses of " + fit_.file;
  else out_.validation_method = "validation set " + val_.file;

  double sigma = kNaN;  // per axis
  bool per_row = false;
  if (!std::isnan(o_.noise_std_mm)) {
    sigma = o_.noise_std_mm;
    out_.noise_floor_source = "given: " + fmtg("%.4g", sigma) + " mm per axis";
  } else if (fl.repeat_dof >= 30) {
    sigma = fl.repeat_std_axis_mm;
    out_.noise_floor_dof = fl.repeat_dof;
    out_.noise_floor_source =
        "repeatability: " + std::to_string(fl.repeat_groups) + " joint configurations measured more than once" +
        (fl.repeat_groups_validation > 0
             ? " (" + std::to_string(fl.repeat_groups - fl.repeat_groups_validation) + " in the fit data, " +
                   std::to_string(fl.repeat_groups_validation) + " in the validation set)"
             : std::string()) +
        " (every joint within " + fmtg("%g", fl.repeat_tol) + " deg or mm), pooled scatter " + fmtg("%.4g", sigma) + " mm per axis (" +
        fmtg("%.0f", fl.repeat_dof) + " degrees of freedom), median pair distance " +
        (std::isfinite(fl.median_pair_mm) ? fmtg("%.4f", fl.median_pair_mm) + " mm" : std::string("-")) + ", " +
        std::to_string(fl.glitches.size()) + " glitch(es) left out";
    if (fl.instrument_known)
      out_.noise_floor_source += "; the instrument states " + fmtg("%.4f", fl.instrument_rms_mm) + " mm (std columns)";
  } else if (fit_.has_std_position && (!has_val_ || val_.has_std_position)) {
    per_row = true;
    out_.noise_floor_source = "std columns of the data (the instrument's stated uncertainty)";
  } else {
    out_.noise_floor_known = false;
    out_.noise_floor_source =
        "unknown: no repeated configurations (" + std::to_string(fl.repeat_groups) +
        " found, at least 10 needed), no std columns and no "
        "--noise-mm; estimated from the fit residual of the geometric model plus every testable effect, an upper "
        "bound when an effect outside the catalogue is present; `unexplained` is then judged by the structure scan";
  }
  auto fill = [&](const MeasurementSet& set, std::vector<Eigen::Vector3d>* w, Eigen::VectorXd* var) {
    w->assign(set.rows.size(), Eigen::Vector3d::Ones());
    var->setZero(static_cast<Eigen::Index>(set.rows.size()));
    for (size_t i = 0; i < set.rows.size(); ++i) {
      const Measurement& r = set.rows[i];
      Eigen::Vector3d s = Eigen::Vector3d::Constant(std::isnan(sigma) ? 1.0 : sigma);
      if (set.has_std_position) s = r.std_mm;  // relative weights from the instrument
      (*w)[i] = std::sqrt(r.weight) * s.cwiseInverse();
      const Eigen::Vector3d sf = per_row ? r.std_mm : Eigen::Vector3d::Constant(std::isnan(sigma) ? 0.0 : sigma);
      (*var)[static_cast<Eigen::Index>(i)] = sf.squaredNorm();
      if (&set == &fit_) noise_fit_[i] = sf;
    }
  };
  noise_fit_.assign(fit_.rows.size(), Eigen::Vector3d::Zero());
  fill(fit_, &w_fit_, &var_fit_);
  if (has_val_) fill(val_, &w_val_, &var_val_);
  if (out_.noise_floor_known) {
    const Eigen::VectorXd& v = has_val_ ? var_val_ : var_fit_;
    out_.noise_floor_mm = std::sqrt(v.mean());
    out_.noise_std_axis_mm = out_.noise_floor_mm / std::sqrt(3.0);
  }
}

// Robust weights from the per-pose residual magnitudes (mm) of the fit rows: Huber's rule with a
// robust scale (median |r| / median of chi_3).
void Diagnoser::robustWeights(const std::vector<double>& e) {
  robust_w_.assign(static_cast<size_t>(m_), 1.0);
  out_.downweighted.clear();
  const double s = median(e) / kChi3Median;
  if (!(s > 0)) return;
  const double cut = o_.robust_k * s;
  for (int i = 0; i < m_; ++i) {
    if (!(e[static_cast<size_t>(i)] > cut)) continue;
    robust_w_[static_cast<size_t>(i)] = cut / e[static_cast<size_t>(i)];
    out_.downweighted.push_back({out_.row_files.empty() ? fit_.file : out_.row_files[static_cast<size_t>(i)], fit_.rows[static_cast<size_t>(i)].line, i, e[static_cast<size_t>(i)],
                                 robust_w_[static_cast<size_t>(i)]});
  }
  std::sort(out_.downweighted.begin(), out_.downweighted.end(),
            [](const DownWeighted& a, const DownWeighted& b) { return a.weight < b.weight; });
}

}  // namespace diagnose_detail
}  // namespace accura::calib
