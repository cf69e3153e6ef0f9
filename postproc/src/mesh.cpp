// Triangle meshes of the cell, read with assimp (see cell.h).
#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <cmath>
#include <filesystem>
#include <functional>

#include "accura/calib/errors.h"
#include "accura/postproc/cell.h"

namespace accura::postproc {

Mesh loadMesh(const std::string& path, double scale_to_mm) {
  if (!(scale_to_mm > 0) || !std::isfinite(scale_to_mm))
    throw ArgumentError("loadMesh: scale_to_mm must be a positive number, got " + std::to_string(scale_to_mm));
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw InputError(path, 0, 0, "expected a mesh file, found no such file");
  Assimp::Importer importer;
  // Triangulate polygons, drop points and lines, merge duplicated vertices (for STL, which
  // stores every triangle's corners), apply the scene graph's node transforms.
  importer.SetPropertyInteger(AI_CONFIG_PP_SBP_REMOVE, aiPrimitiveType_POINT | aiPrimitiveType_LINE);
  const aiScene* scene = importer.ReadFile(
      path, aiProcess_Triangulate | aiProcess_JoinIdenticalVertices | aiProcess_SortByPType | aiProcess_PreTransformVertices);
  if (!scene || (scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE) || !scene->mRootNode) {
    const std::string why = importer.GetErrorString();
    throw InputError(path, 0, 0, "expected a mesh file assimp can read (STL, OBJ, PLY, 3MF, glTF, COLLADA, ...), found: " +
                                     (why.empty() ? std::string("an unreadable file") : why));
  }
  Mesh mesh;
  mesh.file = path;
  for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
    const aiMesh* am = scene->mMeshes[m];
    if (!am || !(am->mPrimitiveTypes & aiPrimitiveType_TRIANGLE)) continue;
    const int base = static_cast<int>(mesh.vertices_mm.size());
    for (unsigned v = 0; v < am->mNumVertices; ++v) {
      const aiVector3D& p = am->mVertices[v];
      const Eigen::Vector3d x(p.x, p.y, p.z);
      if (!x.allFinite()) throw InputError(path, 0, 0, "expected finite vertex coordinates, found a NaN or infinite one (vertex " + std::to_string(v) + ")");
      mesh.vertices_mm.push_back(x * scale_to_mm);
    }
    for (unsigned f = 0; f < am->mNumFaces; ++f) {
      const aiFace& face = am->mFaces[f];
      if (face.mNumIndices != 3) continue;
      std::array<int, 3> t{};
      bool ok = true;
      for (int k = 0; k < 3; ++k) {
        if (face.mIndices[k] >= am->mNumVertices) ok = false;
        else t[k] = base + static_cast<int>(face.mIndices[k]);
      }
      if (!ok) throw InputError(path, 0, 0, "expected vertex indices below " + std::to_string(am->mNumVertices) + ", found a larger one (face " + std::to_string(f) + ")");
      mesh.triangles.push_back(t);
    }
  }
  if (mesh.triangles.empty())
    throw InputError(path, 0, 0, "expected a mesh with triangles, found none (" + std::to_string(scene->mNumMeshes) + " mesh(es), no faces)");
  return mesh;
}

}  // namespace accura::postproc
