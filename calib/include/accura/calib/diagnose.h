// accura: diagnosis of the sim-to-real gap (docs/diagnosis.md): how large the error of the
// complete geometric model is on held-out poses, where in the workspace it lies, which
// effect of the catalogue (joint_compliance, gear_periodic, joint_scale, backlash, thermal)
// causes it, how far it shrinks once that effect is modelled, and what remains against the
// noise floor; `unexplained` when a structured residual remains that no catalogued effect
// explains. Position data only (orientation columns are not used).
//
// Statistics, in short (the details and the reasons are in docs/diagnosis.md):
// - held-out error: on --validate data, or by k-fold cross-validation over the poses
//   (repeated poses stay in one fold); the ranking and selection use the model linearised at
//   the baseline (one Gauss-Newton step from it, exact to about 1e-3 mm for these effect
//   sizes), the shrink table and the verdict use exact non-linear refits;
// - noise floor: a given value, else repeated poses (pooled within-pose scatter), else the
//   std columns of the data; the output says which;
// - forward selection over (effect, joint) blocks: the block with the largest held-out gain
//   is added while a one-sided paired z-test of the per-pose held-out squared errors gives
//   p < alpha / (number of blocks tried in that round) (Bonferroni) and the held-out mean
//   squared error drops by at least min_gain;
// - unexplained: the held-out squared errors of the final model exceed what noise and
//   parameter uncertainty explain (z-test, p < floor_alpha); with no noise floor, when the
//   residual is significantly predictable from the pose and context (the structure scan).
#pragma once

#include <cstdint>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "accura/calib/measurements.h"
#include "accura/calib/robot.h"

namespace accura {

struct DiagnoseOptions {
  /// Effects to test (names of effectCatalogue()); empty: the whole catalogue.
  std::vector<std::string> effects;
  /// Harmonics 1..H of gear_periodic.
  int gear_harmonics = kDefaultGearHarmonics;
  /// Folds of the cross-validation when there is no validation set (>= 2).
  int folds = 5;
  /// Measurement noise, one standard deviation per axis (mm); NaN: from repeated poses, else
  /// from the data's std columns.
  double noise_std_mm = std::numeric_limits<double>::quiet_NaN();
  /// Family-wise significance level of one selection round (Bonferroni over its blocks).
  double alpha = 0.01;
  /// Smallest relative drop of the held-out mean squared error worth an effect (0.01 = 1%).
  double min_gain = 0.01;
  /// Significance level of the test "the remaining error is above the noise floor".
  double floor_alpha = 0.001;
  /// Most (effect, joint) blocks the forward selection adds.
  int max_steps = 12;
  /// Cells per axis of the residual maps over the workspace, and bins per joint range.
  int grid_cells = 8;
  int joint_bins = 10;

  bool IsValid(std::string* error) const;
};

/// Error of a model on held-out poses (position, mm), and how it compares with the noise.
struct HeldOutStats {
  int n = 0;
  double rms_mm = 0, mean_mm = 0, p95_mm = 0, max_mm = 0;
  /// RMS a correct model would show: noise plus the uncertainty of its fitted parameters
  /// (NaN when the noise floor is unknown).
  double expected_rms_mm = std::numeric_limits<double>::quiet_NaN();
  /// z score and one-sided p value of the held-out squared errors above that expectation.
  double floor_z = std::numeric_limits<double>::quiet_NaN();
  double floor_p = std::numeric_limits<double>::quiet_NaN();
};

struct EffectParameter {
  std::string name, unit;
  double value = 0, sigma = 0;  ///< display units; value = deviation from nominal
};

struct JointEvidence {
  int joint = 0;              ///< 1-based
  double rms_after_mm = 0;    ///< held-out RMS with this joint's block added to the baseline
  double gain = 0;            ///< relative drop of the held-out mean squared error
  double z = 0, p_value = 1;  ///< paired test against the baseline
};

/// One effect (with some of its joints) added to a model, and the evidence for it.
struct EffectEvidence {
  std::string effect;
  std::vector<int> joints;  ///< 1-based; empty for thermal (one coefficient for the arm)
  bool testable = true;     ///< false: the data cannot show it (note says why)
  std::string note;
  bool significant = false;
  double rms_before_mm = 0, rms_after_mm = 0;  ///< held-out RMS without / with it
  double max_after_mm = 0;                     ///< held-out max with it
  double gain = 0;                             ///< relative drop of the held-out MSE
  double z = 0, p_value = 1;                   ///< paired test of the per-pose squared errors
  double delta_bic = 0;  ///< BIC(with) - BIC(without) on the fit data; < 0 favours it
  std::vector<EffectParameter> parameters;  ///< fitted on all fit data, 1 sigma
  std::vector<JointEvidence> per_joint;     ///< each joint's block alone on the baseline
};

/// Two effects that explain the same residual: b's gain on the baseline drops below half once
/// a is in the model.
struct Confounding {
  std::string effect_a, effect_b;     ///< a: selected; b: explained away by a
  std::vector<int> joints_a, joints_b;
  double gain_b_alone = 0;            ///< held-out MSE gain of b on the baseline
  double gain_b_given_a = 0;          ///< the same once a is in the model
  double canonical_correlation = 0;   ///< of their Jacobian columns (geometry projected out)
  double rms_a_alone_mm = 0, rms_b_alone_mm = 0;  ///< held-out RMS of each alone on the baseline
  double p_a_better = 1;              ///< paired test: a alone better than b alone
  /// p_a_better > 0.05: this data cannot tell them apart (confounded); otherwise b only
  /// overlaps a and the data prefers a
  bool indistinguishable = false;
  std::string separate_by;            ///< which measurements would separate them
};

/// One row of the shrink table: the model after adding `effect` (cumulative).
struct ShrinkStep {
  std::string effect;        ///< "baseline" for the complete geometric model
  std::vector<int> joints;
  HeldOutStats heldout;      ///< exact (non-linear refit) held-out error
};

/// Error magnitude over a plane of the robot base frame, binned.
struct FieldMap {
  std::string plane;               ///< "base_xy" (top view) or "base_rz" (radius r, height z)
  std::string x_label, y_label;
  std::vector<double> x_edges_mm, y_edges_mm;
  /// Row-major [y][x]; NaN where a cell has no pose.
  std::vector<double> rms_before_mm, rms_after_mm;
  std::vector<int> count;
};

struct JointProfile {
  int joint = 0;  ///< 1-based
  std::string name, unit;
  std::vector<double> edges;
  std::vector<double> rms_before_mm, rms_after_mm;  ///< NaN where a bin has no pose
  std::vector<int> count;
};

/// How much of the held-out residual a variable predicts: the residual regressed on the
/// variable times the joint Jacobian columns and a world translation (cross-validated).
struct Correlation {
  std::string variable;             ///< q3, tau2, payload_kg, temp_c, time_s, dir4
  double r2_before = 0, r2_after = 0;  ///< cross-validated share of the residual variance
  double p_before = 1, p_after = 1;    ///< paired test of the prediction gain
  double pearson_before = 0;           ///< Pearson correlation of |residual| with the variable
  int via_joint_after = 0;             ///< joint whose axis carries most of it (0: translation)
};

struct Region {
  std::string plane;
  double x0_mm = 0, x1_mm = 0, y0_mm = 0, y1_mm = 0;
  int count = 0;
  double rms_before_mm = 0, rms_after_mm = 0;
};

struct WorstPose {
  int line = 0;   ///< source line (0 when simulated)
  int index = 0;  ///< 0-based row of the held-out data (the validation set, or the fit data
                  ///< under cross-validation)
  double error_before_mm = 0, error_after_mm = 0;
};

struct Verdict {
  std::string effect;  ///< a catalogue name, "none" or "unexplained"
  std::vector<int> joints;
  double validation_rms_after_mm = 0;
  std::string explanation;
  std::vector<std::string> correlates;       ///< for unexplained: what the residual follows
  std::vector<std::string> confounded_with;  ///< effects that explain the same residual
};

struct Diagnosis {
  std::string robot;
  std::vector<std::string> joint_names;
  std::string data_file, validation_method;  ///< "validation set FILE" or "5-fold cross-validation"
  int fit_poses = 0, validation_poses = 0;
  bool orientation_ignored = false;
  std::vector<std::string> effects_tested;
  // noise floor
  double noise_floor_mm = 0;      ///< expected 3D RMS of pure noise (sqrt(3) x per-axis std)
  double noise_std_axis_mm = 0;   ///< per-axis standard deviation
  std::string noise_floor_source;
  double noise_floor_dof = std::numeric_limits<double>::infinity();  ///< of the estimate
  bool noise_floor_known = true;  ///< false: upper bound from the fit residual
  std::string tests;              ///< the statistical tests and thresholds, in words
  HeldOutStats baseline;
  std::vector<EffectEvidence> ranking;    ///< every effect alone on the baseline, best first
  std::vector<EffectEvidence> selected;   ///< forward selection, in order (cumulative)
  std::vector<Confounding> confounded;
  std::vector<ShrinkStep> shrink;
  // where
  std::vector<FieldMap> fields;
  std::vector<JointProfile> joints;
  std::vector<Correlation> correlations;
  std::vector<Region> worst_regions;
  std::vector<WorstPose> worst_poses;
  Verdict verdict;
  std::vector<std::string> notes;  ///< parameters left out and why
  double seconds = 0;  ///< wall time of the diagnosis
  /// The baseline (complete geometric) model and the final model (baseline plus the
  /// selected effects), both fitted on all fit data.
  RobotModel baseline_model, final_model;
};

/// Diagnoses `data` (and `validation`, when not null: held-out poses of the same robot from
/// the same station) starting from `start` (nominal or calibrated; its deviations are the
/// starting point, effect values included). Throws InputError when the data is too small
/// (fewer than 30 fit poses, fewer than 20 validation poses) or lacks what the noise floor
/// needs, ArgumentError on invalid options, NumericalError when the fit fails.
Diagnosis diagnose(const RobotModel& start, const MeasurementSet& data, const MeasurementSet* validation,
                   const DiagnoseOptions& options);

/// The diagnosis as JSON (docs/diagnosis.md lists every key).
std::string diagnosisJson(const Diagnosis& d);
/// The diagnosis as one self-contained HTML page (inline SVG and CSS, no script, no network).
std::string diagnosisHtml(const Diagnosis& d);
/// A console summary (a few dozen lines).
std::string diagnosisText(const Diagnosis& d);

// ---------------------------------------------------------------------------------------
// Selfcheck: the diagnosis run blind on simulated robots whose effect is known.

struct SelfcheckOptions {
  std::vector<std::string> robots = {"kuka_kr16", "ur10"};  ///< bundled names or files
  std::vector<std::uint64_t> seeds = {1, 2, 3, 4, 5};
  std::vector<double> noise_mm = {0.01, 0.03};  ///< per-axis noise levels
  /// What is injected (besides the geometric errors): "none", catalogue names,
  /// "unmodelled_coupling" (outside the catalogue).
  std::vector<std::string> injected = {"none",     "joint_compliance", "gear_periodic", "joint_scale",
                                       "backlash", "thermal",          "unmodelled_coupling"};
  int poses = 300;             ///< fit poses per case
  int validation_poses = 200;  ///< for the cases diagnosed with a validation set
  int truth_poses = 500;       ///< fresh poses measuring the true shrink
  DiagnoseOptions diagnose;

  bool IsValid(std::string* error) const;
};

struct SelfcheckCase {
  std::string robot, injected, verdict, expected;
  std::uint64_t seed = 0;
  double noise_mm = 0;
  std::string noise_source;   ///< "std columns" or "repeated poses"
  std::string validation;     ///< "cross-validation" or "validation set"
  std::vector<int> joints;    ///< joints of the verdict
  bool right = false;
  double estimated_before_mm = 0, estimated_after_mm = 0;  ///< from the diagnosis
  double true_before_mm = 0, true_after_mm = 0;  ///< the same models on fresh poses
  /// Systematic error of the geometric model: its RMS on fresh noise-free poses (how large
  /// the withheld effect is after geometry has absorbed what it can).
  double systematic_mm = 0;
  double seconds = 0;
};

struct SelfcheckResult {
  std::vector<SelfcheckCase> cases;
  int right = 0;
  /// The confusion table (rows: injected, columns: verdict) and the shrink table, as text.
  std::string confusionTable() const;
  std::string shrinkTable() const;
};

/// Runs every combination of robot, injected effect, noise level and seed: simulates the
/// data (every context column always present; the noise floor alternately from std columns
/// and from repeated poses; every third case with a separate validation set), diagnoses it
/// with the effect withheld, and compares the verdict with what was injected. `progress` is
/// called after each case. Throws what diagnose and the robot files throw.
SelfcheckResult runSelfcheck(const SelfcheckOptions& options,
                             const std::function<void(const SelfcheckCase&)>& progress = {});

}  // namespace accura
