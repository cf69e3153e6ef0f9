// Fuzz target: a measurement CSV (docs/measurement-format.md) of the bundled KUKA KR 16
// through readMeasurementsCsv.
#include <string>

#include "accura/calib/measurements.h"
#include "accura/calib/robot_io.h"
#include "fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace accura;
  static const calib::RobotModel robot = calib::readRobotFile(calib::resolveRobotPath("kuka_kr16"));
  const std::string path = fuzz::Scratch::get().write("m.csv", std::string_view(reinterpret_cast<const char*>(data), size));
  fuzz::expectParsedOrInputError([&] { (void)calib::readMeasurementsCsv(path, robot.nominal); });
  return 0;
}
