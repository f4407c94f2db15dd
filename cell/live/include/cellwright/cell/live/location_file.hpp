// A taught location written into the cell description file (docs/live-view.md, "Saving a location"): a targeted
// edit of the file's text, so that its formatting and comments are kept, and a diff of what changed.
//
// What a taught location means in the cell's terms (docs/cell-description.md, locations): a location is where a part
// rests; a robot grasps it with its tool centre point grasp_height above it, the tool's z axis pointing down and its
// y axis (the fingers' closing direction) along the location's yaw (models::grasp_pose, models::check_reach, robot
// control's Pick/Put at a location). So a taught tool pose T that points down becomes
//     - {name: NAME, pose: {xyz: [Tx, Ty, Tz - 0.02], yaw: atan2(Ty_axis)}, reach: [ROBOT]}
// (grasp_height left at its default, 0.02 m): the location's grasp pose for that robot is T again (the tool's
// position exactly, to the 0.1 mm the file is written with; its orientation to the 0.001 degree of the yaw). A pose
// whose tool points more than kDownTolerance away from straight down is refused: the cell has no location grasped
// from another direction.
//
// The edit (yaml-cpp's marks give each item's line and column): in the file's `locations:` block sequence, the item
// whose name is NAME is replaced: written on one line (a flow mapping, the style the shipped cells use), by the line
// above in its place; written as a block mapping ("- name: NAME" and its keys below), by a block mapping of the keys
// name, pose and reach at the item's column, the full-line comments inside the old item kept after them. Without such
// an item, a new one is inserted after the last, with the last item's indentation and dash. A file without `locations:`
// gets one at its end. The new text must load as a cell description (models::parse_cell: every check, the new
// location's reach included) before anything is written; then the file is replaced atomically (a temporary file in
// its directory, renamed over it). Every other byte of the file is kept.
//
// Thread safety: reentrant (no shared state); two writers of one file at once are the caller's to avoid.
#pragma once

#include <Eigen/Geometry>
#include <filesystem>
#include <string>

namespace cellwright::cell {

inline constexpr double kDownToleranceDeg = 1.0;  // how far from straight down a taught tool may point

// The location line's mapping (without the dash) for a tool pose, e.g. "{name: tray, pose: {xyz: [0.3, 0.4, 0.68],
// yaw: 90}, reach: [puma]}". LiveRefusal (teach.hpp) when the tool does not point down within kDownToleranceDeg.
std::string taught_location_entry(const std::string& name, const std::string& robot, const Eigen::Isometry3d& tool);

struct SavedLocation {
  bool replaced = false;  // an item of that name was replaced (else one was added)
  std::string diff;       // unified diff of the file, old to new ("--- FILE", "+++ FILE", one hunk)
  int line = 0;           // 1-based line of the location in the new file
};

// Writes location `name` (taught by `robot` at `tool`) into `cell_file`, as the top says. `label` names the file in
// the diff's header. LiveRefusal, the file untouched: a name that is not an identifier ([A-Za-z_][A-Za-z0-9_]*); a
// file that cannot be read, is not YAML, or whose `locations:` is not a block sequence; an item of that name written
// as a flow mapping over several lines, or with its keys below a bare dash; a tool not pointing down; a new text that does not load as a cell (the loader's message); a
// file that cannot be written.
SavedLocation save_location(const std::filesystem::path& cell_file, const std::string& label, const std::string& name,
                            const std::string& robot, const Eigen::Isometry3d& tool);

// A unified diff (one hunk, 3 lines of context) between two texts that differ in one run of lines; "" if equal.
std::string unified_diff(const std::string& before, const std::string& after, const std::string& label);

}  // namespace cellwright::cell
