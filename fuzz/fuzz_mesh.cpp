// Fuzz target: a mesh file through loadMesh (the checks of PLY, STL and OBJ, then assimp and
// its post-processing). The first byte picks the extension (0: .ply, 1: .stl, 2: .obj; the
// value modulo 3), the rest is the file.
#include <string>

#include "accura/postproc/cell.h"
#include "fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace accura;
  if (size < 1) return 0;
  static const char* kNames[] = {"m.ply", "m.stl", "m.obj"};
  const std::string path = fuzz::Scratch::get().write(kNames[data[0] % 3], std::string_view(reinterpret_cast<const char*>(data + 1), size - 1));
  fuzz::expectParsedOrInputError([&] { (void)postproc::loadMesh(path, 1.0); });
  return 0;
}
