// Fuzz target: a measurement mapping (docs/measurement-mapping.md) and, after a line "#####",
// the export it maps (default: two rows of the ipa-robot-accuracy UR10 export), through
// readMeasurementMapping and readMappedMeasurements with the bundled UR10.
#include <string>

#include "accura/calib/import.h"
#include "accura/calib/robot_io.h"
#include "fuzz_util.h"

namespace {
// the header and two rows of tests/data/ipa-robot-accuracy/series_c_random_poses.csv
constexpr std::string_view kExport =
    "Timestamp;Goal x;Goal y;Goal z;Goal roll;Goal pitch;Goal yaw;shoulder_pan_joint;shoulder_lift_joint;elbow_joint;wrist_1_joint;"
    "wrist_2_joint;wrist_3_joint;measurement_temperature;measurement_x;measurement_std_x;measurement_y;measurement_std_y;measurement_z;"
    "measurement_std_z;measurement_rx;measurement_std_rx;measurement_ry;measurement_std_ry;measurement_rz;measurement_std_rz\n"
    "2,02011E+13;-0,000181978;-0,365141;1,4273;1,57005;1,56969;-0,000186977;-3,14159;-1,5708;0;-1,5708;0;0;21,68000031;383,97123;"
    "0,041565;-3240,7562;0,022023;201,72621;0,0055848;-90,179563;0,0024569;-20,112975;0,0065397;-90,157388;0,008348\n"
    "2,02011E+13;0,0103459;-0,480444;1,00632;3,10253;1,66683;1,57927;-4,08444;-2,6946;1,69873;-2,031;0,99275;-0,0673035;21,68000031;"
    "335,14778;0,0054521;-3134,3677;0,0062093;-221,16088;0,0076535;-84,20352;0,00099888;-22,726835;0,0026542;-88,245609;0,0014716\n";
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace accura;
  static const calib::RobotModel robot = calib::readRobotFile(calib::resolveRobotPath("ur10"));
  auto& scratch = fuzz::Scratch::get();
  const auto [map, csv] = fuzz::splitPair(std::string_view(reinterpret_cast<const char*>(data), size), kExport);
  const std::string map_path = scratch.write("e.map", map);
  const std::string csv_path = scratch.write("e.csv", csv);
  fuzz::expectParsedOrInputError([&] {
    const calib::MeasurementMapping mapping = calib::readMeasurementMapping(map_path, robot.nominal);
    (void)calib::readMappedMeasurements(csv_path, mapping, robot.nominal);
  });
  return 0;
}
