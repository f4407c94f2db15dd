// The one URDF loader: every reader of a robot's URDF (the kinematic chain, the MuJoCo scene, the simulated driver)
// gets the robot from here, parsed once with urdfdom, with the line of each <link> and <joint> for its own errors.
//
// Thread safety: a UrdfModel is immutable after loading and may be shared between threads. Loads are serialized
// internally (urdfdom reports through console_bridge's process-wide logger, which is captured during a parse); any
// thread may call the functions.
#pragma once

#include <urdf_model/model.h>

#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "cellwright/common/error.hpp"

namespace cellwright::models {

class UrdfModel {
 public:
  // The file name that errors name.
  const std::string& file() const { return file_; }
  // The robot as urdfdom reads it.
  const urdf::ModelInterface& robot() const { return *robot_; }
  // Where the <link> or <joint> element with this name starts: {file(), line}; line 0 if there is none.
  SourceLocation link_at(const std::string& name) const;
  SourceLocation joint_at(const std::string& name) const;
  // Where the first <mesh> element with this filename attribute is: {file(), line}; line 0 if there is none.
  SourceLocation mesh_at(const std::string& filename) const;
  // Where the index-th (from 0) <tag> element ("inertial", "visual", "collision") of the link with this name
  // starts, in the order urdfdom keeps them (Link::visual_array, collision_array); the link's own line if it has
  // none.
  SourceLocation link_part_at(const std::string& link, const std::string& tag, std::size_t index = 0) const;

 private:
  friend UrdfModel parse_urdf(const std::string& xml, const std::string& file_label);
  UrdfModel() = default;

  std::string file_;
  std::shared_ptr<const urdf::ModelInterface> robot_;
  std::map<std::string, int> link_lines_, joint_lines_, mesh_lines_;
  std::map<std::string, std::map<std::string, std::vector<int>>> link_part_lines_;  // link -> tag -> lines
};

// Reads and parses a URDF file (see parse_urdf). Throws InputError({file}, "cannot read the URDF file: <why>") if it
// cannot be read (read_file's words: "no such file", "is a directory, not a file", "cannot open: <reason>").
// The file is read on every call; text parsed before under the same file name gives the model parsed then (the
// models are immutable; the last 16 kept), so repeated loads of one robot cost a read, not a parse.
UrdfModel load_urdf_file(const std::filesystem::path& file);

// Parses URDF text; errors name `file_label` as the file. Throws InputError:
//  - at the line tinyxml2 reports: "malformed XML: <what is broken>[ in <element>]" ("the file is empty" if so);
//  - at the root element: "the root element is <name>, a URDF needs <robot>";
//  - at the first link or joint urdfdom's message names (line 0 if none): "invalid URDF: <urdfdom's message>".
//  - at the <link> whose <inertial> is not physical: "link '<name>': mass <m> kg is not physical: ...", or "the
//    inertia (<the six values>) is not finite / is not physical: its principal moments ... must not be negative /
//    break the triangle inequality ...". urdfdom takes any numbers, and MuJoCo would simulate a body of -40 kg.
// urdfdom's log messages never reach stderr: they go into the error.
UrdfModel parse_urdf(const std::string& xml, const std::string& file_label);

}  // namespace cellwright::models
