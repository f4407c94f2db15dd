// libFuzzer harness: PNML import (controller/petri). Text -> parse_pnml_document; an accepted net is exported and read
// back as the same net (pnml.hpp's round trip). Only InputError may refuse it. Seeds: tests/controller/petri/data.
#include "cellwright/petri/pnml.hpp"
#include "fuzz.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = cellwright::fuzz::text_of(data, size);
  cellwright::fuzz::refusing_only_with_input_errors([&] {
    using namespace cellwright::petri;
    const PnmlDocument doc = parse_pnml_document(text, "fuzz.pnml");
    CW_FUZZ_CHECK(!doc.net_ids.empty());
    const std::string again = to_pnml(doc.net);
    // The export of an accepted net is read back (an InputError here is a finding: our own output refused).
    try {
      CW_FUZZ_CHECK(to_pnml(parse_pnml(again, "again.pnml")) == again);
    } catch (const cellwright::InputError& e) {
      std::fprintf(stderr, "our own export refused: %s\n", e.what());
      std::abort();
    }
  });
  return 0;
}
