// Seeded "garbage in" for the readers' tests: valid inputs with random edits, fed to a reader, which must either
// accept the mutant or refuse it with an InputError naming the file it was given and a problem; any other exception
// is a test failure (and a crash or a hang fails the whole suite). The number of rounds and edits is fixed, so the
// time is bounded by construction, and the seed is fixed, so a failure reproduces. tests/fuzz runs the same readers
// under libFuzzer for longer (docs/CONTRIBUTING.md).
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <exception>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "cellwright/common/error.hpp"

namespace cellwright::testing {

inline std::string slurp_text(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// One edit of `text`: a byte replaced by one of `alphabet` or by any byte, one of `alphabet` inserted, a span of up
// to 16 bytes deleted, a span of up to 40 bytes copied elsewhere, or the text cut short.
inline std::string mutate(std::string text, std::mt19937_64& rng, std::string_view alphabet) {
  const auto below = [&rng](std::size_t n) { return n == 0 ? std::size_t{0} : static_cast<std::size_t>(rng() % n); };
  if (text.empty()) return std::string(1, alphabet[below(alphabet.size())]);
  const std::size_t at = below(text.size());
  switch (below(8)) {
    case 0:
    case 1:
      text[at] = alphabet[below(alphabet.size())];
      break;
    case 2:
      text[at] = static_cast<char>(below(256));
      break;
    case 3:
    case 4:
      text.insert(text.begin() + static_cast<std::ptrdiff_t>(at), alphabet[below(alphabet.size())]);
      break;
    case 5:
      text.erase(at, 1 + below(16));
      break;
    case 6:
      text.insert(below(text.size() + 1), text.substr(at, 1 + below(40)));
      break;
    default:
      text.resize(at + below(text.size() - at));
      break;
  }
  return text;
}

struct GarbageCounts {
  int accepted = 0;
  int refused = 0;
};

// `rounds` mutants, each of an original picked at random with 1 to `max_edits` edits, fed to `read(text)` (which
// throws InputError to refuse). A refusal must name `file`; anything but an InputError fails the test with the text.
template <class Read>
GarbageCounts feed_garbage(const std::vector<std::string>& originals, int rounds, std::uint64_t seed,
                           std::string_view alphabet, const std::string& file, Read&& read, int max_edits = 4) {
  std::mt19937_64 rng(seed);
  GarbageCounts counts;
  for (int round = 0; round < rounds; ++round) {
    std::string text = originals[static_cast<std::size_t>(rng() % originals.size())];
    const int edits = 1 + static_cast<int>(rng() % static_cast<std::uint64_t>(max_edits));
    for (int e = 0; e < edits; ++e) text = mutate(std::move(text), rng, alphabet);
    try {
      read(text);
      ++counts.accepted;
    } catch (const InputError& error) {
      ++counts.refused;
      EXPECT_EQ(error.where().file, file) << error.what() << "\nfor input:\n" << text;
      EXPECT_FALSE(error.problem().empty()) << "for input:\n" << text;
    } catch (const std::exception& error) {
      ADD_FAILURE() << "round " << round << ": not an InputError: " << error.what() << "\nfor input:\n" << text;
    }
    if (::testing::Test::HasFailure()) break;
  }
  return counts;
}

}  // namespace cellwright::testing
