// libFuzzer harness: the cell description (models/cell). YAML text -> parse_cell, named as if it were scenes/cell.yaml
// so that its URDF paths resolve to the repository's robots; an accepted cell has its reach checked. Only InputError
// may refuse it. Seeds: scenes/cell.yaml and the cells of the tests.
#include "cellwright/models/cell.hpp"
#include "fuzz.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = cellwright::fuzz::text_of(data, size);
  cellwright::fuzz::refusing_only_with_input_errors([&] {
    using namespace cellwright::models;
    const CellDescription cell = parse_cell(text, std::filesystem::path(CW_SOURCE_DIR) / "scenes" / "fuzz-cell.yaml");
    (void)check_reach(cell);
  });
  return 0;
}
