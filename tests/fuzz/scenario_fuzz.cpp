// libFuzzer harness: scenarios (cell/). YAML text -> parse_scenario, named as if it were in scenes/ so that
// the cell, program and recovery files it names resolve to the repository's. Only InputError may refuse it. Seeds:
// scenes/*.yaml but cell.yaml and recovery.yaml.
#include "cellwright/cell/scenario.hpp"
#include "fuzz.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = cellwright::fuzz::text_of(data, size);
  cellwright::fuzz::refusing_only_with_input_errors([&] {
    (void)cellwright::cell::parse_scenario(text,
                                                     std::filesystem::path(CW_SOURCE_DIR) / "scenes" / "fuzz.yaml");
  });
  return 0;
}
