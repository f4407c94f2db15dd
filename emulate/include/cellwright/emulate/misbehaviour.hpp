// What an emulated controller can be told to do wrong (docs/real-robots.md, "What the emulators can be told to do
// wrong"), and the seeded plan that decides, line by line, whether it does. Shared by the Movemaster EX and VAL II
// emulators; each turns a misbehaviour into its own language (an `ER` answer, an error message).
//
// A misbehaviour happens at one line (the n-th line the emulator receives, counting from 1 over the emulator's life,
// reconnections included) or at random, with a probability per line drawn from a generator seeded once: the same seed
// and list give the same lines, whatever the timing.
//
// A misbehaviour may also happen at the n-th line that starts with a given command (KIND@TEXT#N), so that a test can
// aim at a command whatever the position reads around it: the line and TEXT are compared with case and blanks left
// out (`where` matches `WHERE`, `doready` matches `DO READY`), and such an entry counts its lines from the moment the
// entry before it in the list applied (from the start for the first entry): a list is a script, e.g. `error@domove#3
// error@where#1`, the third move fails and then the first WHERE after it.
//
// Written on the command line (`twin emulate ... --misbehave SPEC`, repeatable) as
//   KIND@N          at line N                     e.g. er1@5, drop@12
//   KIND@TEXT#N     at the N-th line starting with TEXT (as above)  e.g. error@where#2, er1@nt#2
//   KIND~P          at each line with probability P (0 < P <= 1)   e.g. garbage~0.05
//   late@N:S, late@TEXT#N:S, late~P:S   answer S seconds late
// KIND is one of:
//   error        the controller reports a hardware error (Movemaster: `ER` answers 1; VAL II: `*Arm power off*`)
//   er1          the same (Movemaster's name for it)
//   unreachable  a position error (Movemaster: `ER` answers 2; VAL II: `*Location out of range*`)
//   er2          the same
//   garbage      the answer is replaced by bytes that are not the protocol
//   silent       the line is taken and never answered (nor executed)
//   drop         the line is hung up (the pseudo-terminal closes; a new one is published at the same path)
//   late         the answer comes S seconds late
//   unknown      an error the controller's documents do not list (Movemaster: `ER` answers 9; VAL II:
//                `*Invalid format*`): the drivers class it as unknown
#pragma once

#include <chrono>
#include <cstdint>
#include <optional>
#include <random>
#include <string>
#include <string_view>
#include <vector>

namespace cellwright::emulate {

enum class MisbehaviourKind : std::uint8_t { error, unreachable, garbage, silent, drop, late, unknown };

struct Misbehaviour {
  MisbehaviourKind kind = MisbehaviourKind::error;
  std::uint64_t at_line = 0;          // 1-based; 0: at random
  // Not empty: at_line counts only the lines that start with this command (upper case, no blanks; see above).
  std::string command;
  double probability = 0.0;           // when at_line is 0
  std::chrono::nanoseconds delay{0};  // late only
};

// Parses one SPEC as above. Throws InputError naming `option` (e.g. "--misbehave") and the text when malformed.
Misbehaviour parse_misbehaviour(const std::string& spec, const std::string& option = "--misbehave");
// "er1@5", "error@WHERE#2", "late~0.100000:1.500000": a spec that parses back to the same misbehaviour.
std::string to_string(const Misbehaviour& m);
const char* to_string(MisbehaviourKind kind);

// The misbehaviours of one emulator and the generator behind the random ones.
class MisbehaviourPlan {
 public:
  MisbehaviourPlan(std::vector<Misbehaviour> list, std::uint64_t seed);

  // Called once per received line (`text`: the line as received, without its end), in order: the misbehaviour for
  // it, if any (the first of the list that applies; a fixed line wins over a random one). The random draws happen on
  // every line for every random entry, so that one entry's outcome does not shift the others'.
  std::optional<Misbehaviour> next_line(std::string_view text = {});
  // Lines seen so far.
  std::uint64_t lines() const { return lines_; }

 private:
  std::vector<Misbehaviour> list_;
  std::vector<std::uint64_t> matched_;  // per entry with a command: its lines seen since it was armed
  std::vector<bool> applied_;           // per entry: it has applied at least once
  std::mt19937_64 random_;
  std::uint64_t lines_ = 0;
};

}  // namespace cellwright::emulate
