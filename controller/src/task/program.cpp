// Parser of the task-level language: a line-oriented lexer, a block parser (declarations, one steps table, free
// sequences) and a name-resolution pass run after the whole file is read, so names may be used before they are
// declared.
#include "cellwright/task/program.hpp"

#include "cellwright/common/files.hpp"
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <fstream>
#include <functional>
#include <limits>
#include <sstream>
#include <system_error>
#include <utility>

namespace cellwright::task {

const char* to_string(NameKind k) {
  switch (k) {
    case NameKind::kRobot:
      return "robot";
    case NameKind::kWorkpiece:
      return "workpiece";
    case NameKind::kLocation:
      return "location";
    case NameKind::kSemaphore:
      return "semaphore";
    case NameKind::kRegion:
      return "region";
    case NameKind::kMachine:
      return "machine";
    case NameKind::kConveyor:
      return "conveyor";
    case NameKind::kSensor:
      return "sensor";
    case NameKind::kBlock:
      return "coordinated block";
  }
  return "?";
}

const char* to_string(CommandKind k) {
  switch (k) {
    case CommandKind::kPick:
      return "Pick";
    case CommandKind::kPut:
      return "Put";
    case CommandKind::kGet:
      return "Get";
    case CommandKind::kPlace:
      return "Place";
    case CommandKind::kSignal:
      return "signal";
    case CommandKind::kWait:
      return "wait";
    case CommandKind::kEnter:
      return "enter";
    case CommandKind::kLeave:
      return "leave";
    case CommandKind::kStart:
      return "start";
    case CommandKind::kRun:
      return "run";
    case CommandKind::kStop:
      return "stop";
    case CommandKind::kAccumulate:
      return "accumulate";
    case CommandKind::kHome:
      return "home";
    case CommandKind::kPark:
      return "park";
    case CommandKind::kCoordinate:
      return "coordinate";
    case CommandKind::kVia:
      return "via";
  }
  return "?";
}

std::string to_string(const Command& c) {
  if (c.argument.empty()) return to_string(c.kind);
  if (!c.machine.empty()) return fmt::format("{} {} from {}", to_string(c.kind), c.argument, c.machine);
  return fmt::format("{} {}", to_string(c.kind), c.argument);
}

const Declaration* find_declaration(const Program& program, std::string_view name) {
  for (const Declaration& d : program.declarations) {
    if (d.name == name) return &d;
  }
  return nullptr;
}

const CoordinatedBlock* find_block(const Program& program, std::string_view name) {
  for (const CoordinatedBlock& b : program.blocks) {
    if (b.name == name) return &b;
  }
  return nullptr;
}

std::vector<std::string> declared_names(const Program& program, NameKind kind) {
  std::vector<std::string> names;
  for (const Declaration& d : program.declarations) {
    if (d.kind == kind) names.push_back(d.name);
  }
  return names;
}

namespace {

// ---- lexer -------------------------------------------------------------------------------------------------------

enum class TokenKind : std::uint8_t { kName, kNumber, kEquals, kBar };

struct Token {
  TokenKind kind = TokenKind::kName;
  std::string text;
  int column = 0;  // 1-based byte column
};

bool is_name_start(char c) {
  return std::isalpha(static_cast<unsigned char>(c)) != 0 || c == '_';
}
bool is_name_char(char c) {
  return std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '_';
}
bool is_digit(char c) {
  return c >= '0' && c <= '9';
}
bool is_blank(char c) {
  return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
}

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

// How a token is quoted in messages.
std::string quoted(const Token& t) {
  return fmt::format("'{}'", t.text);
}

std::string describe_char(char c) {
  const auto u = static_cast<unsigned char>(c);
  if (u >= 0x21 && u < 0x7f) return fmt::format("character '{}'", c);
  return fmt::format("byte 0x{:02x}", static_cast<unsigned>(u));
}

// ---- keywords ----------------------------------------------------------------------------------------------------

struct CommandSpec {
  const char* keyword;  // lower case
  CommandKind kind;
  const char* needs;  // what the argument must be, for messages ("a workpiece")
};

constexpr std::array<CommandSpec, 8> kCommands{{
    {"pick", CommandKind::kPick, "a workpiece"},
    {"put", CommandKind::kPut, "a robot"},
    {"get", CommandKind::kGet, "a robot"},
    {"place", CommandKind::kPlace, "a workpiece or location"},
    {"signal", CommandKind::kSignal, "a semaphore"},
    {"wait", CommandKind::kWait, "a semaphore"},
    {"enter", CommandKind::kEnter, "a region"},
    {"leave", CommandKind::kLeave, "a region"},
}};

// The device commands and the robot's home/park. They came after programs had been written with names like
// `machine` or `home`, so they are recognised by position only (a command at the start of a cell or a sequence line)
// and are not reserved: a program may still name a region `machine` (scenes/pick_place.task does). `needs` is
// empty for a command without argument.
constexpr std::array<CommandSpec, 7> kDeviceCommands{{
    {"start", CommandKind::kStart, "a machine"},
    {"run", CommandKind::kRun, "a conveyor"},
    {"stop", CommandKind::kStop, "a conveyor"},
    {"accumulate", CommandKind::kAccumulate, "a conveyor"},
    {"home", CommandKind::kHome, ""},
    {"park", CommandKind::kPark, ""},
    // Coordinated motion came later too: `coordinate NAME` runs a coordinated block.
    {"coordinate", CommandKind::kCoordinate, "a coordinated block"},
}};

// `via LOCATION` stands only in a coordinated block's body (recognised there by position, not reserved).
constexpr CommandSpec kVia{"via", CommandKind::kVia, "a location"};

// Statements that open a top-level line. Also reserved: they cannot be names.
constexpr std::array<const char*, 8> kStatements{"robot",  "workpiece", "location", "semaphore",
                                                 "region", "steps",     "sequence", "end"};

// Words that are neither statements nor commands but are reserved too: `repeat N` opens a loop inside a block,
// `from` names where the parts of a workpiece class arrive.
constexpr std::array<const char*, 2> kOtherKeywords{"repeat", "from"};

const CommandSpec* find_command(std::string_view word) {
  const std::string w = lower(word);
  for (const CommandSpec& c : kCommands) {
    if (w == c.keyword) return &c;
  }
  return nullptr;
}

// A command keyword or a device command word.
const CommandSpec* find_any_command(std::string_view word) {
  if (const CommandSpec* c = find_command(word)) return c;
  const std::string w = lower(word);
  for (const CommandSpec& c : kDeviceCommands) {
    if (w == c.keyword) return &c;
  }
  return nullptr;
}

const CommandSpec& spec_of(CommandKind kind) {
  for (const CommandSpec& c : kCommands) {
    if (c.kind == kind) return c;
  }
  for (const CommandSpec& c : kDeviceCommands) {
    if (c.kind == kind) return c;
  }
  if (kind == CommandKind::kVia) return kVia;
  return kCommands[0];
}

bool is_statement(std::string_view word, std::string_view statement) {
  return lower(word) == statement;
}

bool is_keyword(std::string_view word) {
  const std::string w = lower(word);
  for (const char* s : kStatements) {
    if (w == s) return true;
  }
  for (const char* s : kOtherKeywords) {
    if (w == s) return true;
  }
  return find_command(w) != nullptr;
}

// A statement keyword that can only begin a top-level line (everything but `end`).
bool is_top_level_statement(const Token& t) {
  if (t.kind != TokenKind::kName) return false;
  const std::string w = lower(t.text);
  return w != "end" && std::find_if(kStatements.begin(), kStatements.end(), [&](const char* s) { return w == s; }) !=
                           kStatements.end();
}

constexpr const char* kCommandList =
    "Pick, Put, Get, Place, signal, wait, enter, leave, start, run, stop, accumulate, home, park or coordinate";

bool is_word(const Token& t, std::string_view keyword) {
  return t.kind == TokenKind::kName && lower(t.text) == keyword;
}

// ---- parser ------------------------------------------------------------------------------------------------------

class Parser {
 public:
  Parser(std::string_view text, std::string file) : text_(text) {
    program_.file = std::move(file);
    // A UTF-8 byte-order mark, which some editors put at the start of a file, is not part of the program (and does
    // not count in line 1's columns).
    if (text_.starts_with("\xEF\xBB\xBF")) text_.remove_prefix(3);
  }

  Program run() {
    std::size_t pos = 0;
    int line = 0;
    while (pos <= text_.size()) {
      const std::size_t nl = text_.find('\n', pos);
      const std::size_t end = nl == std::string_view::npos ? text_.size() : nl;
      ++line;
      line_ = line;
      tokens_ = lex(text_.substr(pos, end - pos));
      if (!tokens_.empty()) parse_line();
      if (nl == std::string_view::npos) break;
      pos = nl + 1;
    }
    if (open_loop_) {
      throw InputError(open_loop_->where, "the loop opened here has no matching 'end' before the end of the file");
    }
    if (mode_ != Mode::kTop) {
      const char* what = block_kind();
      throw InputError(block_where_, fmt::format("the {} block opened here has no matching 'end' before the end "
                                                 "of the file{}",
                                                 what, closed_loop_note()));
    }
    // A program that says nothing for any robot to do would compile to a net that is dead from the start.
    if (program_.declarations.empty() && !program_.steps && program_.sequences.empty()) {
      throw InputError({program_.file, 1, 0}, "the program is empty: it has no statements, only blank lines and "
                                              "comments (docs/task-language.md: declare the robots, then say what "
                                              "they do in a 'steps' table or 'sequence' blocks)");
    }
    resolve();
    // Checked after the names, so that a misused name is reported as such.
    if (!program_.steps && program_.sequences.empty()) {
      throw InputError(program_.declarations.front().where,
                       "the program declares names but says nothing for any robot to do: add a 'steps' table or a "
                       "'sequence' block (docs/task-language.md)");
    }
    return std::move(program_);
  }

 private:
  enum class Mode : std::uint8_t { kTop, kStepsHeader, kSteps, kSequence, kBlock };

  // The name of the open block's kind, for messages.
  const char* block_kind() const {
    return mode_ == Mode::kSequence ? "sequence" : mode_ == Mode::kBlock ? "coordinated" : "steps";
  }

  SourceLocation at(int column) const { return {program_.file, line_, column}; }
  SourceLocation at(const Token& t) const { return at(t.column); }

  [[noreturn]] void fail(const Token& t, std::string problem) const { throw InputError(at(t), std::move(problem)); }

  std::vector<Token> lex(std::string_view s) const {
    std::vector<Token> out;
    std::size_t i = 0;
    while (i < s.size()) {
      const char c = s[i];
      const int column = static_cast<int>(i) + 1;
      if (c == '#') break;
      if (is_blank(c)) {
        ++i;
        continue;
      }
      if (is_name_start(c)) {
        std::size_t j = i;
        while (j < s.size() && is_name_char(s[j])) ++j;
        out.push_back({TokenKind::kName, std::string(s.substr(i, j - i)), column});
        i = j;
      } else if (is_digit(c) || (c == '-' && i + 1 < s.size() && is_digit(s[i + 1]))) {
        std::size_t j = i + 1;
        while (j < s.size() && is_name_char(s[j])) ++j;
        const std::string_view word = s.substr(i, j - i);
        if (!std::all_of(word.begin() + 1, word.end(), is_digit)) {
          throw InputError(at(column), fmt::format("'{}' is not a valid name or number: names start with a letter "
                                                   "or '_', numbers have only digits",
                                                   word));
        }
        out.push_back({TokenKind::kNumber, std::string(word), column});
        i = j;
      } else if (c == '=') {
        out.push_back({TokenKind::kEquals, "=", column});
        ++i;
      } else if (c == '|') {
        out.push_back({TokenKind::kBar, "|", column});
        ++i;
      } else {
        throw InputError(at(column), fmt::format("unexpected {}", describe_char(c)));
      }
    }
    return out;
  }

  void parse_line() {
    switch (mode_) {
      case Mode::kTop:
        parse_top();
        return;
      case Mode::kStepsHeader:
      case Mode::kSteps:
      case Mode::kSequence:
      case Mode::kBlock:
        parse_block_line();
        return;
    }
  }

  // A name token used as a new name in a declaration.
  const Token& expect_new_name(std::size_t i, const char* what) const {
    CW_CHECK(i < tokens_.size(), "token {} of {}", i, tokens_.size());
    const Token& t = tokens_[i];
    if (t.kind != TokenKind::kName) fail(t, fmt::format("expected a {} name, found {}", what, quoted(t)));
    if (is_keyword(t.text)) fail(t, fmt::format("'{}' is a keyword and cannot be used as a name", t.text));
    return t;
  }

  void declare(NameKind kind, const Token& name, std::uint32_t initial) {
    if (const Declaration* d = find_declaration(program_, name.text)) {
      fail(name,
           fmt::format("'{}' is already declared as a {} on line {}", name.text, to_string(d->kind), d->where.line));
    }
    program_.declarations.push_back({kind, name.text, initial, at(name), {}, {}});
  }

  void parse_top() {
    const Token& first = tokens_.front();
    if (first.kind != TokenKind::kName) {
      fail(first, fmt::format("expected a statement (robot, workpiece, location, semaphore, region, machine, "
                              "conveyor, sensor, steps, sequence or coordinated), found {}",
                              quoted(first)));
    }
    const std::string word = lower(first.text);
    if (word == "workpiece" && tokens_.size() > 1 &&
        std::any_of(tokens_.begin() + 1, tokens_.end(), [](const Token& t) { return is_word(t, "from"); })) {
      parse_class(first);
    } else if (word == "robot" || word == "workpiece" || word == "location" || word == "region") {
      const NameKind kind = word == "robot"       ? NameKind::kRobot
                            : word == "workpiece" ? NameKind::kWorkpiece
                            : word == "location"  ? NameKind::kLocation
                                                  : NameKind::kRegion;
      if (tokens_.size() == 1) fail(first, fmt::format("'{}' needs at least one name", first.text));
      for (std::size_t i = 1; i < tokens_.size(); ++i) declare(kind, expect_new_name(i, to_string(kind)), 0);
    } else if (word == "machine" || word == "conveyor") {
      // Device declarations (recognised at the start of a line only: these words are not reserved).
      const NameKind kind = word == "machine" ? NameKind::kMachine : NameKind::kConveyor;
      if (tokens_.size() == 1) fail(first, fmt::format("'{}' needs at least one name", first.text));
      for (std::size_t i = 1; i < tokens_.size(); ++i) declare(kind, expect_new_name(i, to_string(kind)), 0);
    } else if (word == "sensor") {
      parse_sensor(first);
    } else if (word == "coordinated") {
      parse_block_header(first);
    } else if (word == "semaphore") {
      if (tokens_.size() == 1) fail(first, fmt::format("'{}' needs at least one name", first.text));
      std::size_t i = 1;
      while (i < tokens_.size()) {
        const Token& name = expect_new_name(i, "semaphore");
        std::uint32_t initial = 0;
        ++i;
        if (i < tokens_.size() && tokens_[i].kind == TokenKind::kEquals) {
          const Token& eq = tokens_[i];
          if (i + 1 >= tokens_.size() || tokens_[i + 1].kind != TokenKind::kNumber) {
            fail(i + 1 < tokens_.size() ? tokens_[i + 1] : eq,
                 fmt::format("'=' after semaphore '{}' needs its initial count (a number 0 or more)", name.text));
          }
          initial = parse_count(tokens_[i + 1], name.text);
          i += 2;
        }
        declare(NameKind::kSemaphore, name, initial);
      }
    } else if (word == "steps") {
      if (program_.steps) {
        fail(first,
             fmt::format("only one steps block is allowed; the first is on line {}", program_.steps->where.line));
      }
      expect_alone(first);
      program_.steps.emplace();
      program_.steps->where = at(first);
      block_where_ = at(first);
      last_loop_end_ = 0;
      mode_ = Mode::kStepsHeader;
    } else if (word == "sequence") {
      if (tokens_.size() == 1) fail(first, "'sequence' needs the name of the robot it programs");
      const Token& robot = tokens_[1];
      if (robot.kind != TokenKind::kName) fail(robot, fmt::format("expected a robot name, found {}", quoted(robot)));
      if (tokens_.size() > 2) {
        fail(tokens_[2], fmt::format("unexpected {} after 'sequence {}': a sequence programs one robot",
                                     quoted(tokens_[2]), robot.text));
      }
      program_.sequences.push_back({robot.text, at(robot), {}, {}});
      block_where_ = at(first);
      last_loop_end_ = 0;
      mode_ = Mode::kSequence;
    } else if (word == "end") {
      fail(first, "'end' without an open steps or sequence block");
    } else if (find_any_command(word) != nullptr || word == "repeat") {
      fail(first, fmt::format("'{}' must stand inside a steps or sequence block", first.text));
    } else if (word == "via") {
      fail(first, "'via' stands in the body of a coordinated block ('coordinated NAME master ROBOT follower ROBOT')");
    } else if (word == "from") {
      fail(first, "'from' stands in a workpiece class declaration: 'workpiece NAME from LOCATION'");
    } else {
      fail(first, fmt::format("unknown statement '{}' (expected robot, workpiece, location, semaphore, region, "
                              "machine, conveyor, sensor, steps, sequence or coordinated)",
                              first.text));
    }
  }

  // With a loop in the open block, the block's own 'end' may be the one that closed the loop: say so.
  std::string closed_loop_note() const {
    if (last_loop_end_ == 0) return {};
    return fmt::format(" (the 'end' on line {} closed the loop opened on line {})", last_loop_end_, last_loop_line_);
  }

  // `workpiece NAME from LOCATION`: one class per statement. The location is resolved after the whole file.
  void parse_class(const Token& first) {
    const auto from = std::find_if(tokens_.begin() + 1, tokens_.end(), [](const Token& t) { return is_word(t, "from"); });
    const auto from_index = static_cast<std::size_t>(from - tokens_.begin());
    if (from_index == 1) {
      fail(*from, fmt::format("'{} from' needs the class name before 'from': 'workpiece NAME from LOCATION'",
                              first.text));
    }
    if (from_index > 2) {
      fail(tokens_[2], fmt::format("a workpiece class is declared alone ('workpiece NAME from LOCATION'), but {} "
                                   "names stand before 'from'; declare each class on a line of its own",
                                   from_index - 1));
    }
    const Token& name = expect_new_name(1, "workpiece");
    if (from_index + 1 >= tokens_.size()) {
      fail(*from, fmt::format("'from' after workpiece class '{}' needs the location its parts arrive at",
                              name.text));
    }
    const Token& location = tokens_[from_index + 1];
    if (location.kind != TokenKind::kName) {
      fail(location, fmt::format("expected a location name after 'from', found {}", quoted(location)));
    }
    if (from_index + 2 < tokens_.size()) {
      fail(tokens_[from_index + 2],
           fmt::format("unexpected {} after 'workpiece {} from {}': a class takes its parts from one location",
                       quoted(tokens_[from_index + 2]), name.text, location.text));
    }
    declare(NameKind::kWorkpiece, name, 0);
    program_.declarations.back().from = location.text;
    program_.declarations.back().from_where = at(location);
  }

  // `sensor NAME on CONVEYOR`: one photo-eye per statement, with the conveyor whose parts it sees (resolved after
  // the whole file).
  void parse_sensor(const Token& first) {
    if (tokens_.size() == 1) fail(first, "'sensor' needs a name and its conveyor: 'sensor NAME on CONVEYOR'");
    const Token& name = expect_new_name(1, "sensor");
    if (tokens_.size() < 3 || !is_word(tokens_[2], "on")) {
      fail(tokens_.size() < 3 ? name : tokens_[2],
           fmt::format("sensor '{}' needs the conveyor whose parts it sees: 'sensor {} on CONVEYOR'{}", name.text,
                       name.text, tokens_.size() < 3 ? std::string() : fmt::format(", found {}", quoted(tokens_[2]))));
    }
    if (tokens_.size() < 4) fail(tokens_[2], fmt::format("'on' after sensor '{}' needs a conveyor name", name.text));
    const Token& conveyor = tokens_[3];
    if (conveyor.kind != TokenKind::kName) {
      fail(conveyor, fmt::format("expected a conveyor name after 'on', found {}", quoted(conveyor)));
    }
    if (tokens_.size() > 4) {
      fail(tokens_[4], fmt::format("unexpected {} after 'sensor {} on {}': declare each sensor on a line of its own",
                                   quoted(tokens_[4]), name.text, conveyor.text));
    }
    declare(NameKind::kSensor, name, 0);
    program_.declarations.back().from = conveyor.text;
    program_.declarations.back().from_where = at(conveyor);
  }

  // `repeat N` inside a block: opens a loop over the lines (table) or commands (sequence) that follow.
  void open_loop(const Token& first, std::size_t next) {
    if (open_loop_) {
      fail(first, fmt::format("loops do not nest: the loop opened on line {} is still open (close it with 'end' "
                              "first)",
                              open_loop_->where.line));
    }
    if (tokens_.size() == 1) fail(first, "'repeat' needs the number of iterations (a number 1 or more)");
    const Token& n = tokens_[1];
    if (n.kind != TokenKind::kNumber) {
      fail(n, fmt::format("expected the number of iterations after 'repeat', found {}", quoted(n)));
    }
    if (n.text.front() == '-' || std::all_of(n.text.begin(), n.text.end(), [](char c) { return c == '0'; })) {
      fail(n, fmt::format("the number of iterations must be 1 or more, not {}", n.text));
    }
    const std::optional<std::uint32_t> value = to_u32(n.text);
    if (!value) {
      fail(n, fmt::format("the number of iterations is too large: {} (at most {})", n.text,
                          std::numeric_limits<std::uint32_t>::max()));
    }
    LoopBlock loop;
    if (tokens_.size() > 2 && is_word(tokens_[2], "with")) {
      // `repeat N with R...`: the loop of cooperating sequences, one decision for all of them.
      if (mode_ != Mode::kSequence) {
        fail(tokens_[2], fmt::format("'with' names the sequences a loop runs together with; a loop of the steps "
                                     "table already runs with every robot of the table (write 'repeat {}')",
                                     n.text));
      }
      if (tokens_.size() == 3) {
        fail(tokens_[2], fmt::format("'repeat {} with' needs the robots whose sequences loop together with this one",
                                     n.text));
      }
      for (std::size_t i = 3; i < tokens_.size(); ++i) {
        const Token& t = tokens_[i];
        if (t.kind != TokenKind::kName) fail(t, fmt::format("expected a robot name after 'with', found {}", quoted(t)));
        if (std::find(loop.partners.begin(), loop.partners.end(), t.text) != loop.partners.end()) {
          fail(t, fmt::format("robot '{}' is named twice after 'with'", t.text));
        }
        loop.partners.push_back(t.text);
        loop.partner_where.push_back(at(t));
      }
    } else if (tokens_.size() > 2) {
      fail(tokens_[2], fmt::format("unexpected {} after 'repeat {}': the line that opens a loop holds nothing else "
                                   "(or 'with' and the robots whose sequences loop together with this one)",
                                   quoted(tokens_[2]), n.text));
    }
    loop.where = at(first);
    loop.count = *value;
    loop.begin = next;
    loop.end = next;
    open_loop_ = loop;
  }

  // The `end` of the open loop; `next` is the index the next line or command would get.
  void close_loop(const Token& end, std::size_t next) {
    LoopBlock loop = *open_loop_;
    if (next == loop.begin) {
      fail(end, fmt::format("the loop opened on line {} has an empty body: put the {} it repeats between "
                            "'repeat {}' and 'end'",
                            loop.where.line, mode_ == Mode::kSequence ? "commands" : "step lines", loop.count));
    }
    loop.end = next;
    if (mode_ == Mode::kSequence) {
      program_.sequences.back().loops.push_back(loop);
    } else {
      program_.steps->loops.push_back(loop);
    }
    last_loop_end_ = line_;
    last_loop_line_ = loop.where.line;
    open_loop_.reset();
  }

  std::uint32_t parse_count(const Token& t, const std::string& semaphore) const {
    if (t.text.front() == '-') {
      fail(t, fmt::format("the initial count of semaphore '{}' must be 0 or more, not {}", semaphore, t.text));
    }
    const std::optional<std::uint32_t> value = to_u32(t.text);
    if (!value) {
      fail(t, fmt::format("the initial count of semaphore '{}' is too large: {} (at most {})", semaphore, t.text,
                          std::numeric_limits<std::uint32_t>::max()));
    }
    return *value;
  }

  // The value of a number token without sign, or nullopt if it does not fit 32 bits.
  static std::optional<std::uint32_t> to_u32(const std::string& digits) {
    std::uint64_t value = 0;
    for (char c : digits) {
      value = value * 10 + static_cast<std::uint64_t>(c - '0');
      if (value > std::numeric_limits<std::uint32_t>::max()) return std::nullopt;
    }
    return static_cast<std::uint32_t>(value);
  }

  void expect_alone(const Token& first) const {
    if (tokens_.size() > 1) {
      fail(tokens_[1], fmt::format("unexpected {} after '{}'", quoted(tokens_[1]), first.text));
    }
  }

  void parse_block_line() {
    const Token& first = tokens_.front();
    const char* block = block_kind();
    const std::size_t next = mode_ == Mode::kSequence ? program_.sequences.back().commands.size()
                             : mode_ == Mode::kBlock  ? program_.blocks.back().body.size()
                                                      : program_.steps->lines.size();
    if (first.kind == TokenKind::kName && is_statement(first.text, "end")) {
      expect_alone(first);
      if (mode_ == Mode::kStepsHeader) fail(first, "the steps block has no header line naming its robot columns");
      if (mode_ == Mode::kBlock) {
        close_block(first);
        return;
      }
      if (open_loop_) {
        close_loop(first, next);
        return;
      }
      mode_ = Mode::kTop;
      return;
    }
    if (is_top_level_statement(first)) {
      if (open_loop_) {
        throw InputError(open_loop_->where,
                         fmt::format("the loop opened here has no matching 'end' before '{}' on line {}", first.text,
                                     line_));
      }
      fail(first, fmt::format("'{}' inside the {} block opened on line {}: is its 'end' missing?{}", first.text,
                              block, block_where_.line, closed_loop_note()));
    }
    if (is_word(first, "repeat")) {
      if (mode_ == Mode::kBlock) {
        fail(first, fmt::format("a coordinated block has no loops (the block opened on line {}): put "
                                "'coordinate {}' inside a loop of the robots' programs instead",
                                block_where_.line, program_.blocks.back().name));
      }
      if (mode_ == Mode::kStepsHeader) {
        fail(first, "the first line of a steps block is its header naming the robot columns (like 'r1 | r2'), found "
                    "'repeat': a loop opens after the header");
      }
      open_loop(first, next);
      return;
    }
    switch (mode_) {
      case Mode::kStepsHeader:
        parse_header();
        mode_ = Mode::kSteps;
        return;
      case Mode::kSteps:
        parse_step_line();
        return;
      case Mode::kSequence:
        parse_sequence_line();
        return;
      case Mode::kBlock:
        parse_block_body_line();
        return;
      case Mode::kTop:
        return;
    }
  }

  // `coordinated NAME master ROBOT follower ROBOT`: opens a coordinated block. The robots are resolved after the whole
  // file.
  void parse_block_header(const Token& first) {
    constexpr const char* kShape = "'coordinated NAME master ROBOT follower ROBOT'";
    if (tokens_.size() == 1) fail(first, fmt::format("'coordinated' needs a name and its two robots: {}", kShape));
    const Token& name = expect_new_name(1, "coordinated block");
    const char* words[2] = {"master", "follower"};
    for (std::size_t k = 0; k < 2; ++k) {
      const std::size_t w = 2 + 2 * k;
      if (tokens_.size() <= w || !is_word(tokens_[w], words[k])) {
        fail(tokens_.size() <= w ? tokens_.back() : tokens_[w],
             fmt::format("coordinated block '{}' needs its {} robot: {}{}", name.text, words[k], kShape,
                         tokens_.size() <= w ? std::string() : fmt::format(", found {}", quoted(tokens_[w]))));
      }
      if (tokens_.size() <= w + 1 || tokens_[w + 1].kind != TokenKind::kName) {
        fail(tokens_.size() <= w + 1 ? tokens_[w] : tokens_[w + 1],
             fmt::format("'{}' in coordinated block '{}' needs a robot name", words[k], name.text));
      }
    }
    if (tokens_.size() > 6) {
      fail(tokens_[6], fmt::format("unexpected {} after the follower robot: {}", quoted(tokens_[6]), kShape));
    }
    declare(NameKind::kBlock, name, 0);
    CoordinatedBlock b;
    b.name = name.text;
    b.where = at(name);
    b.master = tokens_[3].text;
    b.master_where = at(tokens_[3]);
    b.follower = tokens_[5].text;
    b.follower_where = at(tokens_[5]);
    program_.blocks.push_back(std::move(b));
    block_where_ = at(first);
    last_loop_end_ = 0;
    mode_ = Mode::kBlock;
  }

  // One command of a coordinated block's body: Pick W, via LOCATION or Place X.
  void parse_block_body_line() {
    CoordinatedBlock& b = program_.blocks.back();
    for (const Token& t : tokens_) {
      if (t.kind == TokenKind::kBar) {
        fail(t, "'|' separates the columns of the steps table; a coordinated block has one command per line");
      }
    }
    const Token& word = tokens_.front();
    Command cmd;
    if (is_word(word, "via")) {
      if (tokens_.size() < 2) fail(word, "via needs an argument: a location name");
      const Token& arg = tokens_[1];
      if (arg.kind != TokenKind::kName) fail(arg, fmt::format("via needs a location name, found {}", quoted(arg)));
      if (tokens_.size() > 2) {
        fail(tokens_[2], fmt::format("extra argument {} after 'via {}': via takes one location", quoted(tokens_[2]),
                                     arg.text));
      }
      cmd.kind = CommandKind::kVia;
      cmd.where = at(word);
      cmd.argument = arg.text;
      cmd.argument_where = at(arg);
    } else {
      cmd = parse_command(0, tokens_.size(), b.master, "coordinated block");
    }
    const bool has_pick = !b.body.empty();
    const bool placed = has_pick && b.body.back().kind == CommandKind::kPlace;
    const std::string shape = fmt::format("the body of a coordinated block is 'Pick WORKPIECE', any number of 'via "
                                          "LOCATION', then 'Place X' (block '{}', line {})",
                                          b.name, b.where.line);
    switch (cmd.kind) {
      case CommandKind::kPick:
        if (has_pick) fail(word, fmt::format("a second Pick: {}", shape));
        if (!cmd.machine.empty()) {
          fail(tokens_[2], fmt::format("'Pick ... from MACHINE' is not allowed in a coordinated block: {}", shape));
        }
        break;
      case CommandKind::kVia:
      case CommandKind::kPlace:
        if (!has_pick) fail(word, fmt::format("{} before the block's Pick: {}", to_string(cmd.kind), shape));
        if (placed) fail(word, fmt::format("{} after the block's Place: {}", to_string(cmd.kind), shape));
        break;
      default:
        fail(word, fmt::format("'{}' is not allowed in a coordinated block: {}", to_string(cmd), shape));
    }
    b.body.push_back(std::move(cmd));
  }

  // The `end` of a coordinated block: its body must be complete.
  void close_block(const Token& end) {
    CoordinatedBlock& b = program_.blocks.back();
    if (b.body.empty() || b.body.back().kind != CommandKind::kPlace) {
      fail(end, fmt::format("coordinated block '{}' (line {}) ends {}: its body is 'Pick WORKPIECE', any number of "
                            "'via LOCATION', then 'Place X'",
                            b.name, b.where.line, b.body.empty() ? "with an empty body" : "without a Place"));
    }
    b.end_where = at(end);
    mode_ = Mode::kTop;
  }

  // Splits the line's tokens at '|' into [begin, end) index ranges, one per cell.
  std::vector<std::pair<std::size_t, std::size_t>> cells() const {
    std::vector<std::pair<std::size_t, std::size_t>> out;
    std::size_t begin = 0;
    for (std::size_t i = 0; i < tokens_.size(); ++i) {
      if (tokens_[i].kind == TokenKind::kBar) {
        out.emplace_back(begin, i);
        begin = i + 1;
      }
    }
    out.emplace_back(begin, tokens_.size());
    return out;
  }

  void parse_header() {
    StepTable& table = *program_.steps;
    const auto columns = cells();
    for (std::size_t c = 0; c < columns.size(); ++c) {
      const auto [b, e] = columns[c];
      if (b == e) {
        // Point at the bar that closes (or, for the last column, opens) the empty cell.
        const Token& bar = b < tokens_.size() ? tokens_[b] : tokens_[b - 1];
        fail(bar, fmt::format("column {} of the steps header is empty: the header names one robot per column", c + 1));
      }
      const Token& name = tokens_[b];
      if (name.kind != TokenKind::kName) fail(name, fmt::format("expected a robot name, found {}", quoted(name)));
      if (find_command(name.text) != nullptr) {
        fail(name, fmt::format("the first line of a steps block is its header naming the robot columns (like "
                               "'r1 | r2'), found the command '{}'",
                               name.text));
      }
      if (is_keyword(name.text)) fail(name, fmt::format("'{}' is a keyword and cannot be used as a name", name.text));
      if (e - b > 1) {
        fail(tokens_[b + 1], fmt::format("unexpected {} after robot '{}': separate the header's robot columns "
                                         "with '|'",
                                         quoted(tokens_[b + 1]), name.text));
      }
      const auto dup = std::find(table.robots.begin(), table.robots.end(), name.text);
      if (dup != table.robots.end()) {
        const auto first = static_cast<std::size_t>(dup - table.robots.begin());
        fail(name, fmt::format("robot '{}' is named twice in the steps header (columns {} and {}): it would get "
                               "two commands on one line",
                               name.text, first + 1, c + 1));
      }
      table.robots.push_back(name.text);
      table.robot_where.push_back(at(name));
    }
  }

  void parse_step_line() {
    StepTable& table = *program_.steps;
    const auto columns = cells();
    if (columns.size() > table.robots.size()) {
      const Token& bar = tokens_[columns[table.robots.size()].first - 1];
      fail(bar, fmt::format("this line has {} cells but the steps header (line {}) names {} robot{}", columns.size(),
                            table.robot_where.front().line, table.robots.size(), table.robots.size() == 1 ? "" : "s"));
    }
    StepLine step;
    step.step = static_cast<int>(table.lines.size()) + 1;
    step.where = at(tokens_.front());
    step.cells.resize(table.robots.size());
    for (std::size_t c = 0; c < columns.size(); ++c) {
      const auto [b, e] = columns[c];
      if (b != e) step.cells[c] = parse_command(b, e, table.robots[c], "steps table");
    }
    table.lines.push_back(std::move(step));
  }

  void parse_sequence_line() {
    Sequence& seq = program_.sequences.back();
    for (const Token& t : tokens_) {
      if (t.kind == TokenKind::kBar) {
        fail(t, "'|' separates the columns of the steps table; a sequence has one command per line");
      }
    }
    seq.commands.push_back(parse_command(0, tokens_.size(), seq.robot, "sequence"));
  }

  // The command in tokens [b, e) for `robot`.
  Command parse_command(std::size_t b, std::size_t e, const std::string& robot, const char* block) const {
    const Token& word = tokens_[b];
    if (word.kind != TokenKind::kName) {
      fail(word, fmt::format("expected a command ({}), found {}", kCommandList, quoted(word)));
    }
    const CommandSpec* spec = find_any_command(word.text);
    if (is_word(word, "repeat")) {
      fail(word, "'repeat' opens a loop on a line of its own ('repeat N'), not in a table cell");
    }
    if (spec == nullptr) fail(word, fmt::format("unknown command '{}' (expected {})", word.text, kCommandList));
    Command cmd;
    cmd.kind = spec->kind;
    cmd.where = at(word);
    const bool no_argument = spec->needs[0] == '\0';
    // Arguments end at the cell's end; `Pick W from M` has three.
    std::size_t args = 1;
    if (spec->kind == CommandKind::kPick && e - b >= 3 && is_word(tokens_[b + 2], "from")) args = 3;
    if (no_argument) args = 0;
    if (!no_argument && e - b < 2) {
      fail(word, fmt::format("{} needs an argument: {} name", to_string(spec->kind), spec->needs));
    }
    if (!no_argument) {
      const Token& arg = tokens_[b + 1];
      if (arg.kind != TokenKind::kName) {
        fail(arg, fmt::format("{} needs {} name, found {}", to_string(spec->kind), spec->needs, quoted(arg)));
      }
      cmd.argument = arg.text;
      cmd.argument_where = at(arg);
    }
    if (args == 3) {
      if (e - b < 4) fail(tokens_[b + 2], fmt::format("'from' after 'Pick {}' needs a machine name", cmd.argument));
      const Token& m = tokens_[b + 3];
      if (m.kind != TokenKind::kName) {
        fail(m, fmt::format("expected a machine name after 'from', found {}", quoted(m)));
      }
      cmd.machine = m.text;
      cmd.machine_where = at(m);
    }
    if (e - b > args + 1) {
      const Token& extra = tokens_[b + args + 1];
      if (extra.kind == TokenKind::kName && find_any_command(extra.text) != nullptr) {
        fail(extra, fmt::format("two commands for robot '{}' on line {} ('{}' and '{}'): the {} allows one "
                                "command per robot on a line",
                                robot, line_, to_string(cmd), extra.text, block));
      }
      if (no_argument) {
        fail(extra, fmt::format("unexpected {} after '{}': {} takes no argument", quoted(extra), word.text,
                                to_string(spec->kind)));
      }
      fail(extra, fmt::format("extra argument {} after '{}': {} takes one argument{}", quoted(extra),
                              to_string(cmd), to_string(spec->kind),
                              spec->kind == CommandKind::kPick ? " (or 'Pick W from MACHINE')" : ""));
    }
    return cmd;
  }

  // ---- name resolution (after the whole file is read) ----

  [[noreturn]] static void fail_at(const SourceLocation& where, std::string problem) {
    throw InputError(where, std::move(problem));
  }

  void expect_robot(const std::string& name, const SourceLocation& where) const {
    const Declaration* d = find_declaration(program_, name);
    if (d == nullptr) fail_at(where, fmt::format("unknown robot '{}'", name));
    if (d->kind != NameKind::kRobot) {
      fail_at(where, fmt::format("expected a robot, but '{}' is a {} (declared on line {})", name, to_string(d->kind),
                                 d->where.line));
    }
  }

  void resolve_command(Command& cmd) const {
    if (cmd.kind == CommandKind::kHome || cmd.kind == CommandKind::kPark) return;
    if (!cmd.machine.empty()) {
      const Declaration* m = find_declaration(program_, cmd.machine);
      if (m == nullptr) fail_at(cmd.machine_where, fmt::format("unknown machine '{}'", cmd.machine));
      if (m->kind != NameKind::kMachine) {
        fail_at(cmd.machine_where, fmt::format("Pick ... from expects a machine, but '{}' is a {} (declared on line "
                                               "{})",
                                               cmd.machine, to_string(m->kind), m->where.line));
      }
    }
    const Declaration* d = find_declaration(program_, cmd.argument);
    const CommandSpec& spec = spec_of(cmd.kind);
    std::vector<NameKind> allowed;
    switch (cmd.kind) {
      case CommandKind::kPick:
        allowed = {NameKind::kWorkpiece};
        break;
      case CommandKind::kPut:
      case CommandKind::kGet:
        allowed = {NameKind::kRobot};
        break;
      case CommandKind::kPlace:
        allowed = {NameKind::kWorkpiece, NameKind::kLocation, NameKind::kMachine};
        break;
      case CommandKind::kSignal:
        allowed = {NameKind::kSemaphore};
        break;
      case CommandKind::kWait:
        allowed = {NameKind::kSemaphore, NameKind::kMachine, NameKind::kSensor};
        break;
      case CommandKind::kStart:
        allowed = {NameKind::kMachine};
        break;
      case CommandKind::kRun:
      case CommandKind::kStop:
      case CommandKind::kAccumulate:
        allowed = {NameKind::kConveyor};
        break;
      case CommandKind::kHome:
      case CommandKind::kPark:
        return;
      case CommandKind::kEnter:
      case CommandKind::kLeave:
        allowed = {NameKind::kRegion};
        break;
      case CommandKind::kCoordinate:
        allowed = {NameKind::kBlock};
        break;
      case CommandKind::kVia:
        allowed = {NameKind::kLocation};
        break;
    }
    if (d == nullptr) {
      // "a workpiece" -> "unknown workpiece 'X'"
      fail_at(cmd.argument_where, fmt::format("unknown {} '{}'", std::string(spec.needs).substr(2), cmd.argument));
    }
    if (std::find(allowed.begin(), allowed.end(), d->kind) == allowed.end()) {
      std::string hint;
      if (d->kind == NameKind::kRegion && (cmd.kind == CommandKind::kSignal || cmd.kind == CommandKind::kWait)) {
        hint = "; use enter/leave for regions";
      } else if (d->kind == NameKind::kSemaphore &&
                 (cmd.kind == CommandKind::kEnter || cmd.kind == CommandKind::kLeave)) {
        hint = "; use signal/wait for semaphores";
      }
      fail_at(cmd.argument_where,
              fmt::format("{} expects {}, but '{}' is a {} (declared on line {}){}", to_string(cmd.kind), spec.needs,
                          cmd.argument, to_string(d->kind), d->where.line, hint));
    }
    cmd.argument_kind = d->kind;
  }

  void resolve_table(StepTable& table) const {
    for (std::size_t c = 0; c < table.robots.size(); ++c) expect_robot(table.robots[c], table.robot_where[c]);
    for (StepLine& line : table.lines) {
      for (std::optional<Command>& cell : line.cells) {
        if (cell) resolve_command(*cell);
      }
    }
  }

  void resolve_sequence(Sequence& seq, std::size_t index) const {
    expect_robot(seq.robot, seq.where);
    if (program_.steps) {
      const StepTable& table = *program_.steps;
      const auto col = std::find(table.robots.begin(), table.robots.end(), seq.robot);
      if (col != table.robots.end()) {
        fail_at(seq.where, fmt::format("robot '{}' has a column in the steps table (line {}); a robot is programmed "
                                       "either in the steps table or in one sequence, not both",
                                       seq.robot, table.where.line));
      }
    }
    for (std::size_t i = 0; i < index; ++i) {
      if (program_.sequences[i].robot == seq.robot) {
        fail_at(seq.where, fmt::format("robot '{}' already has a sequence (line {}); a robot has one sequence at most",
                                       seq.robot, program_.sequences[i].where.line));
      }
    }
    for (Command& cmd : seq.commands) resolve_command(cmd);
  }

  // A coordinated block: two distinct robots; a named workpiece picked; a location or named workpiece placed on.
  void resolve_block(CoordinatedBlock& b) const {
    expect_robot(b.master, b.master_where);
    expect_robot(b.follower, b.follower_where);
    if (b.master == b.follower) {
      fail_at(b.follower_where, fmt::format("coordinated block '{}' needs two robots, but its master and follower are "
                                            "both '{}'",
                                            b.name, b.master));
    }
    for (Command& cmd : b.body) {
      resolve_command(cmd);
      const Declaration* d = find_declaration(program_, cmd.argument);
      if (cmd.kind == CommandKind::kPick && !d->from.empty()) {
        fail_at(cmd.argument_where, fmt::format("coordinated block '{}' carries one named workpiece, but '{}' is a "
                                                "workpiece class (whichever part arrives at {})",
                                                b.name, cmd.argument, d->from));
      }
      if (cmd.kind == CommandKind::kPlace && cmd.argument == b.body.front().argument) {
        fail_at(cmd.argument_where, fmt::format("coordinated block '{}' cannot place {} on itself", b.name,
                                                cmd.argument));
      }
      if (cmd.kind == CommandKind::kPlace && cmd.argument_kind == NameKind::kMachine) {
        fail_at(cmd.argument_where, fmt::format("coordinated block '{}' cannot place into machine '{}': a machine "
                                                "is loaded by one robot",
                                                b.name, cmd.argument));
      }
    }
  }

  // The conveyor a sensor sees the parts of.
  void resolve_sensor(const Declaration& c) const {
    const Declaration* d = find_declaration(program_, c.from);
    if (d == nullptr) fail_at(c.from_where, fmt::format("unknown conveyor '{}'", c.from));
    if (d->kind != NameKind::kConveyor) {
      fail_at(c.from_where, fmt::format("sensor '{}' sees the parts of a conveyor, but '{}' is a {} (declared on "
                                        "line {})",
                                        c.name, c.from, to_string(d->kind), d->where.line));
    }
  }

  // The location a workpiece class takes its parts from.
  void resolve_class(const Declaration& c) const {
    const Declaration* d = find_declaration(program_, c.from);
    if (d == nullptr) fail_at(c.from_where, fmt::format("unknown location '{}'", c.from));
    if (d->kind != NameKind::kLocation) {
      fail_at(c.from_where, fmt::format("workpiece class '{}' takes its parts from a location, but '{}' is a {} "
                                        "(declared on line {})",
                                        c.name, c.from, to_string(d->kind), d->where.line));
    }
  }

  // Resolves the class declarations and the blocks in source order, so the first error in the file is the one
  // reported.
  void resolve() {
    std::vector<std::pair<int, std::function<void()>>> work;  // (source line, what to resolve)
    for (const Declaration& d : program_.declarations) {
      if (d.kind == NameKind::kSensor) {
        work.emplace_back(d.where.line, [this, &d] { resolve_sensor(d); });
      } else if (!d.from.empty()) {
        work.emplace_back(d.where.line, [this, &d] { resolve_class(d); });
      }
    }
    if (program_.steps) work.emplace_back(program_.steps->where.line, [this] { resolve_table(*program_.steps); });
    for (CoordinatedBlock& b : program_.blocks) work.emplace_back(b.where.line, [this, &b] { resolve_block(b); });
    for (std::size_t i = 0; i < program_.sequences.size(); ++i) {
      work.emplace_back(program_.sequences[i].where.line, [this, i] { resolve_sequence(program_.sequences[i], i); });
    }
    std::stable_sort(work.begin(), work.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    for (const auto& [line, resolve_one] : work) resolve_one();
  }

  std::string_view text_;
  Program program_;
  std::optional<LoopBlock> open_loop_;  // the `repeat` whose `end` has not come yet
  int last_loop_end_ = 0;               // line of the `end` that closed the last loop of the open block (0: none)
  int last_loop_line_ = 0;              // line of that loop's `repeat`
  std::vector<Token> tokens_;
  int line_ = 0;
  Mode mode_ = Mode::kTop;
  SourceLocation block_where_;
};

}  // namespace

Program parse_program(std::string_view text, const std::string& file) {
  return Parser(text, file).run();
}

Program load_program(const std::filesystem::path& path) {
  const std::string name = path.string();
  std::string text;
  try {
    text = read_file(path);
  } catch (const InputError& e) {
    throw InputError({name, 0, 0}, fmt::format("cannot read the program: {}", e.problem()));
  }
  return parse_program(text, name);
}

}  // namespace cellwright::task
