// accura: simulated measurement campaigns: a perturbed ("real") robot measured by a tracker.
// For the demo, the tests, and for planning a campaign before going to the robot.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "accura/calib/measurements.h"
#include "accura/calib/robot.h"

namespace accura {

struct SimulateOptions {
  int poses = 300;
  std::uint64_t seed = 1;
  /// Errors to put into the real robot: "geometric" (base = the tracker station below,
  /// tool, offsets, lengths, angles), "joint_compliance"; "none": measure the model as given.
  std::vector<std::string> effects = {"geometric"};
  /// Measurement noise: one standard deviation per axis (mm) and per rotation axis (deg).
  double noise_mm = 0.02;
  double noise_deg = 0.002;
  bool orientation = false;      ///< also write the measured orientation (qw..qz)
  bool write_std = false;        ///< write std columns (the noise levels above)
  /// Payload masses (kg) cycled over the poses.
  std::vector<double> payloads_kg = {0.0};
  /// Where the robot base stands in the tracker frame (T_world_base of the real robot), used
  /// when set_station: 3 m from the tracker, turned 30 deg about z and slightly tilted
  /// (tracker not level).
  XyzAbc station = {2400.0, -1700.0, -600.0, 30.0, 0.4, -0.3};
  bool set_station = true;
  /// The measured target on the flange (nominal T_flange_tcp of the real robot), used when
  /// set_tool; the "geometric" effect adds its error on top.
  XyzAbc tool = {};
  bool set_tool = false;
  /// Fraction of each joint range kept free at both ends when drawing random poses.
  double limit_margin = 0.05;
  /// Scale of the random geometric errors: lengths 0.3 mm, angles 0.03 deg (1 sigma) times
  /// this factor.
  double error_scale = 1.0;

  bool IsValid(std::string* error) const;
};

/// The "real" robot: `nominal` with the errors of options.effects drawn from options.seed.
RobotModel perturbModel(const RobotModel& nominal, const SimulateOptions& options);

/// Measurements of `truth` at random poses within its joint limits: positions (and with
/// options.orientation, orientations) with Gaussian noise, and every context column
/// (payload_kg, temp_c, dir1..dirN, time_s). Deterministic for a given seed.
MeasurementSet simulateMeasurements(const RobotModel& truth, const SimulateOptions& options);

}  // namespace accura
