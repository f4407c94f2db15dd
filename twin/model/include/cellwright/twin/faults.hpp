// Fault specifications: what a scenario's `faults:` list and `twin run --fault SPEC` ask the twin to inject, on
// purpose, seeded and deterministic (docs/faults.md section 1 is the contract; docs/scenarios.md the file format).
//
// A FaultSpec is a plain value: the kind, where (a robot or a workpiece, as the kind needs) and when and what, every
// field holding the kind's default until the input sets it. It is read
//  - from a YAML map, an entry of a scenario's `faults:` list: `{kind: drop, robot: puma, carry: 1, after: 0.5}`
//    (with `every: 50`, again at carries 51, 101, ...: a fault at a set rate, for soaks);
//  - from command-line text, the same fields as `KIND:key=value,key=value`, a list value written `a/b`
//    (`misplace:workpiece=A,offset=0.04/0.02,yaw=10`); to_text() writes that form back (every field of the kind).
// Both check every field: an unknown field or one the kind does not take, a value of the wrong type or range, a
// missing robot or workpiece, a robot or workpiece the cell does not have. Errors are InputError naming the file,
// line, column and field (YAML), or the option and the text (command line).
//
// Who injects what: the physical kinds (drop, slip, misplace, unreachable, missing, obstacle) the World's fault
// injector (twin/sim/fault_injector.hpp); the controller's and the link's (timeout, garbage, hardware, position,
// link_lost) a drivers::FaultyDriver around the robot's simulation driver; lost_signal a filter the rig puts on the
// runtime's signal path (RunConfig::signal_filter); frame_lost and detection_noise the plant's camera and a detector
// decorator (perception: vision only). ScenarioRun (run.hpp) puts them in place and logs them (the runtime does not).
//
// Thread safety: plain values and re-entrant functions.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "cellwright/common/error.hpp"
#include "cellwright/models/cell.hpp"
#include "cellwright/models/yaml_fields.hpp"

namespace cellwright::twin {

// The kinds of docs/faults.md's table, in its order.
enum class FaultKind : std::uint8_t {
  drop,             // robot, carry, after: the gripper loses its grip force for 0.3 s while carrying
  slip,             // robot, carry, after, distance: the held part slides down in the fingers, still held
  misplace,         // workpiece, offset, yaw: the part arrives (or starts) moved and turned
  unreachable,      // workpiece, distance: the part arrives (or starts) on the floor beside its belt, out of reach
  missing,          // workpiece: the part never arrives (or is taken out at the start)
  obstacle,         // robot, time, size, ahead, duration: a box appears in front of the moving tool
  timeout,          // robot, command, n: the controller never answers that command
  garbage,          // robot, command, n: it answers with bytes that are no reply (protocol fault)
  hardware,         // robot, command, n: it reports a hardware error (ER 1)
  position,         // robot, command, n: it refuses the position (ER 2)
  link_lost,        // robot, command, n: the serial link is lost at that command
  lost_signal,      // n: the n-th signal fired loses its event
  frame_lost,       // time, count: the camera delivers no frame
  detection_noise,  // time, duration, sigma, sigma_yaw: detections are off
};
inline constexpr std::size_t kFaultKinds = 14;

// "drop", "slip", ... as in docs/faults.md.
std::string_view to_string(FaultKind kind);
// The kind named `name`, or nullopt.
std::optional<FaultKind> fault_kind(std::string_view name);
// Every kind's name, in order, comma-separated (for messages).
std::string fault_kind_names();

// Which commands a controller fault counts (`command:`): moves (joint or pose) or grips (open or close).
enum class FaultCommand : std::uint8_t { move, grip };
std::string_view to_string(FaultCommand command);

// What the kind needs to say where it happens.
enum class FaultTarget : std::uint8_t { none, robot, workpiece };
FaultTarget target_of(FaultKind kind);
// The kinds injected by the robot's driver (timeout, garbage, hardware, position, link_lost).
bool is_driver_fault(FaultKind kind);
// The kinds that need perception: vision (frame_lost, detection_noise).
bool needs_vision(FaultKind kind);

struct FaultSpec {
  FaultKind kind = FaultKind::drop;
  std::string robot;      // cell robot (drop, slip, obstacle, the driver faults); "" otherwise
  std::string workpiece;  // cell workpiece (misplace, unreachable, missing); "" otherwise
  std::uint64_t carry = 1;                  // drop, slip: the robot's n-th carry (from 1)
  std::uint64_t every = 0;                  // drop, slip: and again every `every` carries after it (0: once only)
  double after = 0.3;                       // drop, slip: s after the carry began
  double distance = 0.015;                  // slip: m the part slides; unreachable: m out from the belt (0.6)
  std::array<double, 2> offset{0.04, 0.02};  // misplace: m along the part's own x and y (sides drawn from the seed)
  double yaw = 30;                          // misplace: degrees (the sense drawn from the seed)
  double size = 0.06;                       // obstacle: m, the cube's side
  double ahead = 0.15;                      // obstacle: m in front of the tool along its motion
  double duration = 2;                      // obstacle: s in the cell; detection_noise: s of noise (4)
  double time = 0;                          // obstacle, frame_lost, detection_noise: s of simulation time
  FaultCommand command = FaultCommand::move;  // driver faults
  std::uint64_t n = 1;                      // driver faults: the n-th such command; lost_signal: the n-th signal
  std::uint64_t count = 2;                  // frame_lost: frames not delivered
  double sigma = 0.01;                      // detection_noise: m, standard deviation of the position noise
  double sigma_yaw = 5;                     // detection_noise: degrees, of the yaw noise
  SourceLocation where;                     // the entry in the scenario file, or {"--fault", 0, 0}

  // The fields the input may set, defaults differing by kind (unreachable's distance 0.6, detection_noise's
  // duration 4) already applied.
  static FaultSpec defaults(FaultKind kind);

  // Every field but `where`.
  bool operator==(const FaultSpec& other) const;
};

// The fields a kind takes besides `kind` (in the order to_text writes them), e.g. {"robot", "carry", "after"}.
const std::vector<std::string>& fault_fields(FaultKind kind);

// Reads one entry of a scenario's `faults:` list (a YAML map with `kind`). Throws InputError at the offending node.
FaultSpec parse_fault(const models::yaml::Doc& doc, const YAML::Node& entry, const models::CellDescription& cell);

// Reads the command-line form `KIND:key=value,...` (`--fault`). Throws InputError naming `option` and the text.
FaultSpec parse_fault_text(std::string_view text, const models::CellDescription& cell,
                           std::string_view option = "--fault");

// The command-line form of a spec, every field of its kind written out, e.g.
// "drop:robot=puma,carry=1,after=0.3"; parse_fault_text() reads it back as the same spec.
std::string to_text(const FaultSpec& fault);

}  // namespace cellwright::twin
