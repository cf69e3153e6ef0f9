// Fuzz target: a $config.dat (TOOL_DATA / BASE_DATA) through readKrlFrameTables.
#include <string>

#include "accura/postproc/krl.h"
#include "fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace accura;
  const std::string path = fuzz::Scratch::get().write("$config.dat", std::string_view(reinterpret_cast<const char*>(data), size));
  fuzz::expectParsedOrInputError([&] { (void)postproc::readKrlFrameTables(path); });
  return 0;
}
