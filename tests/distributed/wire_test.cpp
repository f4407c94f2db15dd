// The runtime's messages on the wire (distributed/wire.hpp): what goes in comes out, and bytes that are not a message
// are refused with a reason, never a crash.
#include "cellwright/distributed/wire.hpp"

#include <gtest/gtest.h>

#include <random>

#include "cellwright/task/compile.hpp"

namespace cellwright::distributed {
namespace {

task::CompiledProgram exchange() {
  return task::compile_file(std::string(CW_SOURCE_DIR) + "/scenes/exchange.task");
}

// Robot `robot`'s primitive `index` of `program` as task control sends it.
runtime::MotionCommand command_of(const task::CompiledProgram& program, std::size_t robot, std::size_t index) {
  runtime::MotionCommand command;
  command.robot = robot;
  command.index = index;
  command.primitive = program.programs[robot].primitives[index];
  return command;
}

TEST(Wire, EveryCommandOfAProgramComesBackAsItWasSent) {
  auto program = exchange();
  for (std::size_t r = 0; r < program.programs.size(); ++r) {
    const auto& primitives = program.programs[r].primitives;
    for (std::size_t i = 0; i < primitives.size(); ++i) {
      runtime::MotionCommand sent;
      sent.robot = r;
      sent.index = i;
      sent.primitive = primitives[i];
      sent.transition = static_cast<petri::TransitionId>(7 * i + r);
      sent.sent = std::chrono::microseconds(1234567 + i);
      runtime::MotionCommand got = decode_command(encode_command(sent, 1), program, r);
      EXPECT_EQ(got.robot, r);
      EXPECT_EQ(got.index, i);
      EXPECT_EQ(got.transition, sent.transition);
      EXPECT_EQ(got.sent, sent.sent);
      EXPECT_EQ(task::to_string(got.primitive), task::to_string(primitives[i]));
      EXPECT_EQ(got.primitive.where.line, primitives[i].where.line);
    }
  }
}

TEST(Wire, SeededRandomStatusesComeBackAsTheyWereSent) {
  std::mt19937 random(28);
  for (int n = 0; n < 200; ++n) {
    runtime::RobotStatus sent;
    sent.robot = random() % 5;
    sent.index = random() % 4 == 0 ? runtime::RobotStatus::kNoCommand : random() % 1000;
    sent.outcome = random() % 2 ? runtime::CommandOutcome::kDone : runtime::CommandOutcome::kFailed;
    sent.stop_cell = random() % 2 == 0;
    sent.reason.assign(random() % 300, static_cast<char>('a' + random() % 26));
    sent.time = std::chrono::nanoseconds(random());
    runtime::RobotStatus got = decode_status(encode_status(sent, {1, 1}), sent.robot);
    EXPECT_EQ(got.index, sent.index);
    EXPECT_EQ(got.outcome, sent.outcome);
    EXPECT_EQ(got.stop_cell, sent.stop_cell);
    EXPECT_EQ(got.reason, sent.reason);
    EXPECT_EQ(got.time, sent.time);
  }
}

TEST(Wire, TheLayoutIsPlainLittleEndianCdrWithItsHeader) {
  runtime::RobotStatus status;
  status.robot = 2;
  status.index = 3;
  status.outcome = runtime::CommandOutcome::kFailed;
  status.reason = "ab";
  status.time = std::chrono::nanoseconds(5);
  std::vector<char> b = encode_status(status, {0x0102030405060708u, 9});
  // header CDR_LE; robot u32 @0; pad; index i64 @8; outcome u8 @16; stop_cell @17; pad; reason u32 length 3 @20,
  // "ab\0" @24; pad to 8; time i64 @32; session u64 @40; sequence u64 @48: offsets from the end of the 4-byte header
  // (XCDR1 aligns from there).
  ASSERT_EQ(b.size(), 4u + 56u);
  EXPECT_EQ(b[0], 0);
  EXPECT_EQ(b[1], 1);
  EXPECT_EQ(b[4 + 0], 2);
  EXPECT_EQ(b[4 + 8], 3);
  EXPECT_EQ(b[4 + 16], 1);
  EXPECT_EQ(b[4 + 20], 3);
  EXPECT_EQ(std::string(&b[4 + 24], 2), "ab");
  EXPECT_EQ(b[4 + 32], 5);
  EXPECT_EQ(b[4 + 40], 8);  // little-endian: the low byte first
  EXPECT_EQ(b[4 + 47], 1);
  EXPECT_EQ(b[4 + 48], 9);
  EXPECT_LE(b.size(), max_status_size());
  EXPECT_EQ(max_status_size(), 4u + 24u + kReasonBound + 8u + 16u);  // 1048 is a multiple of 8: no pad

  // A command: robot @0, index @4, transition @8, pad, sent_ns @16, primitive length @24, text @28, the sequence at the
  // next multiple of 8 after the text's NUL.
  runtime::MotionCommand command;
  command.robot = 1;
  command.index = 4;
  command.transition = 6;
  command.sent = std::chrono::nanoseconds(7);
  command.primitive.kind = task::PrimitiveKind::kOpen;
  const std::string text = task::to_string(command.primitive);
  std::vector<char> c = encode_command(command, 11);
  const std::size_t text_end = 28 + text.size() + 1;
  const std::size_t sequence_at = (text_end + 7) / 8 * 8;
  ASSERT_EQ(c.size(), 4 + sequence_at + 8);
  EXPECT_EQ(c[4 + 0], 1);
  EXPECT_EQ(c[4 + 4], 4);
  EXPECT_EQ(c[4 + 8], 6);
  EXPECT_EQ(c[4 + 16], 7);
  EXPECT_EQ(static_cast<std::size_t>(c[4 + 24]), text.size() + 1);
  EXPECT_EQ(std::string(&c[4 + 28], text.size()), text);
  EXPECT_EQ(c[4 + sequence_at], 11);
  EXPECT_EQ(max_command_size(), 4u + 288u + 8u);  // the longest text ends at 284, the sequence at 288

  // The agent's state: robot @0, ready @4, pad, session @8.
  std::vector<char> a = encode_agent_state(3, {true, 0x21});
  ASSERT_EQ(a.size(), 4u + 16u);
  EXPECT_EQ(a[4 + 0], 3);
  EXPECT_EQ(a[4 + 4], 1);
  EXPECT_EQ(a[4 + 8], 0x21);
  EXPECT_EQ(max_agent_state_size(), a.size());
}

TEST(Wire, SequenceNumbersAndSessionsComeBackAsTheyWereSent) {
  auto program = exchange();
  std::uint64_t sequence = 0;
  decode_command(encode_command(command_of(program, 0, 2), 0xfedcba9876543210u), program, 0, &sequence);
  EXPECT_EQ(sequence, 0xfedcba9876543210u);
  StatusStamp stamp;
  decode_status(encode_status(runtime::RobotStatus{}, {77, 5}), 0, &stamp);
  EXPECT_EQ(stamp.session, 77u);
  EXPECT_EQ(stamp.sequence, 5u);
  AgentState state = decode_agent_state(encode_agent_state(1, {true, 99}), 1);
  EXPECT_TRUE(state.ready);
  EXPECT_EQ(state.session, 99u);
  EXPECT_THROW(decode_agent_state(encode_agent_state(1, {true, 0}), 1), WireError);  // sessions are never 0
}

// The reason a refusal gives, or "" when the number was taken.
std::string refusal(SequenceCheck& check, std::uint64_t n) {
  try {
    check.accept(n, "command");
    return "";
  } catch (const WireError& e) {
    return e.what();
  }
}

TEST(Wire, ASequenceTakesOneTwoThreeAndRefusesAGapOrADuplicateNamingTheNumbers) {
  SequenceCheck check;
  EXPECT_EQ(refusal(check, 1), "");
  EXPECT_EQ(refusal(check, 2), "");
  EXPECT_EQ(refusal(check, 2), "command 2 again, the last taken being 2: a duplicate, or a stale one");
  EXPECT_EQ(refusal(check, 1), "command 1 again, the last taken being 2: a duplicate, or a stale one");
  EXPECT_EQ(refusal(check, 4), "command 4 after 2: command 3 is missing");
  EXPECT_EQ(refusal(check, 9), "command 9 after 2: commands 3 to 8 are missing");
  EXPECT_EQ(check.last(), 2u);  // nothing refused was taken
  EXPECT_EQ(refusal(check, 3), "");
  check.restart();  // a new session
  EXPECT_EQ(refusal(check, 2), "command 2 after 0: command 1 is missing");  // its first one lost
  EXPECT_EQ(refusal(check, 1), "");
}

TEST(Wire, ALongReasonIsCutToItsBound) {
  runtime::RobotStatus status;
  status.reason.assign(5000, 'r');
  EXPECT_EQ(encode_status(status, {1, 1}).size(), max_status_size());
  EXPECT_EQ(decode_status(encode_status(status, {1, 1}), 0).reason.size(), kReasonBound - 1);
}

TEST(Wire, EveryTruncationOfAMessageIsRefused) {
  auto program = exchange();
  std::vector<char> bytes = encode_command(command_of(program, 1, 0), 1);
  for (std::size_t n = 0; n < bytes.size(); ++n) {
    std::vector<char> cut(bytes.begin(), bytes.begin() + n);
    EXPECT_THROW(decode_command(cut, program, 1), WireError) << n << " bytes";
  }
  runtime::RobotStatus status;
  status.reason = "a reason";
  bytes = encode_status(status, {1, 1});
  for (std::size_t n = 0; n < bytes.size(); ++n) {
    std::vector<char> cut(bytes.begin(), bytes.begin() + n);
    EXPECT_THROW(decode_status(cut, 0), WireError) << n << " bytes";
  }
}

TEST(Wire, ACommandNotOfThisRobotOrProgramIsRefusedNamingWhy) {
  auto program = exchange();
  runtime::MotionCommand command = command_of(program, 0, 1);
  std::vector<char> bytes = encode_command(command, 1);
  try {
    decode_command(bytes, program, 1);
    FAIL() << "another robot's command was taken";
  } catch (const WireError& e) {
    EXPECT_NE(std::string(e.what()).find("robot 0 on robot 1"), std::string::npos) << e.what();
  }
  command.index = 99;
  EXPECT_THROW(decode_command(encode_command(command, 1), program, 0), WireError);
  command.index = 1;
  command.primitive.workpiece = "Z";  // the text no longer matches the program's primitive 1
  command.primitive.kind = task::PrimitiveKind::kClose;
  try {
    decode_command(encode_command(command, 1), program, 0);
    FAIL() << "another program's command was taken";
  } catch (const WireError& e) {
    EXPECT_NE(std::string(e.what()).find("another program"), std::string::npos) << e.what();
  }
}

TEST(Wire, SeededRandomBytesAreRefusedNeverACrash) {
  auto program = exchange();
  std::mt19937 random(2028);
  for (int n = 0; n < 500; ++n) {
    std::vector<char> bytes(random() % 300);
    for (char& c : bytes) c = static_cast<char>(random() & 0xff);
    if (bytes.size() >= 2) {
      bytes[0] = 0;
      bytes[1] = 1;
    }
    EXPECT_THROW(decode_command(bytes, program, 0), WireError);
  }
}

TEST(Wire, AnOutcomeOtherThanDoneOrFailedIsRefused) {
  runtime::RobotStatus status;
  std::vector<char> bytes = encode_status(status, {1, 1});
  bytes[4 + 16] = 7;
  EXPECT_THROW(decode_status(bytes, 0), WireError);
}

}  // namespace
}  // namespace cellwright::distributed
