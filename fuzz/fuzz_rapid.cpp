// Fuzz target: a RAPID module through parseRapid, and the round trip the RAPID writer
// promises (rapid.h): an unmodified module is written back byte for byte; and a module whose
// every Cartesian target is marked corrected (same value) writes and reads back with the same
// number of motions (two corrections of one declared robtarget are the only ArgumentError).
#include <string>

#include "accura/postproc/rapid.h"
#include "fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace accura;
  const std::string text(reinterpret_cast<const char*>(data), size);
  postproc::Program program;
  bool parsed = false;
  fuzz::expectParsedOrInputError([&] {
    program = postproc::parseRapid(text, "fuzz.mod");
    parsed = true;
  });
  if (!parsed) return 0;
  std::string back;
  try {
    back = postproc::writeRapid(program);
  } catch (const std::exception& e) {
    fuzz::violation(std::string("writeRapid of an unmodified module threw: ") + e.what());
  }
  if (back != text) fuzz::violation("RAPID round trip: the module written back differs from the one read");
  for (auto& m : program.motions) {
    if (m.target.kind == postproc::Target::Kind::kCartesian && m.target.completePose()) m.target.modified = true;
    if (m.aux && m.aux->completePose()) m.aux->modified = true;
  }
  std::string rewritten;
  try {
    rewritten = postproc::writeRapid(program);
  } catch (const calib::ArgumentError&) {
    return 0;
  } catch (const std::exception& e) {
    fuzz::violation(std::string("writeRapid of a corrected module threw: ") + e.what());
  }
  try {
    const postproc::Program again = postproc::parseRapid(rewritten, "rewritten.mod");
    if (again.motions.size() != program.motions.size()) fuzz::violation("RAPID: the rewritten module has another number of motions\n" + rewritten);
  } catch (const std::exception& e) {
    fuzz::violation(std::string("the rewritten RAPID module does not read back: ") + e.what() + "\n--- written:\n" + rewritten);
  }
  return 0;
}
