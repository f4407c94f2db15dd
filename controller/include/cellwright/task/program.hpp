// The task-level language (paper section 2, Table 1): its abstract syntax tree and its parser.
//
// A program declares the labels of the environment (robots, workpieces, locations), the semaphores and critical
// regions, and then says what each robot does, either in one lock-step table (`steps ... end`: robots as columns,
// steps as lines; a line starts when every command of the line before has finished) or in free per-robot sequences
// (`sequence ROBOT ... end`). The full language is described in docs/task-language.md.
//
// parse_program() checks the syntax and resolves every name against the declarations, so a Program it returns only
// names things that are declared and of the right kind. What a program *does* (who holds which workpiece, Put/Get
// pairing, regions entered and left) is checked by compile() in compile.hpp.
//
// Thread safety: plain values and pure functions; any thread may call them.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "cellwright/common/error.hpp"

namespace cellwright::task {

// The kinds of declared names. All names share one namespace.
// Devices (kMachine, kConveyor, kSensor) are the cell's ancillary equipment: the process machine, the belts and their
// photo-eyes (docs/task-language.md, "Devices"). kBlock names a coordinated block (`coordinated NAME ...`, below).
enum class NameKind : std::uint8_t {
  kRobot, kWorkpiece, kLocation, kSemaphore, kRegion, kMachine, kConveyor, kSensor, kBlock
};

// "robot", "workpiece", "location", "semaphore", "region", "machine", "conveyor", "sensor", "coordinated block".
const char* to_string(NameKind k);

// One declared name, e.g. `semaphore s = 2` or one of the names of `robot r1 r2`.
struct Declaration {
  NameKind kind = NameKind::kRobot;
  std::string name;
  std::uint32_t initial = 0;  // semaphores: initial count; always 0 for the other kinds
  SourceLocation where;       // the name token in the declaration
  // Workpieces only: a class (`workpiece part from IN`, one name per such statement) names the location its parts
  // arrive at (a declared location); empty for a named workpiece.
  // Sensors: the conveyor whose parts the photo-eye sees (`sensor in_stop on IN`, a declared conveyor).
  std::string from;
  SourceLocation from_where;  // the location token after `from` (the conveyor token after `on`)
};

// Device commands (docs/task-language.md, "Devices"): kStart (a machine's cycle), kRun / kStop / kAccumulate (a
// conveyor); `wait` also takes a machine (until its cycle is done) or a sensor (until it sees a part), `Place` a
// machine (put the held part into it) and `Pick W from M` takes W out of machine M. kHome and kPark send the robot to
// its home or park pose and take no argument.
// kCoordinate runs a coordinated block (`coordinate NAME`, in the programs of both of the block's robots); kVia stands
// only in a coordinated block's body (`via LOCATION`: carry the workpiece over that location).
enum class CommandKind : std::uint8_t {
  kPick, kPut, kGet, kPlace, kSignal, kWait, kEnter, kLeave, kStart, kRun, kStop, kAccumulate, kHome, kPark,
  kCoordinate, kVia
};

// The canonical spelling of the command keyword: "Pick", "Put", "Get", "Place", "signal", "wait", "enter", "leave",
// "start", "run", "stop", "accumulate", "home", "park", "coordinate", "via".
const char* to_string(CommandKind k);

// One task-level command with its argument (none for home and park).
struct Command {
  CommandKind kind = CommandKind::kPick;
  std::string argument;                           // the name the command takes; empty for home and park
  NameKind argument_kind = NameKind::kWorkpiece;  // what the argument resolved to (Place: workpiece, location or
                                                  // machine; wait: semaphore, machine or sensor)
  SourceLocation where;                           // the command keyword
  SourceLocation argument_where;                  // the argument token
  std::string machine;                            // `Pick W from M`: the machine M; empty otherwise
  SourceLocation machine_where;                   // its token
};

// "Pick A", "Put r2", "signal s1", "Pick A from mill", "home": canonical keyword spelling, then the arguments.
std::string to_string(const Command& c);

// One line of the lock-step table.
struct StepLine {
  int step = 0;          // 1-based step number: the line's position in the table (the header is not a step)
  SourceLocation where;  // the line's first token
  std::vector<std::optional<Command>> cells;  // exactly one per column of the table; nullopt = the robot idles
};

// A `repeat N ... end` block inside a steps table or a sequence: lines (table) or commands (sequence) [begin, end)
// are its body, run `count` times. Loops do not nest, and a body is never empty.
//
// In a sequence, `repeat N with R2 R3 ...` makes the loop one with the loops of the named robots' sequences: one
// decision for all of them (docs/task-language.md, "Loops in cooperating sequences"). `partners` are those names as
// written (resolved by compile()); empty for a loop that decides alone and in the steps table.
struct LoopBlock {
  SourceLocation where;     // the `repeat` keyword
  std::uint32_t count = 1;  // at least 1
  std::size_t begin = 0;
  std::size_t end = 0;
  std::vector<std::string> partners;          // sequences only: the robots named after `with`, in order
  std::vector<SourceLocation> partner_where;  // each of them in the source
};

// The `steps ... end` block.
struct StepTable {
  SourceLocation where;                     // the `steps` keyword
  std::vector<std::string> robots;          // the columns, left to right, as named in the header line
  std::vector<SourceLocation> robot_where;  // each column's name in the header line
  std::vector<StepLine> lines;              // in source order
  std::vector<LoopBlock> loops;             // in source order, indexes into `lines`
};

// A `sequence ROBOT ... end` block: one robot's commands, executed one after the other, unsynchronised with the
// other robots except through semaphores and regions.
struct Sequence {
  std::string robot;
  SourceLocation where;  // the robot name after `sequence`
  std::vector<Command> commands;
  std::vector<LoopBlock> loops;  // in source order, indexes into `commands`
};

// A coordinated block (docs/task-language.md, "Coordinated motion: two robots carry one workpiece"):
//
//   coordinated carry master left follower right
//     Pick beam        # both grasp the workpiece, each at its own grasp point
//     via MID          # carry it over MID (any number of these)
//     Place FIX        # put it down together
//   end
//
// Both robots run it with `coordinate carry` in their own program (a table cell or a sequence line). Every segment of
// the block (each move and each gripper action) is done by both robots together: the master goes to its target at
// the programmed speed, the follower to the master's target composed with the fixed grasp transform between the two
// grasp points; both start and stop each segment together. The body is one Pick of a named workpiece, then any
// number of `via LOCATION`, then one Place.
struct CoordinatedBlock {
  std::string name;
  SourceLocation where;  // the block's name in the `coordinated` statement
  std::string master, follower;
  SourceLocation master_where, follower_where;
  std::vector<Command> body;  // kPick, kVia..., kPlace (checked by parse_program)
  SourceLocation end_where;   // the block's `end`
};

// A parsed, name-resolved program.
// Invariants (established by parse_program): every name is declared once; the table's robots are distinct robots;
// a coordinated block's master and follower are two distinct robots and its body is Pick, via..., Place;
// no robot is both a table column and a sequence, and no robot has two sequences; every command argument is
// declared with the kind the command needs (`argument_kind` says which).
struct Program {
  std::string file;                       // as given to the parser; used in every SourceLocation
  std::vector<Declaration> declarations;  // in source order
  std::optional<StepTable> steps;
  std::vector<Sequence> sequences;  // in source order
  std::vector<CoordinatedBlock> blocks;  // in source order; each name is also a kBlock declaration
};

// The coordinated block named `name`, or nullptr.
const CoordinatedBlock* find_block(const Program& program, std::string_view name);

// The declaration of `name`, or nullptr if it is not declared.
const Declaration* find_declaration(const Program& program, std::string_view name);

// The names declared with kind `kind`, in declaration order.
std::vector<std::string> declared_names(const Program& program, NameKind kind);

// Parses program text. `file` is used only to name the source in locations and messages.
// Throws InputError (file, line, column of the offending token) on any syntax error, unknown or misused name,
// duplicate declaration, robot both in the table and in a sequence, and missing `end`; and for a program that gives
// no robot anything to do: one with no statements at all (at line 1: "the program is empty"), or with declarations
// but no `steps` table and no `sequence` (at the first declaration). A UTF-8 byte-order mark at the start is skipped.
Program parse_program(std::string_view text, const std::string& file);

// Reads and parses a program file. Throws InputError as parse_program does, and when the file cannot be read.
Program load_program(const std::filesystem::path& path);

}  // namespace cellwright::task
