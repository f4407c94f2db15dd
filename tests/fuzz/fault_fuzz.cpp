// libFuzzer harness: fault specs as the command line gives them (`--fault KIND:key=value,...`, twin/model/faults).
// Text -> parse_fault_text against scenes/cell.yaml; an accepted spec is written back with to_text and must read as
// the same spec. Only InputError may refuse it. Seeds: the specs of docs/faults.md and the tests.
#include "cellwright/models/cell.hpp"
#include "cellwright/twin/faults.hpp"
#include "fuzz.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace cellwright::twin;
  static const cellwright::models::CellDescription cell =
      cellwright::models::load_cell(std::filesystem::path(CW_SOURCE_DIR) / "scenes" / "cell.yaml");
  const std::string text = cellwright::fuzz::text_of(data, size);
  cellwright::fuzz::refusing_only_with_input_errors([&] {
    const FaultSpec spec = parse_fault_text(text, cell);
    const std::string written = to_text(spec);
    try {
      CW_FUZZ_CHECK(parse_fault_text(written, cell) == spec);
    } catch (const cellwright::InputError& e) {
      std::fprintf(stderr, "'%s' read as '%s', which is refused: %s\n", text.c_str(), written.c_str(), e.what());
      std::abort();
    }
  });
  return 0;
}
