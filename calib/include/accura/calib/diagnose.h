// accura: diagnosis of the sim-to-real gap (docs/diagnosis.md): how large the error of the
// complete geometric model is on held-out poses, where in the workspace it lies, which
// effect of the catalogue (joint_compliance, gear_periodic, joint_scale, backlash, thermal)
// causes it, how far it shrinks once that effect is modelled, and what remains against the
// noise floor; `unexplained` when a structured residual remains that no catalogued effect
// explains. Positions drive the fits; for 6D data the orientation residual is reported.
//
// Statistics, in short (the details and the reasons are in docs/diagnosis.md):
// - held-out error: on --validate data, or by k-fold cross-validation over the poses
//   (repeated poses stay in one fold); the ranking and selection use the model linearised at
//   the baseline (one Gauss-Newton step from it, exact to about 1e-3 mm for these effect
//   sizes), the shrink table and the verdict use exact non-linear refits;
// - floors, kept apart: the instrument's (std columns) and the repeatability from repeated joint
//   configurations (every joint within repeat_tol); the verdict is judged against a given value,
//   else the repeatability, else the std columns; repeat pairs that disagree grossly are glitches;
// - robust estimation (Huber weights from the richest model's residual; the rows down-weighted
//   are listed as file:line);
// - forward selection over (effect, joint) blocks: the block with the largest held-out gain
//   is added while a one-sided paired z-test of the per-pose held-out squared errors gives
//   p < alpha / (number of blocks tried in that round) (Bonferroni) and the held-out mean
//   squared error drops by at least min_gain, *and* its parameters are physically plausible,
//   a periodic term's joint is covered over at least 162 deg, and the gain stays positive under
//   blocked cross-validation (contiguous blocks of each joint's angle and of the pose order);
//   selected effects are reported with their coverage and as identify --params takes them;
// - unexplained: the held-out squared errors of the final model exceed what noise and
//   parameter uncertainty explain (z-test, p < floor_alpha) and the excess is structured (the
//   structure scan, or a significant peak of the per-joint spectrum, Bonferroni over joints and
//   cycles per revolution), with the share the selected effects explain (partial explanation).
#pragma once

#include <cstdint>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "accura/calib/identify.h"
#include "accura/calib/measurements.h"
#include "accura/calib/robot.h"

namespace accura::calib {

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
  /// Two rows are one joint configuration measured again when every joint agrees within this
  /// tolerance (deg for revolute, mm for prismatic joints) and payload and dirN are equal.
  double repeat_tol = kRepeatTolerance;
  /// A repeat pair whose positions disagree by more than this many times the median pair
  /// distance is a glitch (excluded from the repeatability, listed).
  double glitch_factor = 10.0;
  /// Robust estimation: a pose whose baseline residual exceeds robust_k robust standard
  /// deviations (3D, chi with 3 degrees of freedom: 4.03 is its 99.9% quantile) is down-weighted
  /// by Huber's rule (weight k s / |r|); 0 turns it off.
  double robust_k = 4.03;
  /// Blocked cross-validation (the check that mimics new data): contiguous blocks of each
  /// joint's angle and of the pose order.
  int blocked_folds = 5;
  /// 6D data: the linearised fits use the measured orientations too, as identify fits them
  /// (rows weighted like identify's: 1 / sqrt(std^2 + tau^2) per axis and component type, tau
  /// the geometric baseline's unmodelled-error term); the held-out errors stay positions (mm).
  /// false: positions only.
  bool use_orientation = true;
  /// Highest number of cycles per revolution of the per-joint spectrum of the residual.
  int spectrum_max_cycles = 90;
  /// joint_map candidates: knot spacing (deg for revolute joints, mm for prismatic ones; made
  /// coarser when the fit data have fewer than 10 poses per coefficient of the widest joint) and
  /// relative smoothness weight (as IdentifyOptions::joint_map_smoothing). A joint gets a map
  /// when the fit data cover at least 4 knot spacings of it.
  double joint_map_knot = 3.0;
  double joint_map_smoothing = 0.003;

  bool IsValid(std::string* error) const;
};

/// A glitch among the repeats of one joint configuration (within DiagnoseOptions::repeat_tol).
/// A configuration measured twice: the two rows (which of them is wrong cannot be told).
/// Measured three times or more: the odd row alone (index_b = -1, line_b = 0), against the
/// configuration's robust centre (the per-axis median of its measured points).
struct RepeatPair {
  int line_a = 0, line_b = 0;    ///< source lines (0 when simulated)
  int index_a = 0, index_b = 0;  ///< 0-based rows of the data; index_b -1: row a against the centre
  double distance_mm = 0;        ///< |p_a - p_b|, or |p_a - centre|
  double rotation_deg = std::numeric_limits<double>::quiet_NaN();  ///< orientation jump (6D data)
  int measurements = 2;          ///< rows of the configuration
  bool validation = false;       ///< rows of the validation set (else of the fit data)
  /// The rows' file when they are named by it (a duplicated row: no longer among the rows, its
  /// index that of the set as given); empty: by the index (Diagnosis::row_files).
  std::string file;
};

/// The floors of a data set: what the instrument states (std columns) and what the robot and
/// instrument repeat (repeated configurations). The model can at best reach the repeatability.
struct Floors {
  bool instrument_known = false;
  double instrument_rms_mm = std::numeric_limits<double>::quiet_NaN();  ///< 3D RMS of the std columns
  double repeat_tol = 0.01;       ///< joint tolerance of a repeat (deg / mm)
  /// Configurations measured more than once (glitch-free, in the pooled scatter), and the pairs
  /// among them (all), of the fit data and the validation set together; *_validation: the
  /// validation set's share.
  int repeat_groups = 0;
  int repeat_pairs = 0;
  int repeat_groups_validation = 0, repeat_pairs_validation = 0;
  int repeat_min_gap = 0, repeat_max_gap = 0;  ///< rows between the two measurements of a pair
  double median_pair_mm = std::numeric_limits<double>::quiet_NaN();  ///< median |p_a - p_b|, glitches excluded
  double repeat_std_axis_mm = std::numeric_limits<double>::quiet_NaN();  ///< pooled, per axis
  double repeat_rms_mm = std::numeric_limits<double>::quiet_NaN();       ///< 3D RMS (sqrt(3) per-axis)
  double repeat_dof = 0;
  double glitch_threshold_mm = std::numeric_limits<double>::quiet_NaN();
  /// Measurement glitches: pairs disagreeing grossly, or the odd rows of a configuration
  /// measured three times or more (RepeatPair).
  std::vector<RepeatPair> glitches;
  /// Rows that repeat an earlier row of their configuration exactly, every measured value equal
  /// (duplicatedRows(): row a the copy, row b the earlier row; distance 0, `file` set): the same
  /// measurement written twice, not a second measurement. Left out of the diagnosis before
  /// anything else, so that each measurement counts once in every statistic (with them the
  /// repeatability would read 0, and every test count the row twice).
  std::vector<RepeatPair> duplicated_rows;
};

/// A pose the robust estimation down-weighted.
struct DownWeighted {
  std::string file;
  int line = 0, index = 0;
  double residual_mm = 0;  ///< baseline fit residual
  double weight = 1;       ///< robust weight (0..1)
};

/// The per-joint spectrum of a residual: the residual projected onto one joint's angle (the
/// joint motion that best explains each pose's residual, weighted by how well the pose shows
/// it) regressed on cos/sin(k q) for k = 1..K cycles per revolution, one k at a time.
struct JointSpectrum {
  int joint = 0;  ///< 1-based, revolute joints only
  double range_deg = 0;              ///< range of the joint in the data
  std::vector<int> cycles;           ///< k (cycles per revolution)
  std::vector<double> amplitude_urad_before, amplitude_urad_after;  ///< of the baseline / final residual
  int peak_cycles = 0;               ///< k of the largest amplitude (final residual)
  double peak_amplitude_urad = 0;
  double peak_share = 0;             ///< share of the joint-projected residual variance at the peak
  double peak_p = 1;                 ///< Bonferroni over every joint and k (p x tests, capped at 1)
  int peak_cycles_before = 0;        ///< the same for the baseline residual
  double peak_amplitude_urad_before = 0, peak_p_before = 1;
};

/// Where an effect's fit data lie: the range of every joint (and temperature) it depends on.
struct Coverage {
  std::string variable;  ///< q1..qN, temp_c
  std::string unit;
  double lo = 0, hi = 0;
};

/// An effect block that passed the ordinary test but was not selected, and why.
struct Rejected {
  std::string effect;
  std::vector<int> joints;
  std::string reason;
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
  /// Blocked cross-validation: the smallest gain over the schemes (contiguous blocks of each
  /// joint's angle and of the pose order) and the scheme that gives it.
  double blocked_gain = std::numeric_limits<double>::quiet_NaN();
  std::string blocked_scheme;
  /// Physically implausible parameters (negative compliance, thermal coefficient of the wrong
  /// sign or size, amplitudes above a degree): never offered as a cause.
  std::vector<std::string> implausible;
  std::vector<Coverage> coverage;  ///< ranges of the fit data (selected effects)
  std::string params;              ///< as identify --params accepts it, e.g. "gear_periodic:j1+j2"
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
  /// Every effect the verdict names as a cause (several when several explain a share of the
  /// gap); for `unexplained`, the effects that explain part of it.
  std::vector<std::string> effects;
  /// Share of the gap (baseline MSE minus the floor's) the selected effects explain (0..1).
  double explained_share = 0;
  double validation_rms_after_mm = 0;
  std::string explanation;
  std::vector<std::string> correlates;       ///< for unexplained: what the residual follows
  std::vector<std::string> confounded_with;  ///< effects that explain the same residual
};

struct Diagnosis {
  std::string robot;
  std::vector<std::string> joint_names;
  std::string data_file, validation_method;  ///< "validation set FILE" or "5-fold cross-validation"
  std::string validation_file;               ///< the validation set's file (empty without one)
  /// Several data sets (diagnose on StationSets): the file of each fit row (rows are named
  /// file:line with it); empty for one data set.
  std::vector<std::string> row_files;
  int fit_poses = 0, validation_poses = 0;
  /// Validation rows named as glitches (Floors::glitches) and left out of the held-out statistics.
  int validation_glitch_rows_left_out = 0;
  /// The data have orientation columns and the fits did not use them (use_orientation false,
  /// or fewer than 30 rows with an orientation); the held-out errors are positions either way.
  bool orientation_ignored = false;
  /// The fits used the measured orientations beside the positions (6D data, use_orientation).
  bool fits_orientation = false;
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
  std::vector<JointSpectrum> spectra;
  /// Orientation residual of 6D data (deg, RMS over the fit data) of the baseline's and the final
  /// model's parameter groups identified on positions and orientations (identify's orientation
  /// fit RMS; the diagnosis' own models are fitted on positions alone, which leave some wrist
  /// parameters free); NaN for position-only data or when that identification fails.
  double orientation_rms_before_deg = std::numeric_limits<double>::quiet_NaN();
  double orientation_rms_after_deg = std::numeric_limits<double>::quiet_NaN();
  Floors floors;
  std::vector<DownWeighted> downweighted;
  std::vector<ExcludedRow> excluded;  ///< gross rows left out before anything else (removeGrossRows)
  std::vector<Rejected> rejected;
  /// What to give `identify --params`: "geometric" plus every selected effect with its joints.
  std::string identify_params = "geometric";
  Verdict verdict;
  std::vector<std::string> notes;  ///< parameters left out and why
  /// What limits the data (a joint that never moves: heldJointWarning), printed as WARNING lines.
  std::vector<std::string> warnings;
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

/// Several data sets of one robot, each measured from its own tracker station unless
/// `same_station`, expressed in the frame of the first set's station.
struct StationSets {
  MeasurementSet combined;            ///< every row, measured points and orientations in station 1's frame
  std::vector<int> set_of_row;        ///< 0-based data set of each combined row
  std::vector<std::string> files;     ///< per data set
  /// T_station1_stationK per data set (identity for the first, and for all when same_station):
  /// the registration of each station by the complete geometric identification on all sets.
  std::vector<Eigen::Isometry3d> T_first_station;
};

/// Combines data sets for one diagnosis. Unless same_station, the complete geometric model is
/// identified on all sets at once with 6 station parameters per set beyond the first
/// (identify() on several sets), and every later set's measured poses are mapped into the first
/// station's frame with the stations found; the diagnosis then holds the stations fixed (they
/// are determined by hundreds of poses each: their uncertainty is far below the model's).
/// Throws ArgumentError on an empty list, InputError when a set has no rows or the sets differ
/// in what they hold (std columns, context columns), and what identify() throws.
/// `groups`: the parameter groups of that identification (identify's --params, e.g.
/// {"geometric", "joint_compliance:j2"}).
StationSets combineStations(const RobotModel& start, const std::vector<MeasurementSet>& sets, bool same_station,
                            const std::vector<std::string>& groups = {"geometric"});

/// The diagnosis of several data sets: as diagnose() on their combination (combineStations),
/// each row named by its own file (Diagnosis::row_files), repeated configurations only within
/// one data set (a configuration measured from two stations also differs by the stations'
/// registration). Unless same_station, in two passes: the stations registered by the geometric
/// model, then, when the diagnosis selects effects, registered again by the geometric model plus
/// those effects (an effect the registration does not model would bend the stations) and
/// diagnosed again. *stations (optional) receives the combination of the final pass.
Diagnosis diagnose(const RobotModel& start, const std::vector<MeasurementSet>& sets, bool same_station,
                   const MeasurementSet* validation, const DiagnoseOptions& options, StationSets* stations = nullptr);

/// The diagnosis as JSON (docs/diagnosis.md lists every key).
std::string diagnosisJson(const Diagnosis& d);
/// The diagnosis as one self-contained HTML page (inline SVG and CSS, no script, no network).
std::string diagnosisHtml(const Diagnosis& d);

/// What makes the HTML report a metrology deliverable, filled by its caller (accura diagnose):
/// where the diagnosis comes from and the identified model's numbers. Empty parts are left out.
struct DiagnosisReportContext {
  std::string date_utc;                  ///< when the report was made, e.g. "2026-11-23 14:30 UTC"
  std::string version;                   ///< accura's version
  std::string instrument;                ///< what measured the data, its stated noise
  std::vector<std::string> data_files;   ///< fit data, validation data, mapping files
  struct Parameter {
    std::string name;
    double value = 0, sigma = 0;         ///< the identified value and one standard deviation
    std::string unit;
    bool station = false;                ///< the tracker station (absolute), not a deviation
  };
  std::vector<Parameter> parameters;     ///< the complete geometric model identified on the fit data
  /// Measured minus predicted tool point per fit pose (world = measurement frame, mm), of
  /// that model: the error histogram and the per-axis split.
  std::vector<Eigen::Vector3d> residuals_mm;
};
/// The page of diagnosisHtml(d), titled "Remaining error of <robot>", with the context's
/// header (date, version, instrument, files), parameters with sigmas, an error histogram and
/// the per-axis split.
std::string diagnosisHtml(const Diagnosis& d, const DiagnosisReportContext& context);
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
  /// The real-data cases (realDataCases()): "cyclic_fine" (joints 2 and 3 err by 0.3-0.7 mrad
  /// at 11-23 cycles per revolution: `unexplained`, and the spectrum finds a joint and its
  /// cycles), "outliers" (joint compliance plus 2% gross outliers of 0.5-3 mm: the verdict
  /// and 80% of the outliers down-weighted), "two_effects" (joint compliance and backlash: both
  /// named), "partial_cyclic" (joint 2 errs at 2 and 17 cycles per revolution: gear_periodic
  /// explains part, `unexplained` with the partial explanation), "partial_range" (gear_periodic
  /// with fit data over the middle third of joint 1's range: the verdict, or `none`, and the
  /// selected model no worse than the geometric one on fresh poses over the whole range; gear_periodic
  /// may then be named as a partial explanation, its part on joint 1 unexplained).
  std::vector<std::string> injected = {"none",        "joint_compliance", "gear_periodic", "joint_scale",
                                       "backlash",    "thermal",          "unmodelled_coupling",
                                       "cyclic_fine", "outliers",         "two_effects",
                                       "partial_cyclic", "partial_range"};
  int poses = 300;             ///< fit poses per case
  int validation_poses = 200;  ///< for the cases diagnosed with a validation set
  int truth_poses = 500;       ///< fresh poses measuring the true shrink
  DiagnoseOptions diagnose;

  bool IsValid(std::string* error) const;
};

/// The selfcheck's cases of the kinds real data bring (see SelfcheckOptions::injected).
const std::vector<std::string>& realDataCases();

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
  /// The smallest footprint the data can show: 8 sigma / sqrt(N) (mm; sigma the noise per axis,
  /// N the fit poses): a paired test of N held-out squared errors sees an effect of RMS s beyond
  /// the geometric model at z = s sqrt(N) / (2 sigma), so z = 4 (about what the diagnosis' tests,
  /// corrected for the variants tried, need).
  double detection_limit_mm = 0;
  /// Each injected catalogue effect (joint_compliance, gear_periodic, joint_scale, backlash,
  /// thermal) with its footprint: the RMS (mm) of the complete geometric model plus the other
  /// injected effects, identified on fresh noise-free poses of the simulated robot (the part of
  /// the effect nothing else in the model takes).
  std::vector<std::pair<std::string, double>> footprints_mm;
  /// The verdict the data can show when it differs from `expected`: `expected` without the
  /// injected effects whose footprint lies below detection_limit_mm ("none" when none is left).
  /// Either counts as right (`right_by_limit` when only this one matched). Empty otherwise.
  std::string expected_detectable;
  bool right_by_limit = false;
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

}  // namespace accura::calib
