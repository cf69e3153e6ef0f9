// Fuzz target: a robot file (docs/robot-format.md) through readRobotFile; a model it reads is
// written (writeRobotFile) and must read back.
#include <string>

#include "accura/calib/robot_io.h"
#include "fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace accura;
  auto& scratch = fuzz::Scratch::get();
  const std::string path = scratch.write("robot.xml", std::string_view(reinterpret_cast<const char*>(data), size));
  calib::RobotModel model;
  bool parsed = false;
  fuzz::expectParsedOrInputError([&] {
    model = calib::readRobotFile(path);
    parsed = true;
  });
  if (!parsed) return 0;
  try {
    calib::writeRobotFile(scratch.path("written.xml"), model);
    (void)calib::readRobotFile(scratch.path("written.xml"));
  } catch (const std::exception& e) {
    fuzz::violation(std::string("a model read from a robot file does not write and read back: ") + e.what());
  }
  return 0;
}
