// Fuzz target: a KRL program (.src, and its .dat after a line "#####") through readKrl, and
// the round trip the KRL writer promises: an unmodified program is written back byte for byte
// (krl.h), so writeKrl(readKrl(src, dat)) gives src and dat again.
#include <string>

#include "accura/postproc/krl.h"
#include "fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace accura;
  const std::string_view in(reinterpret_cast<const char*>(data), size);
  const auto [src, dat] = fuzz::splitPair(in, std::string_view());
  const bool has_dat = dat.data() != nullptr;
  auto& scratch = fuzz::Scratch::get();
  const std::string src_path = scratch.write("fuzz.src", src);
  std::string dat_path;
  if (has_dat) dat_path = scratch.write("fuzz.dat", dat);
  else std::remove(scratch.path("fuzz.dat").c_str());
  postproc::Program program;
  bool parsed = false;
  fuzz::expectParsedOrInputError([&] {
    postproc::KrlReadOptions o;
    o.dat_path = dat_path;
    program = postproc::readKrl(src_path, o);
    parsed = true;
  });
  if (!parsed) return 0;
  postproc::KrlText text;
  try {
    text = postproc::writeKrl(program);
  } catch (const std::exception& e) {
    fuzz::violation(std::string("writeKrl of an unmodified program threw: ") + e.what());
  }
  if (text.src != src) fuzz::violation("KRL round trip: the .src written back differs from the one read");
  if (has_dat && text.dat != dat) fuzz::violation("KRL round trip: the .dat written back differs from the one read");
  return 0;
}
