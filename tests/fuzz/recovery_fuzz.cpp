// libFuzzer harness: the recovery decision tree (controller/runtime, recovery.hpp). YAML text -> DecisionTree::parse;
// an accepted tree is walked for every symptom with every question answered yes, then no, then alternately: each walk
// must end at a leaf naming a cause. Only InputError may refuse it. Seeds: scenes/recovery.yaml.
#include "cellwright/runtime/recovery.hpp"
#include "fuzz.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = cellwright::fuzz::text_of(data, size);
  cellwright::fuzz::refusing_only_with_input_errors([&] {
    using namespace cellwright::runtime;
    const DecisionTree tree = DecisionTree::parse(text, "fuzz-recovery.yaml");
    for (std::size_t s = 0; s < kSymptoms; ++s) {
      const auto symptom = static_cast<Symptom>(s);
      for (int way = 0; way < 3; ++way) {
        int asked = 0;
        const Diagnosis d = tree.diagnose(symptom, [&](Question) { return way == 2 ? (asked++ % 2 == 0) : way == 0; });
        CW_FUZZ_CHECK(!d.cause.empty());
        CW_FUZZ_CHECK(d.symptom == symptom);
      }
    }
  });
  return 0;
}
