// The VAL II monitor's parser (instruction.hpp): words, numbers and punctuation, then one function per command.
#include <fmt/format.h>

#include <charconv>
#include <cmath>
#include <optional>
#include <span>

#include "val2/instruction.hpp"

namespace cellwright::emulate::val2 {

std::string joint_limit_stop(int joint) {
  return fmt::format("*Joint {} limit stop*", joint);
}

namespace {

struct Token {
  enum class Kind : std::uint8_t { word, number, open, close, comma };
  Kind kind;
  std::string text;  // word: upper case, with a leading '#' for a precision point
  double value = 0;  // number
};

bool is_letter(char c) {
  return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z');
}
bool is_digit(char c) {
  return c >= '0' && c <= '9';
}
char upper(char c) {
  return c >= 'a' && c <= 'z' ? static_cast<char>(c - 'a' + 'A') : c;
}

// The length of a number starting at text[i] (sign, digits, point, exponent), 0 if none starts there.
std::size_t number_length(std::string_view text, std::size_t i) {
  std::size_t j = i;
  if (j < text.size() && (text[j] == '+' || text[j] == '-')) ++j;
  std::size_t digits = 0;
  while (j < text.size() && is_digit(text[j])) ++j, ++digits;
  if (j < text.size() && text[j] == '.') {
    ++j;
    while (j < text.size() && is_digit(text[j])) ++j, ++digits;
  }
  if (digits == 0) return 0;
  if (j < text.size() && (text[j] == 'e' || text[j] == 'E')) {
    std::size_t k = j + 1;
    if (k < text.size() && (text[k] == '+' || text[k] == '-')) ++k;
    if (k < text.size() && is_digit(text[k])) {
      while (k < text.size() && is_digit(text[k])) ++k;
      j = k;
    }
  }
  return j - i;
}

// Splits a line into tokens; nullopt when a character starts none.
std::optional<std::vector<Token>> tokenize(std::string_view text) {
  std::vector<Token> tokens;
  std::size_t i = 0;
  while (i < text.size()) {
    const char c = text[i];
    if (c == ' ' || c == '\t') {
      ++i;
    } else if (c == '(' || c == ')' || c == ',') {
      tokens.push_back({c == '(' ? Token::Kind::open : c == ')' ? Token::Kind::close : Token::Kind::comma, {}, 0});
      ++i;
    } else if (is_letter(c) || (c == '#' && i + 1 < text.size() && is_letter(text[i + 1]))) {
      Token t{Token::Kind::word, std::string(1, upper(c)), 0};
      for (++i; i < text.size() && (is_letter(text[i]) || is_digit(text[i]) || text[i] == '.' || text[i] == '_'); ++i) {
        t.text += upper(text[i]);
      }
      tokens.push_back(std::move(t));
    } else if (const std::size_t n = number_length(text, i); n > 0) {
      // from_chars reads no leading '+'; it is locale-independent.
      const std::size_t skip = text[i] == '+' ? 1 : 0;
      Token t{Token::Kind::number, std::string(text.substr(i, n)), 0};
      const auto [end, ec] = std::from_chars(text.data() + i + skip, text.data() + i + n, t.value);
      if (ec != std::errc() || end != text.data() + i + n || !std::isfinite(t.value)) return std::nullopt;
      tokens.push_back(std::move(t));
      i += n;
    } else {
      return std::nullopt;
    }
  }
  return tokens;
}

// The keywords of one level, in VAL II's abbreviation rule: an exact word wins, else a prefix of exactly one.
struct Keyword {
  std::string_view name;
  std::optional<Op> op;  // nullopt: a VAL II word this monitor does not emulate (it still takes part in prefixes)
};

constexpr Keyword kMonitorWords[] = {
    {"DO", std::nullopt},  // handled apart: it introduces an instruction
    {"SPEED", Op::speed},    {"WHERE", Op::where},   {"HERE", std::nullopt},    {"TEACH", std::nullopt},
    {"POINT", std::nullopt}, {"EDIT", std::nullopt}, {"EXECUTE", std::nullopt}, {"ABORT", std::nullopt},
    {"STORE", std::nullopt}, {"LOAD", std::nullopt}, {"LIST", std::nullopt},
};

constexpr Keyword kInstructionWords[] = {
    {"READY", Op::ready},       {"MOVE", Op::move},      {"MOVES", Op::moves},     {"OPENI", Op::open_hand},
    {"CLOSEI", Op::close_hand}, {"SPEED", Op::speed},    {"SIGNAL", Op::signal},   {"WAIT", Op::wait_signal},
    {"MOVET", std::nullopt},    {"APPRO", std::nullopt}, {"DEPART", std::nullopt}, {"DRIVE", std::nullopt},
    {"ALIGN", std::nullopt},    {"OPEN", std::nullopt},  {"CLOSE", std::nullopt},  {"GRASP", std::nullopt},
};

const Keyword* resolve(std::string_view word, std::span<const Keyword> words) {
  const Keyword* found = nullptr;
  int prefixes = 0;
  for (const Keyword& k : words) {
    if (k.name == word) return &k;
    if (k.name.starts_with(word)) {
      found = &k;
      ++prefixes;
    }
  }
  return prefixes == 1 ? found : nullptr;
}

Parsed failure(std::string_view error) {
  Parsed p;
  p.error = std::string(error);
  return p;
}

Parsed success(Instruction instruction) {
  Parsed p;
  p.instruction = std::move(instruction);
  return p;
}

// Reads the arguments of one command: tokens[at...].
class Arguments {
 public:
  Arguments(const std::vector<Token>& tokens, std::size_t at) : tokens_(tokens), at_(at) {}

  bool done() const { return at_ == tokens_.size(); }
  const Token* peek() const { return done() ? nullptr : &tokens_[at_]; }
  bool next_is(Token::Kind kind) const { return !done() && tokens_[at_].kind == kind; }
  void skip() { ++at_; }

  // `(n, n, ...)`: the numbers, or the error line. A word where a number stands is an invalid argument.
  std::optional<std::string_view> list(std::vector<double>* values) {
    if (!next_is(Token::Kind::open)) return kSyntaxError;
    skip();
    for (;;) {
      if (next_is(Token::Kind::word)) return kInvalidArgument;
      if (!next_is(Token::Kind::number)) return kSyntaxError;
      values->push_back(tokens_[at_].value);
      skip();
      if (next_is(Token::Kind::close)) break;
      if (!next_is(Token::Kind::comma)) return kSyntaxError;
      skip();
    }
    skip();
    return std::nullopt;
  }

 private:
  const std::vector<Token>& tokens_;
  std::size_t at_;
};

bool whole(double v) {
  return v == std::floor(v);
}

// MOVE / MOVES: a location, and nothing after it.
Parsed parse_motion(Op op, Arguments args) {
  const Token* t = args.peek();
  if (t == nullptr || t->kind != Token::Kind::word) return failure(t == nullptr ? kInvalidArgument : kSyntaxError);
  Instruction in;
  in.op = op;
  if (t->text == "TRANS") {
    in.location.kind = Location::Kind::trans;
  } else if (t->text == "#PPOINT" && op == Op::move) {
    in.location.kind = Location::Kind::precision_point;
  } else {
    return failure(kInvalidArgument);  // a named location, or #PPOINT for a straight line
  }
  args.skip();
  std::vector<double> values;
  if (const auto error = args.list(&values)) return failure(*error);
  if (values.size() != in.location.values.size()) return failure(kInvalidArgument);
  if (!args.done()) return failure(kSyntaxError);
  std::copy(values.begin(), values.end(), in.location.values.begin());
  return success(std::move(in));
}

// SPEED n.
Parsed parse_speed(Arguments args) {
  const Token* t = args.peek();
  if (t == nullptr || t->kind != Token::Kind::number) return failure(kInvalidArgument);
  args.skip();
  if (!args.done()) return failure(kInvalidArgument);
  if (!(t->value >= 1 && t->value <= 100)) return failure(kIllegalValue);
  Instruction in;
  in.op = Op::speed;
  in.speed = t->value;
  return success(std::move(in));
}

// SIGNAL n, n, ...
Parsed parse_signal(Arguments args) {
  Instruction in;
  in.op = Op::signal;
  for (;;) {
    const Token* t = args.peek();
    if (t == nullptr || t->kind == Token::Kind::word) return failure(kInvalidArgument);
    if (t->kind != Token::Kind::number) return failure(kSyntaxError);
    const double v = t->value;
    if (!whole(v) || std::abs(v) < 1 || std::abs(v) > 32) return failure(kIllegalValue);
    in.signals.push_back(static_cast<int>(v));
    args.skip();
    if (args.done()) break;
    if (!args.next_is(Token::Kind::comma)) return failure(kSyntaxError);
    args.skip();
  }
  return success(std::move(in));
}

// WAIT SIG(n).
Parsed parse_wait(Arguments args) {
  const Token* t = args.peek();
  if (t == nullptr || t->kind != Token::Kind::word || t->text != "SIG") return failure(kInvalidArgument);
  args.skip();
  std::vector<double> values;
  if (const auto error = args.list(&values)) return failure(*error);
  if (values.size() != 1) return failure(kInvalidArgument);
  if (!args.done()) return failure(kSyntaxError);
  const double v = values[0];
  if (!whole(v) || std::abs(v) < 1001 || std::abs(v) > 1032) return failure(kIllegalValue);
  Instruction in;
  in.op = Op::wait_signal;
  in.signals.push_back(static_cast<int>(v));
  return success(std::move(in));
}

// An instruction without arguments.
Parsed parse_bare(Op op, const Arguments& args) {
  if (!args.done()) return failure(kInvalidArgument);
  Instruction in;
  in.op = op;
  return success(std::move(in));
}

// The instruction whose word is tokens[at].
Parsed parse_instruction_at(const std::vector<Token>& tokens, std::size_t at) {
  if (at == tokens.size()) return failure(kInvalidArgument);  // DO alone
  if (tokens[at].kind != Token::Kind::word) return failure(kSyntaxError);
  const Keyword* k = resolve(tokens[at].text, kInstructionWords);
  if (k == nullptr || !k->op) return failure(kUnknownInstruction);
  const Arguments args(tokens, at + 1);
  switch (*k->op) {
    case Op::move:
    case Op::moves:
      return parse_motion(*k->op, args);
    case Op::speed:
      return parse_speed(args);
    case Op::signal:
      return parse_signal(args);
    case Op::wait_signal:
      return parse_wait(args);
    default:
      return parse_bare(*k->op, args);
  }
}

}  // namespace

Parsed parse_instruction(std::string_view text) {
  const auto tokens = tokenize(text);
  if (!tokens) return failure(kSyntaxError);
  return parse_instruction_at(*tokens, 0);
}

Parsed parse_monitor_line(std::string_view line) {
  const auto tokens = tokenize(line);
  if (!tokens) return failure(kSyntaxError);
  if (tokens->empty()) return success(Instruction{});
  if ((*tokens)[0].kind != Token::Kind::word) return failure(kSyntaxError);
  const Keyword* k = resolve((*tokens)[0].text, kMonitorWords);
  if (k == nullptr) return failure(kUnknownInstruction);
  if (k->name == "DO") return parse_instruction_at(*tokens, 1);
  if (!k->op) return failure(kUnknownInstruction);
  if (*k->op == Op::speed) return parse_speed(Arguments(*tokens, 1));
  return parse_bare(*k->op, Arguments(*tokens, 1));
}

}  // namespace cellwright::emulate::val2
