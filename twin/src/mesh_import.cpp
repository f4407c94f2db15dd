// Robot meshes as MuJoCo 2.2 reads them (mesh_import.hpp): binary STL as it is, anything else converted with Assimp.
#include "cellwright/twin/mesh_import.hpp"

#include <assimp/Exporter.hpp>
#include <assimp/Importer.hpp>
#include <assimp/config.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <system_error>

#include "cellwright/common/files.hpp"

namespace cellwright::twin {
namespace {

// Bumped when the conversion changes, so that old cache files are not reused.
constexpr const char* kConversionVersion = "assimp-stlb-1";

// A binary STL: an 80-byte header, a 32-bit triangle count, 50 bytes per triangle, nothing else. (An ASCII STL
// starts with "solid" and cannot match the size by chance except in odd cases, which MuJoCo would then reject.)
bool is_binary_stl(const std::string& bytes) {
  if (bytes.size() < 84) return false;
  std::uint32_t count = 0;
  std::memcpy(&count, bytes.data() + 80, sizeof count);
  return count > 0 && bytes.size() == 84 + 50ULL * count;
}

// FNV-1a, 64 bits: a cache key, not a security measure.
std::uint64_t fnv1a(const std::string& bytes) {
  std::uint64_t h = 0xcbf29ce484222325ULL;
  for (unsigned char c : bytes) {
    h ^= c;
    h *= 0x100000001b3ULL;
  }
  for (const char* p = kConversionVersion; *p != '\0'; ++p) {
    h ^= static_cast<unsigned char>(*p);
    h *= 0x100000001b3ULL;
  }
  return h;
}

std::string extension_lower(const std::filesystem::path& p) {
  std::string e = p.extension().string();
  for (char& c : e) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return e;
}

}  // namespace

std::filesystem::path mesh_cache_dir() {
  if (const char* dir = std::getenv("CW_MESH_CACHE"); dir != nullptr && *dir != '\0') return dir;
  if (const char* dir = std::getenv("XDG_CACHE_HOME"); dir != nullptr && *dir != '\0') {
    return std::filesystem::path(dir) / "cellwright" / "meshes";
  }
  if (const char* home = std::getenv("HOME"); home != nullptr && *home != '\0') {
    return std::filesystem::path(home) / ".cache" / "cellwright" / "meshes";
  }
  return std::filesystem::temp_directory_path() / "cellwright-meshes";
}

std::filesystem::path mujoco_mesh(const std::filesystem::path& source, const SourceLocation& where) {
  std::string bytes;
  try {
    bytes = read_file(source);
  } catch (const InputError& e) {
    throw InputError(where, fmt::format("mesh file {} cannot be read: {}", source.string(), e.problem()));
  }
  if (is_binary_stl(bytes)) return source;

  const std::filesystem::path dir = mesh_cache_dir();
  const std::filesystem::path out = dir / fmt::format("{:016x}.stl", fnv1a(bytes));
  std::error_code ec;
  if (std::filesystem::is_regular_file(out, ec)) return out;

  Assimp::Importer importer;
  importer.SetPropertyBool(AI_CONFIG_IMPORT_COLLADA_IGNORE_UP_DIRECTION, true);
  // Lines and points are not surfaces: drop them rather than fail on them.
  importer.SetPropertyInteger(AI_CONFIG_PP_SBP_REMOVE, aiPrimitiveType_POINT | aiPrimitiveType_LINE);
  const aiScene* scene =
      importer.ReadFileFromMemory(bytes.data(), bytes.size(),
                                  aiProcess_Triangulate | aiProcess_PreTransformVertices | aiProcess_SortByPType |
                                      aiProcess_JoinIdenticalVertices,
                                  extension_lower(source).c_str() + (extension_lower(source).empty() ? 0 : 1));
  if (scene == nullptr) {
    throw InputError(where, fmt::format("mesh file {} cannot be read: {}", source.string(), importer.GetErrorString()));
  }
  std::size_t triangles = 0;
  for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
    const aiMesh* mesh = scene->mMeshes[m];
    if ((mesh->mPrimitiveTypes & aiPrimitiveType_TRIANGLE) != 0) triangles += mesh->mNumFaces;
  }
  if (triangles == 0) throw InputError(where, fmt::format("mesh file {} has no triangles", source.string()));

  Assimp::Exporter exporter;
  const aiExportDataBlob* blob = exporter.ExportToBlob(scene, "stlb");
  if (blob == nullptr) {
    throw InputError(where, fmt::format("mesh file {} cannot be converted to STL: {}", source.string(),
                                        exporter.GetErrorString()));
  }
  std::filesystem::create_directories(dir, ec);
  try {
    write_file_atomically(out, std::string_view(static_cast<const char*>(blob->data), blob->size));
  } catch (const InputError& e) {
    throw InputError(where, fmt::format("mesh file {}: cannot write its conversion to {}: {}", source.string(),
                                        dir.string(), e.problem()));
  }
  return out;
}

}  // namespace cellwright::twin
