// accura: the verdict of the diagnosis (diagnose.h, docs/diagnosis.md).
#include "diagnose_internal.h"

#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <numeric>
#include <set>

#include "accura/calib/errors.h"
#include "accura/calib/identify.h"
#include "accura/calib/kinematics.h"

namespace accura::calib {
namespace diagnose_detail {

// A selected effect whose paired test against the model without it reaches this z is named as a
// cause however small its share of the drop (one-sided p 3e-5: beyond the multiple testing of the
// forward selection).
constexpr double kNamedCauseZ = 4.0;
// The share of the gap (baseline MSE above the expected) from which the selected effects are its
// cause even when a structured rest remains (selfcheck: a catalogued effect leaves 0.1-5% of it,
// partly, in a joint the selection did not take; an effect outside the catalogue that a
// catalogued one explains in part leaves 6.5% or more)
constexpr double kCauseShare = 0.95;

void Diagnoser::verdict() {
  const std::vector<std::string>& order = order_;
  std::map<std::string, std::vector<int>>& blocks_of = blocks_of_;
  std::map<std::string, double>& drop_of = drop_of_;
  if (!out_.noise_floor_known) {
    // upper bound: the fit residual of the geometric model plus every testable effect
    std::vector<int> all_blocks(blocks_.size());
    std::iota(all_blocks.begin(), all_blocks.end(), 0);
    const std::vector<int> S = withBlocks(all_blocks);
    Eigen::VectorXd x = fitAll(S, nullptr, nullptr);
    const Eigen::VectorXd e = rF_ - JF_(Eigen::all, S) * x;
    const double dof = std::max(1.0, 3.0 * m_ - double(S.size()));
    out_.noise_std_axis_mm = std::sqrt(e.squaredNorm() / dof);
    out_.noise_floor_mm = std::sqrt(3.0) * out_.noise_std_axis_mm;
  }
  // verdict
  Verdict& v = out_.verdict;
  v.validation_rms_after_mm = final_stats_.rms_mm;
  bool structured = false;
  std::vector<const Correlation*> corr;
  {
    const double thr = o_.alpha / double(std::max<size_t>(1, out_.correlations.size()));
    for (const Correlation& c : out_.correlations)
      if (c.p_after < thr && c.r2_after >= 0.05) corr.push_back(&c);
    std::sort(corr.begin(), corr.end(), [](const Correlation* a, const Correlation* b) { return a->r2_after > b->r2_after; });
    structured = !corr.empty();
  }
  // the per-joint spectrum of the final residual: a peak significant after the Bonferroni
  // correction over every joint and k, carrying at least 5% of the joint-projected variance
  std::vector<const JointSpectrum*> peaks;
  for (const JointSpectrum& sp : out_.spectra)
    if (sp.peak_p < o_.alpha && sp.peak_share >= 0.05) peaks.push_back(&sp);
  std::sort(peaks.begin(), peaks.end(), [](const JointSpectrum* a, const JointSpectrum* b) { return a->peak_share > b->peak_share; });
  structured = structured || !peaks.empty();
  // Unexplained: above the noise floor, and structured: a variable of the pose or context
  // predicts it, or it is large (its excess over the expected RMS, in quadrature, is at least
  // the noise floor). Without a noise floor: when the structure scan finds a predictor.
  // (The excess is taken against the upper 95% confidence bound of the noise variance when
  // the floor is estimated from repeated poses: chi^2 quantile by Wilson-Hilferty.)
  double expected_ms = std::isfinite(final_stats_.expected_rms_mm) ? final_stats_.expected_rms_mm * final_stats_.expected_rms_mm : 0.0;
  if (std::isfinite(out_.noise_floor_dof)) {
    const double nu = out_.noise_floor_dof;
    const double c = 1.0 - 2.0 / (9.0 * nu) - 1.645 * std::sqrt(2.0 / (9.0 * nu));
    const double upper = c > 0.05 ? 1.0 / (c * c * c) : 20.0;  // nu / chi^2_{nu, 0.05}
    expected_ms += (upper - 1.0) * out_.noise_floor_mm * out_.noise_floor_mm;
  }
  const double excess_mm = std::sqrt(std::max(0.0, final_stats_.rms_mm * final_stats_.rms_mm - expected_ms));
  const bool large = excess_mm >= out_.noise_floor_mm;
  const bool significant_excess = out_.noise_floor_known && final_stats_.floor_p < o_.floor_alpha;
  // With nothing selected, a variable of the scan that predicts the held-out residual (its own
  // test, Bonferroni over the variables) says by itself that the residual is not noise: "the
  // geometry explains the data down to the noise" would be false, though a small excess (a
  // coupling of 0.035 mm beside a floor of 0.087 mm) does not reach the floor test's p < 0.001.
  above_floor_ = out_.noise_floor_known ? (significant_excess && (structured || large)) || (order.empty() && !corr.empty())
                                        : structured;
  // share of the gap (baseline MSE above what the floor and the parameters explain) that the
  // selected effects take away
  {
    const double b2 = out_.baseline.rms_mm * out_.baseline.rms_mm, f2 = final_stats_.rms_mm * final_stats_.rms_mm;
    const double gap = b2 - expected_ms;
    v.explained_share = gap > 0 ? std::clamp((b2 - f2) / gap, 0.0, 1.0) : 0.0;
  }
  // Selected effects that take kCauseShare or more of the gap are its cause: a rest of a few
  // percent, structured or not, is said in the explanation, not made the verdict (`unexplained`
  // would have most of the gap remain, which it does not). Below it, a structured excess makes
  // the explanation partial.
  const bool rest_small = !order.empty() && v.explained_share >= kCauseShare;
  const bool small_rest_structured = rest_small && above_floor_;
  if (rest_small) above_floor_ = false;
  std::string after = order.empty() ? std::string("the complete geometric model") : "the geometric model plus ";
  for (size_t k = 0; k < order.size(); ++k) after += (k ? ", " : "") + order[k];
  const std::string against =
      out_.noise_floor_known
          ? "held-out RMS " + fmtg("%.4f", final_stats_.rms_mm) + " mm against " + fmtg("%.4f", final_stats_.expected_rms_mm) +
                " mm expected from the noise floor and the parameter uncertainty (z = " + fmtg("%.1f", final_stats_.floor_z) + ")"
          : "held-out RMS " + fmtg("%.4f", final_stats_.rms_mm) + " mm; the noise floor is unknown";
  for (const Correlation* c : corr) {
    std::string s = c->variable + " (R2 " + fmtg("%.2f", c->r2_after);
    if (c->via_joint_after > 0) s += ", acting like a motion of joint " + std::to_string(c->via_joint_after);
    else s += ", acting like a translation";
    v.correlates.push_back(s + ")");
    if (v.correlates.size() >= 4) break;
  }
  for (const JointSpectrum* sp : peaks) {
    if (v.correlates.size() >= 6) break;
    v.correlates.push_back("q" + std::to_string(sp->joint) + " at " + std::to_string(sp->peak_cycles) + " cycles/rev (" +
                           fmtg("%.0f", sp->peak_amplitude_urad) + " urad, " + fmtg("%.0f", 100 * sp->peak_share) +
                           "% of the residual projected on joint " + std::to_string(sp->joint) + ", p " + fmtg("%.2g", sp->peak_p) + ")");
  }
  std::string followed;  // the correlates, as the explanations name them
  for (const std::string& c : v.correlates) followed += (followed.empty() ? "" : "; ") + c;
  if (above_floor_) {
    v.effect = "unexplained";
    std::set<int> js;
    if (!corr.empty() && corr[0]->via_joint_after > 0) js.insert(corr[0]->via_joint_after);
    v.joints.assign(js.begin(), js.end());
    v.explanation = "after " + after + ", a structured residual remains that no catalogued effect explains: " + against + ".";
    if (out_.noise_floor_known && !significant_excess)
      v.explanation += " The excess alone is within what noise could give (floor test p " + fmtg("%.2g", final_stats_.floor_p) +
                       "); that variables of the pose predict the residual is what shows it is not noise.";
    if (!v.correlates.empty()) {
      v.explanation += " It follows " + followed + ".";
    } else {
      v.explanation += " No single variable of the pose or context predicts it.";
    }
    if (!order.empty()) {
      v.effects = order;
      const double rest = std::sqrt(std::max(0.0, final_stats_.rms_mm * final_stats_.rms_mm - expected_ms));
      v.explanation += " Partial explanation: " + after.substr(std::string("the geometric model plus ").size()) + " explain " +
                       fmtg("%.0f", 100 * v.explained_share) + "% of the gap (held-out RMS " + fmtg("%.4f", out_.baseline.rms_mm) +
                       " -> " + fmtg("%.4f", final_stats_.rms_mm) + " mm); the rest, " + fmtg("%.4f", rest) +
                       " mm in quadrature above the floor, is unexplained; do not take them for the cause.";
    }
  } else if (order.empty()) {
    v.effect = "none";
    if (significant_excess)
      v.explanation = "slightly above the noise floor (" + fmtg("%.4f", excess_mm) +
                      " mm in quadrature) but without structure: ";
    v.explanation += "the complete geometric model explains the data down to the noise: " + against + "; no catalogued effect improves the held-out error significantly.";
  } else {
    std::string best = order[0];
    for (const std::string& e : order)
      if (drop_of[e] > drop_of[best]) best = e;
    v.effect = best;
    // every selected effect that takes at least 10% of the total drop is named as a cause, and
    // one whose own gain is beyond doubt (z >= kNamedCauseZ in its selection test, where a small
    // effect beside a large one can take less than a tenth of the drop: a compliance of a few
    // micrometres beside a backlash of a tenth of a millimetre)
    double total = 0;
    for (const std::string& e : order) total += std::max(0.0, drop_of[e]);
    auto selectedZ = [&](const std::string& e) {
      double z = 0;
      for (const EffectEvidence& ev : out_.selected)
        if (ev.effect == e) z = std::max(z, ev.z);
      return z;
    };
    v.effects.push_back(best);
    for (const std::string& e : order)
      if (e != best && total > 0 &&
          (drop_of[e] >= 0.1 * total || std::sqrt(std::max(0.0, drop_of[e])) >= out_.noise_floor_mm || selectedZ(e) >= kNamedCauseZ))
        v.effects.push_back(e);
    for (int b : blocks_of[best])
      if (blocks_[b].joint >= 0) v.joints.push_back(blocks_[b].joint + 1);
    std::sort(v.joints.begin(), v.joints.end());
    std::string also;
    for (size_t k = 1; k < v.effects.size(); ++k) also += (k > 1 ? ", " : "") + v.effects[k];
    v.explanation = best + (v.joints.empty() ? std::string() : " (" + jointList(v.joints) + ")") +
                    (also.empty() ? "" : " and " + also + " together cause the gap (" + best + " the largest part)") +
                    (also.empty() ? " causes the largest part of the gap" : "") + ": held-out RMS " + fmtg("%.4f", out_.baseline.rms_mm) + " -> " +
                    fmtg("%.4f", final_stats_.rms_mm) + " mm with " + after + "; " + against + ".";
    if (small_rest_structured) {
      v.explanation += " What remains is above the noise floor (" + fmtg("%.4f", excess_mm) + " mm in quadrature, " +
                       fmtg("%.0f", 100 * (1 - v.explained_share)) + "% of the gap) and follows " +
                       (followed.empty() ? std::string("no single variable") : followed) + ": a small rest the selected effects do not take.";
    } else if (significant_excess) {
      v.explanation += " What remains is slightly above the noise floor (" + fmtg("%.4f", excess_mm) +
                       " mm in quadrature) but follows no variable of the pose or context.";
    }
    for (const Confounding& c : out_.confounded) {
      if (!c.indistinguishable) continue;
      if (c.effect_a == best) v.confounded_with.push_back(c.effect_b);
      if (c.effect_b == best) v.confounded_with.push_back(c.effect_a);
    }
    if (!v.confounded_with.empty()) {
      v.explanation += " Confounded: this data cannot tell it from ";
      for (size_t k = 0; k < v.confounded_with.size(); ++k) v.explanation += (k ? ", " : "") + v.confounded_with[k];
      v.explanation += " (see `confounded` for the measurements that would separate them).";
    }
  }
  v.explanation += coverageLimitedSentence();
}

std::string Diagnoser::coverageLimitedSentence() const {
  // Coverage-limited: effects that gain on the joint range the fit data cover but would be
  // extrapolated over the rest of it (carriesOver); the reason of each is in `rejected`.
  std::map<std::string, std::set<int>> limited_joints;
  for (const Rejected& r : out_.rejected) {
    std::string why;
    for (const Block& B : blocks_)
      if (B.effect == r.effect && std::find(r.joints.begin(), r.joints.end(), B.joint + 1) != r.joints.end() &&
          !carriesOver(B, &why))
        limited_joints[r.effect].insert(B.joint + 1);
  }
  std::string limited;
  for (const auto& kv : limited_joints)
    limited += (limited.empty() ? "" : ", ") + kv.first + " (" + jointList({kv.second.begin(), kv.second.end()}) + ")";
  if (limited.empty()) return "";
  return " Coverage-limited: " + limited +
         " gain on the joint range the fit data cover but are not selected: fitted there, they would be "
         "extrapolated over the rest of the joint's range (see `rejected`); measure the joint's whole range.";
}

}  // namespace diagnose_detail
}  // namespace accura::calib
