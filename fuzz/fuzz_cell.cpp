// Fuzz target: a cell file (docs/cell-format.md) and, after a line "#####", the bytes of a
// mesh it can name as m.ply, m.stl or m.obj (the same bytes under each name), through
// readCellFile, which reads the meshes with loadMesh (checks, then assimp).
#include <string>

#include "accura/postproc/cell.h"
#include "fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace accura;
  auto& scratch = fuzz::Scratch::get();
  const auto [cell, mesh] = fuzz::splitPair(std::string_view(reinterpret_cast<const char*>(data), size), std::string_view());
  const std::string cell_path = scratch.write("cell.xml", cell);
  for (const char* name : {"m.ply", "m.stl", "m.obj"}) scratch.write(name, mesh);
  fuzz::expectParsedOrInputError([&] { (void)postproc::readCellFile(cell_path); });
  return 0;
}
