// accura: selection of the diagnosis: forward selection, ranking, confounding, shrink table (diagnose.h, docs/diagnosis.md).
#include "diagnose_internal.h"

#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <algorithm>
#include <limits>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <numeric>
#include <set>

#include "accura/calib/errors.h"
#include "accura/calib/identify.h"
#include "accura/calib/joint_map.h"
#include "accura/calib/kinematics.h"

namespace accura::calib {
namespace diagnose_detail {

// A blocked scheme whose held-out error is worse with the addition at this z (one-sided p 0.01)
// shows harm beyond chance.
constexpr double kHarmZ = 2.326;


// Physically implausible values of an effect's parameters (display units): a negative or absurd
// joint compliance, a thermal coefficient of the wrong sign or above 50 ppm/K (steel 11-13,
// aluminium 23), a gear or backlash amplitude above a degree, a scale error above 1%.
std::vector<std::string> Diagnoser::implausible(const std::vector<EffectParameter>& ps) const {
  std::vector<std::string> out;
  std::map<std::string, double> gear_amp2;  // per joint and harmonic: s^2 + c^2 (deg^2)
  for (const EffectParameter& p : ps) {
    const std::string v = p.name + " = " + fmtg("%.4g", p.value) + " " + p.unit;
    if (p.unit == "urad/Nm" || p.unit == "um/N") {
      if (p.value < 0) out.push_back(v + ": a joint compliance cannot be negative");
      else if (p.value > 500) out.push_back(v + ": above 500 " + p.unit + ", not a joint's stiffness");
    } else if (p.unit == "ppm/K") {
      if (p.value < 0) out.push_back(v + ": a thermal expansion coefficient of the wrong sign");
      else if (p.value > 50) out.push_back(v + ": above 50 ppm/K, no arm material expands so much");
    } else if (p.unit == "ppm") {
      if (std::abs(p.value) > 1e4) out.push_back(v + ": a scale error above 1%");
    } else if (p.name.find("backlash") != std::string::npos) {
      if (p.value < 0) out.push_back(v + ": a backlash cannot be negative");
      else if (p.value > 1) out.push_back(v + ": a backlash above a degree");
    } else if (p.unit == "deg") {
      // gear harmonics jN_sH / jN_cH: the amplitude of each harmonic
      const size_t u = p.name.rfind('_');
      if (u != std::string::npos && u + 2 <= p.name.size()) {
        const std::string key = p.name.substr(0, u) + "_h" + p.name.substr(u + 2);
        gear_amp2[key] += p.value * p.value;
      }
      if (std::abs(p.value) > 1) out.push_back(v + ": an amplitude above a degree");
    }
  }
  for (const auto& kv : gear_amp2)
    if (std::sqrt(kv.second) > 1 && out.empty())
      out.push_back(kv.first + " amplitude " + fmtg("%.3g", std::sqrt(kv.second)) + " deg: above a degree");
  return out;
}

// The ranges of the fit data an effect on these joints depends on.
std::vector<Coverage> Diagnoser::coverageOf(const std::string& effect, const std::vector<int>& joints) const {
  std::vector<Coverage> out;
  auto range = [&](const std::string& name, const std::string& unit, auto get) {
    Coverage c{name, unit, 1e300, -1e300};
    for (const Measurement& r : fit_.rows) {
      c.lo = std::min(c.lo, get(r));
      c.hi = std::max(c.hi, get(r));
    }
    out.push_back(c);
  };
  if (effect == "thermal") {
    range("temp_c", "C", [](const Measurement& r) { return r.context.temp_c; });
    return out;
  }
  std::vector<int> js = joints;  // 1-based
  if (effect == "joint_compliance") {
    // the gravity torque on a joint depends on it and the joints after it
    std::set<int> all;
    for (int j : joints)
      for (int k = j; k <= M0_.dof(); ++k) all.insert(k);
    js.assign(all.begin(), all.end());
  }
  for (int j : js) {
    const bool rev = M0_.nominal.joints[static_cast<size_t>(j - 1)].type == JointType::kRevolute;
    range("q" + std::to_string(j), rev ? "deg" : "mm", [j](const Measurement& r) { return r.q[j - 1]; });
  }
  return out;
}

// The range of joint j the training rows of fold f cover (every row not held out in f).
std::pair<double, double> Diagnoser::trainingRange(const Scheme& sc, size_t f, int j) const {
  std::vector<bool> held(static_cast<size_t>(m_), false);
  for (int i : sc.poses[f]) held[static_cast<size_t>(i)] = true;
  double lo = 1e300, hi = -1e300;
  for (int i = 0; i < m_; ++i)
    if (!held[static_cast<size_t>(i)]) {
      lo = std::min(lo, fit_.rows[static_cast<size_t>(i)].q[j]);
      hi = std::max(hi, fit_.rows[static_cast<size_t>(i)].q[j]);
    }
  return {lo, hi};
}

// A scale or a gear harmonic is a formula of the joint's angle over its whole range: what the fit
// data determine on the covered range is extrapolated everywhere else. Periodic terms fitted on
// less than about half a turn (0.45 turn, 162 deg) are not determined (inside the range the
// geometric parameters compensate them, outside they do not), unless the joint's limits leave
// nothing beyond the data (periodicTermHoldsOverLimits); and neither term is extrapolated to
// joint limits further beyond the covered range than half its width (on the KR 16 with joint 1
// covered over its middle third, a scale of joint 1 fitted there made fresh poses over the whole
// range worse than the geometric model: 0.317 -> 0.455 mm). A periodic term whose data cover a
// whole turn is determined everywhere. Blocked cross-validation cannot show this: its training
// rows always lie inside the covered range.
bool Diagnoser::carriesOver(const Block& B, std::string* why) const {
  if ((B.effect != "gear_periodic" && B.effect != "joint_scale") || B.joint < 0) return true;
  const JointSpec& J = M0_.nominal.joints[static_cast<size_t>(B.joint)];
  const bool rev = J.type == JointType::kRevolute;
  const bool periodic = B.effect == "gear_periodic" && rev;
  double lo = 1e300, hi = -1e300;
  for (const Measurement& r : fit_.rows) {
    lo = std::min(lo, r.q[B.joint]);
    hi = std::max(hi, r.q[B.joint]);
  }
  const double width = hi - lo;
  if (periodic && width >= 360.0) return true;
  const std::string unit = rev ? " deg" : " mm";
  const std::string covered = "the fit data cover " + fmtg("%.0f", width) + unit + " of joint " + std::to_string(B.joint + 1) +
                              " (" + fmtg("%.1f", lo) + ".." + fmtg("%.1f", hi) + ")";
  if (periodic && !periodicTermHoldsOverLimits(J, lo, hi)) {
    *why = covered + ": " + B.effect + " fitted on less than about half a turn does not carry over to the rest of the range";
    return false;
  }
  // How far the joint's limits reach beyond the covered range. A periodic term repeats with each
  // turn, so an angle counts at its turn nearest the covered range (beyondFitRange, as `check` and
  // `compensate` judge a gear term's coverage): a UR joint's -360..360 deg limits lie 15 deg beyond
  // data over -165..165 deg for it (the half turn opposite the range's centre), not 195 deg.
  double beyond = 0.0;
  if (J.upper > J.lower) {
    const JointRange covered_range{lo, hi};
    const double period = periodic ? 360.0 : 0.0;
    beyond = std::max(beyondFitRange(covered_range, J.lower, period), beyondFitRange(covered_range, J.upper, period));
    if (periodic) {  // the farthest angle of a turn: half a turn from the centre, where the limits reach it
      const double centre = 0.5 * (lo + hi);
      for (double a = centre + 180.0 - 360.0 * std::ceil((centre + 180.0 - J.lower) / 360.0); a <= J.upper; a += 360.0)
        if (a >= J.lower) beyond = std::max(beyond, beyondFitRange(covered_range, a, period));
    }
  }
  if (beyond > 0.5 * width) {
    *why = covered + " and its limits (" + fmtg("%.0f", J.lower) + ".." + fmtg("%.0f", J.upper) + ") lie up to " +
           fmtg("%.0f", beyond) + unit + (periodic ? " beyond (modulo a turn)" : " beyond") + ": " + B.effect +
           " would be extrapolated over more than half the covered width (coverage-limited: measure the joint's whole range)";
    return false;
  }
  return true;
}

// Besides the held-out test, an addition must carry over to its joints' whole ranges
// (carriesOver), have physically plausible parameters and keep its gain under blocked
// cross-validation (every scheme: contiguous blocks of each joint's angle and of the pose order);
// a gain that vanishes or turns into a loss when a joint range is held out would make new data worse.
bool Diagnoser::admissible(const std::vector<int>& cur, const std::vector<int>& add, std::string* why,
                           double* blocked_gain, std::string* scheme) const {
  for (int b : add)
    if (!carriesOver(blocks_[static_cast<size_t>(b)], why)) return false;
  std::vector<int> with = cur;
  with.insert(with.end(), add.begin(), add.end());
  const std::vector<int> S = withBlocks(with);
  std::set<std::string> effects;
  for (int b : add) effects.insert(blocks_[static_cast<size_t>(b)].effect);
  for (const std::string& e : effects) {
    std::vector<EffectParameter> ps;
    for (const EffectParameter& p : parametersOf(S, e)) {
      // only the parameters of the blocks being added
      for (int b : add) {
        const Block& B = blocks_[static_cast<size_t>(b)];
        for (int c : B.cols)
          if (layout_[cols_[c]].name == p.name) ps.push_back(p);
      }
    }
    const std::vector<std::string> bad = implausible(ps);
    if (!bad.empty()) {
      *why = "physically implausible: " + bad[0];
      for (size_t k = 1; k < bad.size(); ++k) *why += "; " + bad[k];
      return false;
    }
  }
  // Blocked cross-validation. An effect given by a formula over the whole range (compliance, a
  // scale, harmonics, thermal) must keep a gain in every scheme: it extrapolates, so it must help
  // where the training rows did not go. A joint map is zero outside the range its data cover: it
  // cannot help there and must do no harm (no scheme significantly worse, one-sided p 0.01).
  bool local = true;
  std::vector<int> periodic_joints;
  for (int b : add) {
    const Block& B = blocks_[static_cast<size_t>(b)];
    local = local && B.effect == "joint_map";
    if (B.effect == "gear_periodic" && B.joint >= 0) periodic_joints.push_back(B.joint);
  }
  *blocked_gain = kNaN;
  double harm_z = 0;
  std::string harm_scheme;
  const std::vector<int> S0 = withBlocks(cur);
  auto worst = [&](const Gain& g, const std::string& name) {
    if (g.z < harm_z) {
      harm_z = g.z;
      harm_scheme = name;
    }
    if (std::isnan(*blocked_gain) || g.gain < *blocked_gain) {
      *blocked_gain = g.gain;
      *scheme = name;
    }
  };
  const bool periodic = !periodic_joints.empty();
  for (const Scheme& sc : blocked_) {
    // half a joint's range is less than the half turn a periodic term needs, and trained on half
    // of another joint's range the geometry it is fitted with does not carry over: the halves do
    // not test it
    if (periodic && sc.end_folds.empty() && sc.poses.size() == 2) continue;
    const Eval e0 = cvEval(S0, sc, false), e1 = cvEval(S, sc, false);
    if (!e0.ok || !e1.ok) continue;
    // The folds the addition is judged on: a periodic term cannot be told from an offset and a
    // scale of its joint on a fold whose training rows cover less than 162 deg of that joint (the
    // coverage rule of carriesOver, fold by fold).
    std::vector<int> judged;
    for (size_t f = 0; f < sc.poses.size(); ++f) {
      bool ok = true;
      for (int j : periodic_joints) {
        const std::pair<double, double> r = trainingRange(sc, f, j);
        ok = ok && r.second - r.first >= kPeriodicCoverageDeg;
      }
      if (ok) judged.push_back(static_cast<int>(f));
    }
    auto gainOn = [&](const std::vector<int>& folds) {
      std::vector<double> d0, d1;
      for (int f : folds)
        for (int i : sc.poses[static_cast<size_t>(f)]) {
          d0.push_back(e0.d[i]);
          d1.push_back(e1.d[i]);
        }
      return pairedGain(Eigen::Map<Eigen::VectorXd>(d0.data(), static_cast<Eigen::Index>(d0.size())),
                        Eigen::Map<Eigen::VectorXd>(d1.data(), static_cast<Eigen::Index>(d1.size())));
    };
    if (judged.empty()) continue;
    worst(gainOn(judged), sc.name);
    // the end blocks alone: new data beyond the range the training rows cover (periodic terms:
    // the coverage rule of carriesOver)
    if (periodic) continue;
    std::vector<int> ends;
    for (int f : sc.end_folds)
      if (std::find(judged.begin(), judged.end(), f) != judged.end()) ends.push_back(f);
    if (!ends.empty()) worst(gainOn(ends), sc.name.substr(0, sc.name.find(' ')) + " end blocks");
  }
  if (local && harm_z < -kHarmZ) {
    *why = "does harm outside the joint ranges it was fitted on: blocked cross-validation (" + harm_scheme +
           ") makes the held-out error worse (z = " + fmtg("%.1f", harm_z) + ")";
    return false;
  }
  if (!local && *blocked_gain <= 0) {
    *why = "does not carry over to new joint ranges: blocked cross-validation (" + *scheme + ") gives a gain of " +
           fmtg("%.1f", 100 * *blocked_gain) + "% (held-out error " + (*blocked_gain < 0 ? "worse" : "not better") + ")";
    return false;
  }
  return true;
}

// One forward selection: its state and its steps (Diagnoser::forward). The candidate units are
// one block each, except joint_map, whose blocks are one unit: a map of one joint alone moves the
// geometric parameters that the maps of the others hold (on the real UR10, a map of joint 2 alone
// makes the end blocks of joint 4 worse; all maps together do not).
struct Diagnoser::ForwardRun {
  const Diagnoser& d;
  const std::vector<int>& candidates;
  Forward fw;
  std::vector<bool> used, rejected_block;
  std::set<std::string> selected_effects;
  std::vector<std::vector<int>> units;

  ForwardRun(const Diagnoser& diagnoser, const std::vector<int>& cands) : d(diagnoser), candidates(cands) {
    const size_t B = d.blocks_.size();
    fw.cur = d.base_eval_;
    fw.last_round.assign(B, Gain{});
    used.assign(B, false);
    rejected_block.assign(B, false);
    std::vector<int> maps;
    for (int b : candidates)
      if (block(b).effect == "joint_map") maps.push_back(b);
      else units.push_back({b});
    if (!maps.empty()) units.push_back(maps);
  }
  const Block& block(int b) const { return d.blocks_[static_cast<size_t>(b)]; }
  bool isMapUnit(const std::vector<int>& u) const { return block(u[0]).effect == "joint_map"; }
  bool unused(const std::vector<int>& u) const {
    for (int b : u)
      if (used[static_cast<size_t>(b)]) return false;
    return true;
  }
  // held-out errors of the current selection plus `add`
  Eval evalWith(const std::vector<int>& add) const {
    if (fw.blocks.empty() && add.size() == 1) return d.round1_eval_[static_cast<size_t>(add[0])];
    std::vector<int> blocks = fw.blocks;
    blocks.insert(blocks.end(), add.begin(), add.end());
    return d.evaluate(d.withBlocks(blocks));
  }
  void accept(const std::vector<int>& add, const Eval& e, double blocked_gain, const std::string& scheme) {
    for (size_t k = 0; k < add.size(); ++k) {
      used[static_cast<size_t>(add[k])] = true;
      fw.blocks.push_back(add[k]);
      fw.drops.push_back(k == 0 ? fw.cur.d.mean() - e.d.mean() : 0.0);
      fw.blocked_gain.push_back(blocked_gain);
      fw.blocked_scheme.push_back(scheme);
    }
    fw.cur = e;
    selected_effects.insert(block(add[0]).effect);
    // what was rejected is tried again on the new model (a map may carry over once the compliance
    // it would otherwise absorb is in the model)
    for (size_t b = 0; b < rejected_block.size(); ++b)
      if (rejected_block[b]) {
        rejected_block[b] = false;
        used[b] = false;
      }
  }
  // the latest reason of each candidate; a block that does not carry over to its joint's range
  // stays out (no later addition changes the range the data cover)
  void reject(const std::vector<int>& add, const std::string& why, bool for_good) {
    const Block& first = block(add[0]);
    fw.rejected.erase(std::remove_if(fw.rejected.begin(), fw.rejected.end(),
                                     [&](const Rejected& x) {
                                       return x.effect == first.effect &&
                                              (x.joints.empty() || first.joint < 0 ||
                                               std::find(x.joints.begin(), x.joints.end(), first.joint + 1) != x.joints.end());
                                     }),
                      fw.rejected.end());
    Rejected r;
    r.effect = first.effect;
    for (int b : add) {
      used[static_cast<size_t>(b)] = true;
      rejected_block[static_cast<size_t>(b)] = !for_good;
      if (block(b).joint >= 0) r.joints.push_back(block(b).joint + 1);
    }
    std::sort(r.joints.begin(), r.joints.end());
    r.reason = why;
    fw.rejected.push_back(r);
  }
  // Adds `add` when it is admissible, else lists it as rejected.
  void tryAdd(const std::vector<int>& add, const Eval& e) {
    std::string why, scheme;
    double bg = kNaN;
    if (d.admissible(fw.blocks, add, &why, &bg, &scheme)) {
      accept(add, e, bg, scheme);
      return;
    }
    bool for_good = false;
    std::string unused_why;
    for (int b : add) for_good = for_good || !d.carriesOver(block(b), &unused_why);
    reject(add, why, for_good);
  }
  // One round over the single units (maps aside) in two families, each with its own Bonferroni
  // correction: blocks of effects already in the model (is the effect on more joints?) and blocks
  // of new effects. True when the best passing unit (or a simpler one on the same joints that it
  // does not beat significantly) was added or rejected.
  bool singleStep() {
    struct Candidate {
      size_t unit = 0;
      int fam = 1;   // 0: an effect already in the model, 1: a new one
      int cols = 0;  // its parameters
      Gain gain;
      Eval eval;
    };
    std::vector<Candidate> cands;
    int best[2] = {-1, -1}, tried[2] = {0, 0};
    std::vector<Gain> round(d.blocks_.size(), Gain{});
    for (size_t u = 0; u < units.size(); ++u) {
      if (!unused(units[u]) || isMapUnit(units[u])) continue;
      const Eval e = evalWith(units[u]);
      if (!e.ok) continue;
      const int fam = selected_effects.count(block(units[u][0]).effect) ? 0 : 1;
      ++tried[fam];
      const Gain g = pairedGain(fw.cur.d, e.d);
      for (int x : units[u]) round[static_cast<size_t>(x)] = g;
      int cols = 0;
      for (int x : units[u]) cols += static_cast<int>(block(x).cols.size());
      cands.push_back({u, fam, cols, g, e});
      const int k = static_cast<int>(cands.size()) - 1;
      if (best[fam] < 0 || g.gain > cands[static_cast<size_t>(best[fam])].gain.gain) best[fam] = k;
    }
    fw.last_round = round;
    if (fw.blocks.empty() && !fw.has_best_single && best[1] >= 0) {
      fw.has_best_single = true;
      fw.best_single = units[cands[static_cast<size_t>(best[1])].unit];
      fw.best_single_eval = cands[static_cast<size_t>(best[1])].eval;
    }
    const auto passes = [&](const Candidate& c) {
      return c.gain.p < d.o_.alpha / double(tried[c.fam]) && c.gain.gain >= d.o_.min_gain;
    };
    int pick = -1;
    for (int fam = 0; fam < 2; ++fam) {
      if (best[fam] < 0) continue;
      const Candidate& c = cands[static_cast<size_t>(best[fam])];
      if (passes(c) && (pick < 0 || c.gain.gain > cands[static_cast<size_t>(pick)].gain.gain)) pick = best[fam];
    }
    if (pick < 0) return false;
    // Parsimony on the same joints: an effect that fits a joint's error as well (a 4-parameter
    // gear_periodic takes the linear ramp of a joint_scale over 190-260 deg of range) is not
    // named in place of the simpler one unless it does significantly better. Simpler: an effect
    // already in the model, then fewer parameters; the best such passing unit on the same joints
    // that the pick does not beat at alpha (paired test on the held-out errors).
    {
      const Candidate& P = cands[static_cast<size_t>(pick)];
      const auto key = [](const Candidate& c) { return std::make_pair(c.fam, c.cols); };
      const auto joints = [&](const Candidate& c) {
        std::set<int> j;
        for (int x : units[c.unit]) j.insert(block(x).joint);
        return j;
      };
      const std::set<int> jp = joints(P);
      int alt = -1;
      for (size_t i = 0; i < cands.size(); ++i) {
        const Candidate& c = cands[i];
        if (static_cast<int>(i) == pick || !(key(c) < key(P)) || !passes(c) || joints(c) != jp) continue;
        if (pairedGain(c.eval.d, P.eval.d).p < d.o_.alpha) continue;  // the pick is significantly better
        const Candidate* a = alt < 0 ? nullptr : &cands[static_cast<size_t>(alt)];
        if (!a || key(c) < key(*a) || (key(c) == key(*a) && c.gain.gain > a->gain.gain)) alt = static_cast<int>(i);
      }
      if (alt >= 0) pick = alt;
    }
    const Candidate& chosen = cands[static_cast<size_t>(pick)];
    tryAdd(units[chosen.unit], chosen.eval);
    return true;
  }
  // When no single block passes: the remaining blocks of each effect together (one candidate per
  // effect), so that an effect spread thinly over several joints is not missed.
  bool groupStep() {
    std::map<std::string, std::vector<int>> groups;
    for (int b : candidates)
      if (!used[static_cast<size_t>(b)] && block(b).effect != "joint_map") groups[block(b).effect].push_back(b);
    std::vector<int> best_group;
    Gain group_gain;
    Eval group_eval;
    int groups_tried = 0;
    for (const auto& kv : groups) {
      if (kv.second.size() < 2) continue;  // a single block was tried above
      const Eval e = evalWith(kv.second);
      if (!e.ok) continue;
      ++groups_tried;
      const Gain g = pairedGain(fw.cur.d, e.d);
      if (best_group.empty() || g.gain > group_gain.gain) {
        best_group = kv.second;
        group_gain = g;
        group_eval = e;
      }
    }
    if (best_group.empty() || !(group_gain.p < d.o_.alpha / double(groups_tried) && group_gain.gain >= d.o_.min_gain))
      return false;
    tryAdd(best_group, group_eval);
    return true;
  }
  // The joint maps last: a map of every joint can follow what a parametric effect describes (a
  // gear harmonic, a compliance); they are tried only when none of them passes any more. True
  // when the maps were added.
  bool mapStep() {
    for (const std::vector<int>& u : units) {
      if (!isMapUnit(u) || !unused(u)) continue;
      const Eval e = evalWith(u);
      if (!e.ok) return false;
      const Gain g = pairedGain(fw.cur.d, e.d);
      for (int x : u) fw.last_round[static_cast<size_t>(x)] = g;
      if (fw.blocks.empty() && !fw.has_best_single) {
        fw.has_best_single = true;
        fw.best_single = u;
        fw.best_single_eval = e;
      }
      if (!(g.p < d.o_.alpha && g.gain >= d.o_.min_gain)) return false;
      const size_t before = fw.blocks.size();
      tryAdd(u, e);
      return fw.blocks.size() > before;
    }
    return false;
  }
  // a candidate rejected once and selected later is not reported as rejected
  void forgetRejectedSelectedLater() {
    fw.rejected.erase(std::remove_if(fw.rejected.begin(), fw.rejected.end(),
                                     [&](const Rejected& x) {
                                       for (int b : fw.blocks)
                                         if (block(b).effect == x.effect &&
                                             (x.joints.empty() ||
                                              std::find(x.joints.begin(), x.joints.end(), block(b).joint + 1) != x.joints.end()))
                                           return true;
                                       return false;
                                     }),
                      fw.rejected.end());
  }
};

// Forward selection over the candidate blocks, starting from the baseline: each round adds
// the block with the largest held-out gain if it passes the test; when no single block
// passes, the remaining blocks of each effect are tried together; the joint maps last.
Diagnoser::Forward Diagnoser::forward(const std::vector<int>& candidates) const {
  ForwardRun run(*this, candidates);
  const int B = static_cast<int>(blocks_.size());
  // rejected candidates do not count as steps
  for (int step = 0; static_cast<int>(run.fw.blocks.size()) < o_.max_steps && step < o_.max_steps + B; ++step)
    if (!run.singleStep() && !run.groupStep() && !run.mapStep()) break;
  run.forgetRejectedSelectedLater();
  return run.fw;
}

void Diagnoser::selection() {
  base_eval_ = evaluate(G_);
  if (!base_eval_.ok) {
    // the fold whose training rows hold too few distinct configurations, when one does
    std::string why;
    for (int f = 0; f < folds_ && why.empty(); ++f) why = singularWhy(groups_, trainingRows(f), static_cast<int>(G_.size()));
    throw NumericalError("diagnose: the baseline's normal matrix is singular on a fold" + why);
  }
  const size_t B = blocks_.size();
  round1_.assign(B, Gain{});
  round1_eval_.assign(B, Eval{});
  for (size_t b = 0; b < B; ++b) {
    round1_eval_[b] = evaluate(withBlocks({static_cast<int>(b)}));
    if (round1_eval_[b].ok) round1_[b] = pairedGain(base_eval_.d, round1_eval_[b].d);
  }
  std::vector<int> all(B);
  std::iota(all.begin(), all.end(), 0);
  const Forward fw = forward(all);
  sel_blocks_ = fw.blocks;
  sel_drop_ = fw.drops;
  last_round_ = fw.last_round;
  sel_blocked_gain_ = fw.blocked_gain;
  sel_blocked_scheme_ = fw.blocked_scheme;
  out_.rejected = fw.rejected;
}

void Diagnoser::ranking() {
  const double base_rms = std::sqrt(base_eval_.d.mean());
  for (const std::string& e : o_.effects) {
    EffectEvidence ev;
    ev.effect = e;
    ev.rms_before_mm = base_rms;
    std::vector<int> mine;
    for (size_t b = 0; b < blocks_.size(); ++b)
      if (blocks_[b].effect == e) mine.push_back(static_cast<int>(b));
    if (mine.empty()) {
      ev.testable = false;
      auto it = effect_note_.find(e);
      ev.note = it != effect_note_.end() ? it->second : "not testable: no parameter of it can be determined from these measurements";
      ev.rms_after_mm = base_rms;
      out_.ranking.push_back(ev);
      continue;
    }
    for (int b : mine) {
      JointEvidence je;
      je.joint = blocks_[b].joint + 1;
      je.rms_after_mm = round1_eval_[b].ok ? std::sqrt(round1_eval_[b].d.mean()) : kNaN;
      je.gain = round1_[b].gain;
      je.z = round1_[b].z;
      je.p_value = round1_[b].p;
      if (blocks_[b].joint >= 0) ev.per_joint.push_back(je);
    }
    // forward selection within the effect
    const Forward fw = forward(mine);
    std::vector<int> chosen = fw.blocks;
    Eval cur = fw.cur;
    ev.significant = !chosen.empty();
    if (chosen.empty() && fw.has_best_single) {
      chosen = fw.best_single;  // the best single unit, reported as not significant
      cur = fw.best_single_eval;
    }
    for (int b : chosen)
      if (blocks_[b].joint >= 0) ev.joints.push_back(blocks_[b].joint + 1);
    std::sort(ev.joints.begin(), ev.joints.end());
    ev.rms_after_mm = std::sqrt(cur.d.mean());
    ev.max_after_mm = std::sqrt(cur.d.maxCoeff());
    const Gain g = pairedGain(base_eval_.d, cur.d);
    ev.gain = g.gain;
    ev.z = g.z;
    ev.p_value = g.p;
    const std::vector<int> S = withBlocks(chosen);
    double chi_with = 0, chi_without = 0;
    fitAll(S, &chi_with, nullptr);
    fitAll(G_, &chi_without, nullptr);
    ev.delta_bic = chi_with - chi_without + double(S.size() - G_.size()) * std::log(equations_);
    ev.parameters = parametersOf(S, e);
    ev.implausible = implausible(ev.parameters);
    if (!ev.significant) {
      ev.note = "not significant: the best joint alone does not pass the test";
      for (const Rejected& r : fw.rejected)
        if (r.effect == e) {
          ev.note = "not selected: " + jointList(r.joints) + (r.joints.empty() ? "" : " ") + r.reason;
          break;
        }
    }
    out_.ranking.push_back(ev);
  }
  std::stable_sort(out_.ranking.begin(), out_.ranking.end(), [](const EffectEvidence& a, const EffectEvidence& b) {
    if (a.testable != b.testable) return a.testable;
    if (a.significant != b.significant) return a.significant;
    return a.rms_after_mm < b.rms_after_mm;
  });
}

// Canonical correlation of two blocks' weighted columns with the geometry projected out.
double canonicalCorrelation(const Eigen::MatrixXd& Jw, const std::vector<int>& G, const std::vector<int>& a,
                            const std::vector<int>& b) {
  Eigen::MatrixXd Gm = Jw(Eigen::all, G);
  Eigen::HouseholderQR<Eigen::MatrixXd> qr(Gm);
  const Eigen::MatrixXd Q = qr.householderQ() * Eigen::MatrixXd::Identity(Gm.rows(), Gm.cols());
  auto basis = [&](const std::vector<int>& cols) {
    Eigen::MatrixXd X = Jw(Eigen::all, cols);
    X -= Q * (Q.transpose() * X);
    Eigen::HouseholderQR<Eigen::MatrixXd> q2(X);
    return Eigen::MatrixXd(q2.householderQ() * Eigen::MatrixXd::Identity(X.rows(), X.cols()));
  };
  const Eigen::MatrixXd Qa = basis(a), Qb = basis(b);
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(Qa.transpose() * Qb);
  return std::min(1.0, svd.singularValues().size() ? svd.singularValues()[0] : 0.0);
}

void Diagnoser::confounding() {
  const size_t B = blocks_.size();
  const double thr1 = o_.alpha / double(std::max<size_t>(1, B));
  Eigen::MatrixXd Jw(JF_.rows() + JR_.rows(), JF_.cols());  // every weighted row (6D: the orientation's too)
  Jw << wF_.asDiagonal() * JF_, wR_.asDiagonal() * JR_;
  std::map<std::pair<std::string, std::string>, Confounding> pairs;
  std::map<std::pair<std::string, std::string>, double> representative_gain;  // of the block whose comparison a line reports
  for (size_t d = 0; d < B; ++d) {
    if (std::find(sel_blocks_.begin(), sel_blocks_.end(), static_cast<int>(d)) != sel_blocks_.end()) continue;
    if (!(round1_[d].p < thr1 && round1_[d].gain >= o_.min_gain)) continue;  // D alone did not matter
    const Gain& given = last_round_[d];
    if (given.p < thr1 && given.gain >= o_.min_gain) continue;  // still helps: not explained away
    // which selected block explains it away?
    int best_c = -1;
    double best_ratio = 1e300, best_given = 0;
    for (int c : sel_blocks_) {
      if (blocks_[c].effect == blocks_[d].effect) continue;
      const Eval ec = evaluate(withBlocks({c}));
      const Eval ecd = evaluate(withBlocks({c, static_cast<int>(d)}));
      if (!ec.ok || !ecd.ok) continue;
      const double g = pairedGain(ec.d, ecd.d).gain;
      const double ratio = g / std::max(round1_[d].gain, 1e-300);
      if (ratio < best_ratio) {
        best_ratio = ratio;
        best_c = c;
        best_given = g;
      }
    }
    if (best_c < 0 || best_ratio > 0.5) continue;
    const Block& C = blocks_[best_c];
    const Block& D = blocks_[d];
    Confounding& cf = pairs[{C.effect, D.effect}];
    cf.effect_a = C.effect;
    cf.effect_b = D.effect;
    if (C.joint >= 0 && std::find(cf.joints_a.begin(), cf.joints_a.end(), C.joint + 1) == cf.joints_a.end())
      cf.joints_a.push_back(C.joint + 1);
    if (D.joint >= 0 && std::find(cf.joints_b.begin(), cf.joints_b.end(), D.joint + 1) == cf.joints_b.end())
      cf.joints_b.push_back(D.joint + 1);
    cf.gain_b_alone = std::max(cf.gain_b_alone, round1_[d].gain);
    cf.gain_b_given_a = std::max(cf.gain_b_given_a, best_given);
    cf.canonical_correlation = std::max(cf.canonical_correlation, canonicalCorrelation(Jw, G_, C.cols, D.cols));
    // could the data tell them apart? C alone against D alone on the baseline. One line may
    // hold several blocks of D (joints): its comparison is the one of D's block that gained
    // most alone, all its numbers from that block (a merge of several blocks' numbers
    // contradicted itself: "cannot tell them apart" next to p = 4e-15)
    double& representative = representative_gain.try_emplace({C.effect, D.effect}, -std::numeric_limits<double>::infinity()).first->second;
    if (round1_[d].gain > representative) {
      representative = round1_[d].gain;
      const Gain cd = pairedGain(round1_eval_[d].d, round1_eval_[best_c].d);
      cf.indistinguishable = cd.p > 0.05;
      cf.rms_a_alone_mm = std::sqrt(round1_eval_[best_c].d.mean());
      cf.rms_b_alone_mm = std::sqrt(round1_eval_[d].d.mean());
      cf.p_a_better = cd.p;
    }
  }
  for (auto& kv : pairs) {
    Confounding& cf = kv.second;
    std::sort(cf.joints_a.begin(), cf.joints_a.end());
    std::sort(cf.joints_b.begin(), cf.joints_b.end());
    const std::string sa = separator(cf.effect_a, cf.joints_a), sb = separator(cf.effect_b, cf.joints_b);
    cf.separate_by = sa == sb ? sa : sa + "; " + sb;
    out_.confounded.push_back(cf);
  }
}

void Diagnoser::shrink() {
  // cumulative steps by effect, in the order of their first selection
  std::vector<std::string> order;
  std::map<std::string, std::vector<int>> blocks_of;
  std::map<std::string, double> drop_of;
  for (size_t k = 0; k < sel_blocks_.size(); ++k) {
    const Block& b = blocks_[sel_blocks_[k]];
    if (!blocks_of.count(b.effect)) order.push_back(b.effect);
    blocks_of[b.effect].push_back(sel_blocks_[k]);
    drop_of[b.effect] += sel_drop_[k];
  }
  Exact base = exact(G_);
  E0_ = base.e;
  out_.baseline = base.stats;
  out_.baseline_model = base.model_all;
  out_.shrink.push_back({"baseline", {}, base.stats});
  std::vector<int> cumulative;
  Eval prev = base_eval_;
  Exact last = base;
  for (const std::string& e : order) {
    cumulative.insert(cumulative.end(), blocks_of[e].begin(), blocks_of[e].end());
    const std::vector<int> S = withBlocks(cumulative);
    Exact ex = exact(S);
    const Eval lin = evaluate(S);
    EffectEvidence ev;
    ev.effect = e;
    for (int b : blocks_of[e])
      if (blocks_[b].joint >= 0) ev.joints.push_back(blocks_[b].joint + 1);
    std::sort(ev.joints.begin(), ev.joints.end());
    ev.rms_before_mm = last.stats.rms_mm;
    ev.rms_after_mm = ex.stats.rms_mm;
    ev.max_after_mm = ex.stats.max_mm;
    ev.significant = true;
    if (lin.ok) {
      const Gain g = pairedGain(prev.d, lin.d);
      ev.gain = g.gain;
      ev.z = g.z;
      ev.p_value = g.p;
      prev = lin;
    }
    double chi_with = 0, chi_without = 0;
    fitAll(S, &chi_with, nullptr);
    std::vector<int> before(cumulative.begin(), cumulative.end() - static_cast<long>(blocks_of[e].size()));
    fitAll(withBlocks(before), &chi_without, nullptr);
    ev.delta_bic = chi_with - chi_without + double(S.size() - withBlocks(before).size()) * std::log(equations_);
    ev.parameters = parametersOf(S, e);
    ev.implausible = implausible(ev.parameters);
    ev.coverage = coverageOf(e, ev.joints);
    ev.params = e;
    for (size_t k = 0; k < ev.joints.size(); ++k) ev.params += (k ? "+j" : ":j") + std::to_string(ev.joints[k]);
    if (e == "joint_map") ev.params += "@" + fmtg("%.4g", map_knot_) + (M0_.nominal.joints[0].type == JointType::kRevolute ? "deg" : "mm");
    for (size_t k = 0; k < sel_blocks_.size(); ++k)
      if (blocks_[sel_blocks_[k]].effect == e &&
          (std::isnan(ev.blocked_gain) || sel_blocked_gain_[k] < ev.blocked_gain)) {
        ev.blocked_gain = sel_blocked_gain_[k];
        ev.blocked_scheme = sel_blocked_scheme_[k];
      }
    out_.identify_params += "," + ev.params;
    out_.selected.push_back(ev);
    out_.shrink.push_back({e, ev.joints, ex.stats});
    last = std::move(ex);
  }
  E1_ = last.e;
  final_stats_ = last.stats;
  out_.final_model = last.model_all;
  order_ = order;
  blocks_of_ = blocks_of;
  drop_of_ = drop_of;
}

}  // namespace diagnose_detail
}  // namespace accura::calib
