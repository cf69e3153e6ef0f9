// Fuzz target: an XML program through parseXmlProgram, and the round trip the XML writer
// promises (xml_program.h: canonical layout, reading and writing back gives the same bytes):
// write(parse(write(parse(x)))) == write(parse(x)), and the written text always parses.
#include <string>

#include "accura/postproc/xml_program.h"
#include "fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace accura;
  const std::string text(reinterpret_cast<const char*>(data), size);
  postproc::Program program;
  bool parsed = false;
  fuzz::expectParsedOrInputError([&] {
    program = postproc::parseXmlProgram(text, "fuzz.xml");
    parsed = true;
  });
  if (!parsed) return 0;
  std::string once;
  try {
    once = postproc::writeXmlProgram(program);
  } catch (const calib::ArgumentError&) {
    return 0;  // documented: a target that cannot be represented
  } catch (const std::exception& e) {
    fuzz::violation(std::string("writeXmlProgram threw: ") + e.what());
  }
  std::string twice;
  try {
    twice = postproc::writeXmlProgram(postproc::parseXmlProgram(once, "written.xml"));
  } catch (const std::exception& e) {
    fuzz::violation(std::string("the written XML program does not read back: ") + e.what() + "\n--- written:\n" + once);
  }
  if (twice != once) fuzz::violation("XML round trip: writing the program read back gives other bytes\n--- first:\n" + once + "\n--- second:\n" + twice);
  return 0;
}
