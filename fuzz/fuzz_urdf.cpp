// Fuzz target: a URDF (docs/robot-format.md, "URDF") through parseUrdfChain and modelFromChain,
// the two steps of readUrdfRobot; a model read is written as URDF (modelToUrdf, which reads its
// text back and checks its kinematics) and that text must read back as a model with as many
// joints. The input is also read once as a file through readRobotFile (the .urdf extension
// selects the URDF reader, as the command line does).
#include <string>

#include "accura/calib/robot_io.h"
#include "accura/calib/urdf.h"
#include "fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace accura;
  const std::string text(reinterpret_cast<const char*>(data), size);
  calib::RobotModel model;
  bool parsed = false;
  fuzz::expectParsedOrInputError([&] {
    model = calib::modelFromChain(calib::parseUrdfChain(text, "fuzz.urdf"));
    parsed = true;
  });
  if (!parsed) return 0;
  try {
    const calib::UrdfText written = calib::modelToUrdf(model);
    const calib::RobotModel back = calib::modelFromChain(calib::parseUrdfChain(written.text, "written.urdf"));
    if (back.dof() != model.dof()) fuzz::violation("a URDF written from a model reads back with another joint count");
    const std::string path = fuzz::Scratch::get().write("robot.urdf", text);
    if (calib::readRobotFile(path).dof() != model.dof()) fuzz::violation("readRobotFile reads another joint count");
  } catch (const std::exception& e) {
    fuzz::violation(std::string("a model read from a URDF does not write and read back: ") + e.what());
  }
  return 0;
}
