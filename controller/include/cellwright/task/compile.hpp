// Compilation of a task-level program to primitive robot programs (paper section 2): each task-level command is
// divided into motion-level commands (Pick A -> approach A, grasp A, lift up A), the synchronisation the program
// needs is inserted (lock-step barriers between table lines, the hand-over handshake of Put/Get, region
// semaphores), and the result is written as move/open/close/signal/wait primitives (compiled.hpp).
// docs/task-language.md lists every expansion and how inserted events are named.
//
// Thread safety: pure functions over values; any thread may call them.
#pragma once

#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "cellwright/task/compiled.hpp"
#include "cellwright/task/program.hpp"

namespace cellwright::task {

// Compiles a parsed program. Every declared robot gets a program (empty if the source gives it none); robots,
// workpieces and locations keep declaration order; semaphores list the user's semaphores and regions in declaration
// order followed by the events the compiler inserted, in the order they are first used.
// Throws InputError (at the offending command) when the program cannot run as written: Pick while holding, Place or
// Put while holding nothing, Get while holding, picking a workpiece another table robot holds, Place of a workpiece
// on itself, Put without the matching Get on the same line (or Get without Put), Put/Get to itself or outside the
// steps table, entering a region the robot is inside, leaving one it is not inside, a program ending inside a
// region. Throws InternalError if `program` breaks the invariants parse_program establishes.
CompiledProgram compile(const Program& program);

// load_program + compile.
CompiledProgram compile_file(const std::filesystem::path& path);

// A readable listing: per robot, one line per primitive (index, primitive, and a comment with the source line:column,
// the task-level and the motion-level command), then the semaphores/events and the regions with their spans.
std::string format_listing(const CompiledProgram& compiled);

// The compiled program as JSON (docs/task-language.md shows the layout): every field of CompiledProgram, plus each
// primitive's index and text ("move above(A)"). A primitive carries "target" only for move, "workpiece" only for
// open/close and "event" only for signal/wait.
nlohmann::json to_json(const CompiledProgram& compiled);

}  // namespace cellwright::task
