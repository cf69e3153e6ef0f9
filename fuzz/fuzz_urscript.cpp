// Fuzz target: a URScript program through parseUrScript, and the round trip the URScript
// writer promises (urscript.h): an unmodified program is written back byte for byte; and a
// program whose every Cartesian target is marked corrected (same value) writes and reads back
// with the same number of motions (the literal solving of pose_trans / pose_add never throws
// anything but ArgumentError).
#include <string>

#include "accura/postproc/urscript.h"
#include "fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace accura;
  const std::string text(reinterpret_cast<const char*>(data), size);
  postproc::Program program;
  bool parsed = false;
  fuzz::expectParsedOrInputError([&] {
    program = postproc::parseUrScript(text, "fuzz.script");
    parsed = true;
  });
  if (!parsed) return 0;
  std::string back;
  try {
    back = postproc::writeUrScript(program);
  } catch (const std::exception& e) {
    fuzz::violation(std::string("writeUrScript of an unmodified program threw: ") + e.what());
  }
  if (back != text) fuzz::violation("URScript round trip: the script written back differs from the one read");
  for (auto& m : program.motions) {
    if (m.target.kind == postproc::Target::Kind::kCartesian && m.target.completePose()) m.target.modified = true;
    if (m.aux && m.aux->completePose()) m.aux->modified = true;
  }
  std::string rewritten;
  try {
    rewritten = postproc::writeUrScript(program);
  } catch (const calib::ArgumentError&) {
    return 0;  // documented: a literal used by two targets that need different values
  } catch (const std::exception& e) {
    fuzz::violation(std::string("writeUrScript of a corrected program threw: ") + e.what());
  }
  try {
    const postproc::Program again = postproc::parseUrScript(rewritten, "rewritten.script");
    if (again.motions.size() != program.motions.size()) fuzz::violation("URScript: the rewritten script has another number of motions\n" + rewritten);
  } catch (const std::exception& e) {
    fuzz::violation(std::string("the rewritten URScript does not read back: ") + e.what() + "\n--- written:\n" + rewritten);
  }
  return 0;
}
