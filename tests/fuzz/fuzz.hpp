// What every libFuzzer harness in tests/fuzz shares (docs/CONTRIBUTING.md, "Fuzzing the readers"): the input as
// text, the rule that an InputError is a reader's documented refusal and anything else is a finding, and a check for
// the properties a harness asserts beyond "no crash" (a round trip, finite numbers).
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

#include "cellwright/common/error.hpp"

namespace cellwright::fuzz {

inline std::string text_of(const std::uint8_t* data, std::size_t size) {
  return {reinterpret_cast<const char*>(data), size};
}

// Runs `read`. An InputError is the clean refusal every reader documents; it must name a problem. Any other
// exception (InternalError from a CW_CHECK, std::out_of_range, YAML::Exception, ...) is not caught: it terminates the
// process and libFuzzer keeps the input as a crash.
template <class Read>
void refusing_only_with_input_errors(Read&& read) {
  try {
    read();
  } catch (const InputError& e) {
    if (e.problem().empty()) {
      std::fprintf(stderr, "an InputError without a problem: %s\n", e.what());
      std::abort();
    }
  }
}

}  // namespace cellwright::fuzz

// A property of an accepted input that must hold; aborts (a libFuzzer finding) with the condition when it does not.
#define CW_FUZZ_CHECK(cond)                                                                 \
  do {                                                                                      \
    if (!(cond)) {                                                                          \
      std::fprintf(stderr, "%s:%d: fuzz property failed: %s\n", __FILE__, __LINE__, #cond); \
      std::abort();                                                                         \
    }                                                                                       \
  } while (false)
