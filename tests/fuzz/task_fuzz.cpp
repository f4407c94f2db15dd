// libFuzzer harness: the task language (controller/task). Text -> parse_program -> compile -> listing, JSON and the
// Petri net; only InputError may refuse it. Seeds: scenes/*.task.
#include "cellwright/task/compile.hpp"
#include "cellwright/task/program.hpp"
#include "cellwright/task/to_net.hpp"
#include "fuzz.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = cellwright::fuzz::text_of(data, size);
  cellwright::fuzz::refusing_only_with_input_errors([&] {
    using namespace cellwright::task;
    const CompiledProgram compiled = compile(parse_program(text, "fuzz.task"));
    CW_FUZZ_CHECK(!format_listing(compiled).empty());
    CW_FUZZ_CHECK(!to_json(compiled).dump().empty());
    (void)to_net(compiled);
  });
  return 0;
}
