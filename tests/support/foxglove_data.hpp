// The Foxglove WebSocket protocol's Message Data (serve/live_server.hpp, "Foxglove") read back in tests: opcode 0x01,
// the subscription id (uint32) and the timestamp (uint64, ns), little-endian, then the payload.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

namespace cellwright::testing {

struct MessageData {
  std::uint32_t subscription = 0;
  std::uint64_t time_ns = 0;
  std::string payload;
};

// The Message Data that `bytes` is; none when it is not one.
inline std::optional<MessageData> decode_message_data(const std::string& bytes) {
  if (bytes.size() < 13 || bytes[0] != '\x01') return std::nullopt;
  MessageData d;
  for (int i = 0; i < 4; ++i) d.subscription |= std::uint32_t(std::uint8_t(bytes[1 + i])) << (8 * i);
  for (int i = 0; i < 8; ++i) d.time_ns |= std::uint64_t(std::uint8_t(bytes[5 + i])) << (8 * i);
  d.payload = bytes.substr(13);
  return d;
}

}  // namespace cellwright::testing
