// Robot meshes as MuJoCo 2.2 reads them. MuJoCo 2.2.2 reads binary STL (and its own MSH); URDFs as makers publish
// them also use Collada (.dae), ASCII STL, OBJ and others. Those are converted with Assimp (the Open Asset Import
// Library) into binary STL files in a cache directory, named by a hash of the source's bytes, so that a file is
// converted once and the saved MJCF (twin snapshot --mjcf) finds it too.
//
// How: Assimp reads the file (triangulated, node transforms and the file's unit baked into the vertices; a Collada
// file's <up_axis> is ignored, as ROS's viewer does, so that the mesh lies in its link frame as its maker drew it)
// and writes every mesh of it into one binary STL. Colours and textures are dropped: the scene colours a mesh with
// the URDF's <material>.
//
// Thread safety: any thread may call mujoco_mesh; conversions write each cache file atomically (files.hpp).
#pragma once

#include <filesystem>

#include "cellwright/common/error.hpp"

namespace cellwright::twin {

// Where converted meshes are kept: $CW_MESH_CACHE if set, else $XDG_CACHE_HOME/cellwright/meshes, else
// $HOME/.cache/cellwright/meshes, else cellwright-meshes in the system's temporary directory.
std::filesystem::path mesh_cache_dir();

// A file MuJoCo 2.2 reads with the same geometry as `source`: `source` itself if it is a binary STL, else its
// conversion in mesh_cache_dir(). Throws InputError at `where` (the URDF's file and line of the <mesh>) naming the
// file and the reason: "mesh file F cannot be read: <Assimp's reason>", "mesh file F has no triangles", or "mesh
// file F: cannot write its conversion to <dir>: <reason>".
std::filesystem::path mujoco_mesh(const std::filesystem::path& source, const SourceLocation& where);

}  // namespace cellwright::twin
