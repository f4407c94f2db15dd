// PNML import/export: the hand-written corpus in data/ (nets in the style of MCC, PIPE, TINA and ePNK, and one
// malformed file per error), round trips of built, corpus and random nets, and atomic writing.
#include "cellwright/petri/pnml.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <limits>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "cellwright/common/error.hpp"
#include "cellwright/petri/analysis.hpp"

namespace cellwright::petri {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

const fs::path kData = fs::path(CW_SOURCE_DIR) / "tests/controller/petri/data";

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

const Place& place(const Net& net, const std::string& id) {
  const auto p = net.find_place(id);
  if (!p) throw std::runtime_error("no place " + id);
  return net.places()[*p];
}

const Transition& transition(const Net& net, const std::string& id) {
  const auto t = net.find_transition(id);
  if (!t) throw std::runtime_error("no transition " + id);
  return net.transitions()[*t];
}

// A pre- or post-set as "place-id*weight" strings, sorted, for readable comparisons.
std::vector<std::string> arcs(const Net& net, const std::vector<Arc>& set) {
  std::vector<std::string> out;
  for (const Arc& a : set) out.push_back(net.places()[a.place].id + "*" + std::to_string(a.weight));
  std::sort(out.begin(), out.end());
  return out;
}

std::size_t arc_count(const Net& net) {
  std::size_t n = 0;
  for (const Transition& t : net.transitions()) n += t.inputs.size() + t.outputs.size();
  return n;
}

void expect_same_origin(const Origin& a, const Origin& b, const std::string& what) {
  EXPECT_EQ(a.robot, b.robot) << what;
  EXPECT_EQ(a.line, b.line) << what;
  EXPECT_EQ(a.column, b.column) << what;
  EXPECT_EQ(a.task, b.task) << what;
  EXPECT_EQ(a.motion, b.motion) << what;
  EXPECT_EQ(a.primitive, b.primitive) << what;
}

void expect_same_arcs(const std::vector<Arc>& a, const std::vector<Arc>& b, const std::string& what) {
  ASSERT_EQ(a.size(), b.size()) << what;
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].place, b[i].place) << what << " arc " << i;
    EXPECT_EQ(a[i].weight, b[i].weight) << what << " arc " << i;
  }
}

// Everything a Net holds, in order: PlaceIds and TransitionIds must survive a round trip unchanged.
void expect_same_net(const Net& a, const Net& b) {
  EXPECT_EQ(a.name(), b.name());
  ASSERT_EQ(a.num_places(), b.num_places());
  ASSERT_EQ(a.num_transitions(), b.num_transitions());
  for (std::size_t i = 0; i < a.num_places(); ++i) {
    const Place& p = a.places()[i];
    const Place& q = b.places()[i];
    const std::string what = "place #" + std::to_string(i) + " '" + p.id + "'";
    EXPECT_EQ(p.id, q.id) << what;
    EXPECT_EQ(p.name, q.name) << what;
    EXPECT_EQ(p.initial, q.initial) << what;
    EXPECT_EQ(p.kind, q.kind) << what;
    expect_same_origin(p.origin, q.origin, what);
  }
  for (std::size_t i = 0; i < a.num_transitions(); ++i) {
    const Transition& t = a.transitions()[i];
    const Transition& u = b.transitions()[i];
    const std::string what = "transition #" + std::to_string(i) + " '" + t.id + "'";
    EXPECT_EQ(t.id, u.id) << what;
    EXPECT_EQ(t.name, u.name) << what;
    expect_same_arcs(t.inputs, u.inputs, what + " inputs");
    expect_same_arcs(t.outputs, u.outputs, what + " outputs");
    expect_same_origin(t.origin, u.origin, what);
    EXPECT_EQ(t.starts_robot, u.starts_robot) << what;
    EXPECT_EQ(t.starts_primitive, u.starts_primitive) << what;
  }
  ASSERT_EQ(a.regions().size(), b.regions().size());
  for (std::size_t i = 0; i < a.regions().size(); ++i) {
    EXPECT_EQ(a.regions()[i].name, b.regions()[i].name);
    EXPECT_EQ(a.regions()[i].inside, b.regions()[i].inside);
    EXPECT_EQ(a.regions()[i].capacity, b.regions()[i].capacity);
  }
  EXPECT_EQ(a.robots(), b.robots());
  expect_same_arcs(a.final_places(), b.final_places(), "final places");
}

// ---------------------------------------------------------------------------------------------------------------
// The corpus: nets written in other tools' styles.

TEST(PnmlImport, MccStyleKanbanWithNamespaceAndNestedPages) {
  const Net net = read_pnml(kData / "kanban-1.pnml");
  EXPECT_EQ(net.name(), "Kanban-PT-0001");
  ASSERT_EQ(net.num_places(), 16u);
  EXPECT_EQ(net.num_transitions(), 16u);
  EXPECT_EQ(arc_count(net), 40u);
  // Pages are flattened depth first in document order: cell 1's places come first.
  EXPECT_EQ(net.places()[0].id, "Pkan1");
  EXPECT_EQ(net.places()[4].id, "Pkan2");
  for (const Place& p : net.places()) {
    EXPECT_EQ(p.initial, p.id.rfind("Pkan", 0) == 0 ? 1u : 0u) << p.id;
    EXPECT_EQ(p.name, p.id);
    EXPECT_EQ(p.kind, PlaceKind::kPlain);
  }
  const Transition& sync = transition(net, "tsynch1_23");
  EXPECT_THAT(arcs(net, sync.inputs), ::testing::ElementsAre("Pkan2*1", "Pkan3*1", "Pout1*1"));
  EXPECT_THAT(arcs(net, sync.outputs), ::testing::ElementsAre("Pkan1*1", "Pm2*1", "Pm3*1"));
  EXPECT_TRUE(net.robots().empty());
  EXPECT_TRUE(net.regions().empty());
  EXPECT_FALSE(sync.starts_robot.has_value());
}

TEST(PnmlImport, PipeStylePhilosophersWithValuesGraphicsAndNoPage) {
  const Net net = read_pnml(kData / "philosophers-2.pnml");
  EXPECT_EQ(net.name(), "Net-One");  // no <name>: the net id
  EXPECT_EQ(net.num_places(), 8u);
  EXPECT_EQ(net.num_transitions(), 6u);
  EXPECT_EQ(arc_count(net), 20u);
  for (const char* id : {"think1", "think2", "fork1", "fork2"}) EXPECT_EQ(place(net, id).initial, 1u) << id;
  for (const char* id : {"left1", "left2", "eat1", "eat2"}) EXPECT_EQ(place(net, id).initial, 0u) << id;
  EXPECT_THAT(arcs(net, transition(net, "take_right1").inputs), ::testing::ElementsAre("fork2*1", "left1*1"));
  EXPECT_THAT(arcs(net, transition(net, "release2").outputs), ::testing::ElementsAre("fork1*1", "fork2*1", "think2*1"));
}

TEST(PnmlImport, TinaStyleProducerConsumerWithNamesAndWeights) {
  const Net net = read_pnml(kData / "producer-consumer.pnml");
  EXPECT_EQ(net.name(), "producer_consumer");
  ASSERT_EQ(net.num_places(), 6u);
  EXPECT_EQ(net.num_transitions(), 4u);
  EXPECT_EQ(arc_count(net), 12u);
  EXPECT_EQ(net.places()[3].id, "p-7A01-1B16-5");
  EXPECT_EQ(net.places()[3].name, "free");
  EXPECT_EQ(net.places()[3].initial, 3u);
  const Transition& take = transition(net, "t-7A01-1B28-10");
  EXPECT_EQ(take.name, "take_two");
  EXPECT_THAT(arcs(net, take.inputs), ::testing::ElementsAre("p-7A01-1B13-4*2", "p-7A01-1B1A-6*1"));
  EXPECT_THAT(arcs(net, take.outputs), ::testing::ElementsAre("p-7A01-1B16-5*2", "p-7A01-1B1D-7*1"));
}

TEST(PnmlImport, EpnkStyleReferencesWhitespaceMissingNamesAndParallelArcs) {
  const Net net = read_pnml(kData / "epnk-references.pnml");
  EXPECT_EQ(net.name(), "references and pages");  // surrounding white space is not part of a name
  ASSERT_EQ(net.num_places(), 3u);                // reference places are not places of their own
  ASSERT_EQ(net.num_transitions(), 2u);
  EXPECT_EQ(place(net, "p1").name, "inbox");
  EXPECT_EQ(place(net, "p1").initial, 2u);
  EXPECT_EQ(place(net, "p2").name, "p2");  // no <name>: the id
  EXPECT_EQ(place(net, "p2").initial, 0u);
  EXPECT_EQ(place(net, "p3").initial, 1u);
  const Transition& t1 = transition(net, "t1");
  // a3 goes rrp1 -> rp1 -> p1 and a1 is p1 -> t1 directly: parallel arcs add up.
  EXPECT_THAT(arcs(net, t1.inputs), ::testing::ElementsAre("p1*2", "p3*1"));
  EXPECT_THAT(arcs(net, t1.outputs), ::testing::ElementsAre("p2*1"));
  const Transition& t2 = transition(net, "t2");
  EXPECT_EQ(t2.name, "t2");
  EXPECT_THAT(arcs(net, t2.inputs), ::testing::ElementsAre("p2*1"));
  EXPECT_THAT(arcs(net, t2.outputs), ::testing::ElementsAre("p1*2", "p3*1"));
}

TEST(PnmlImport, SeveralNetsReadsTheFirstOrTheOneAskedFor) {
  const PnmlDocument first = read_pnml_document(kData / "two-nets.pnml");
  EXPECT_THAT(first.net_ids, ::testing::ElementsAre("first", "second"));
  EXPECT_EQ(first.net.name(), "first");
  EXPECT_EQ(first.net.num_places(), 1u);

  PnmlReadOptions options;
  options.net_id = "second";
  const Net second = read_pnml(kData / "two-nets.pnml", options);
  EXPECT_EQ(second.name(), "second");
  EXPECT_EQ(second.num_places(), 2u);
  EXPECT_EQ(second.num_transitions(), 2u);

  options.net_id = "third";
  try {
    read_pnml(kData / "two-nets.pnml", options);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_THAT(e.problem(), HasSubstr("no net with id 'third'"));
    EXPECT_THAT(e.problem(), HasSubstr("'first', 'second'"));
  }
}

TEST(PnmlImport, NamespacePrefixesAreAccepted) {
  const Net net = parse_pnml(R"(<pnml:pnml xmlns:pnml="http://www.pnml.org/version-2009/grammar/pnml">
  <pnml:net id="n" type="http://www.pnml.org/version-2009/grammar/ptnet"><pnml:page id="g">
    <pnml:place id="p"><pnml:initialMarking><pnml:text>4</pnml:text></pnml:initialMarking></pnml:place>
    <pnml:transition id="t"/>
    <pnml:arc id="a" source="p" target="t"><pnml:inscription><pnml:text>3</pnml:text></pnml:inscription></pnml:arc>
  </pnml:page></pnml:net></pnml:pnml>)",
                             "prefixed.pnml");
  ASSERT_EQ(net.num_places(), 1u);
  EXPECT_EQ(net.places()[0].initial, 4u);
  EXPECT_THAT(arcs(net, net.transitions()[0].inputs), ::testing::ElementsAre("p*3"));
}

TEST(PnmlImport, LargestTokenCountIsAcceptedOneMoreIsNot) {
  const auto net_with = [](const std::string& marking) {
    return "<pnml><net id='n'><page id='g'><place id='p'><initialMarking><text>" + marking +
           "</text></initialMarking></place></page></net></pnml>";
  };
  EXPECT_EQ(parse_pnml(net_with("4294967295"), "max.pnml").places()[0].initial, 4294967295u);
  EXPECT_EQ(parse_pnml(net_with("0007"), "zeros.pnml").places()[0].initial, 7u);
  EXPECT_THROW(parse_pnml(net_with("4294967296"), "over.pnml"), InputError);
  EXPECT_THROW(parse_pnml(net_with("+1"), "plus.pnml"), InputError);
  EXPECT_THROW(parse_pnml(net_with("1e3"), "exp.pnml"), InputError);
  EXPECT_THROW(parse_pnml(net_with("0x10"), "hex.pnml"), InputError);
}

// ---------------------------------------------------------------------------------------------------------------
// Malformed files: each bad-*.pnml says on its first line which line and problem it must be reported with:
// <!-- expect line N: problem text -->

struct Expectation {
  int line = 0;
  std::string problem;
};

Expectation expectation_of(const fs::path& file) {
  std::ifstream in(file);
  std::string first;
  std::getline(in, first);
  const std::string head = "<!-- expect line ";
  const std::string tail = " -->";
  if (first.rfind(head, 0) != 0 || first.size() < head.size() + tail.size() ||
      first.compare(first.size() - tail.size(), tail.size(), tail) != 0) {
    return {};
  }
  const std::string body = first.substr(head.size(), first.size() - head.size() - tail.size());  // "N: problem"
  const auto colon = body.find(": ");
  if (colon == std::string::npos || colon == 0 ||
      !std::all_of(body.begin(), body.begin() + static_cast<long>(colon),
                   [](char c) { return c >= '0' && c <= '9'; })) {
    return {};
  }
  return {std::stoi(body.substr(0, colon)), body.substr(colon + 2)};
}

TEST(PnmlImport, EveryMalformedFileGivesItsErrorAndLine) {
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(kData)) {
    if (entry.path().filename().string().rfind("bad-", 0) == 0) files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end());
  ASSERT_GE(files.size(), 25u) << "the malformed corpus is missing";
  for (const fs::path& file : files) {
    SCOPED_TRACE(file.filename().string());
    const Expectation want = expectation_of(file);
    ASSERT_GT(want.line, 0) << "first line has no '<!-- expect line N: problem -->'";
    try {
      read_pnml(file);
      ADD_FAILURE() << "read without error";
    } catch (const InputError& e) {
      EXPECT_EQ(e.where().file, file.string());
      EXPECT_EQ(e.where().line, want.line) << e.what();
      EXPECT_THAT(e.problem(), HasSubstr(want.problem));
      // what() is "file:line: error: problem", the form editors jump to.
      EXPECT_THAT(std::string(e.what()), HasSubstr(file.string() + ":" + std::to_string(want.line) + ": error: "));
    }
  }
}

TEST(PnmlImport, EmptyAndMissingFilesAreInputErrors) {
  try {
    parse_pnml("", "empty.pnml");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.where().file, "empty.pnml");
    EXPECT_THAT(e.problem(), HasSubstr("no XML element"));
  }
  const fs::path missing = kData / "no-such-file.pnml";
  try {
    read_pnml(missing);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.where().file, missing.string());
    EXPECT_EQ(e.problem(), "cannot read: no such file");
  }
  try {
    read_pnml(kData);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.problem(), "cannot read: is a directory, not a file");
  }
}

TEST(PnmlImport, HostileInputsAreReportedNotCrashedOn) {
  // Deep nesting: tinyxml2 refuses it before any recursion of ours could overflow the stack.
  std::string deep = "<pnml><net id='n'>";
  for (int i = 0; i < 5000; ++i) deep += "<page>";
  for (int i = 0; i < 5000; ++i) deep += "</page>";
  deep += "</net></pnml>";
  try {
    parse_pnml(deep, "deep.pnml");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_THAT(e.problem(), HasSubstr("nested deeper than"));
  }
  // A million-digit marking: reported with the value shortened, not wrapped and not echoed in full.
  const std::string digits(1'000'000, '9');
  try {
    parse_pnml("<pnml><net id='n'><place id='p'><initialMarking><text>" + digits +
                   "</text></initialMarking></place></net></pnml>",
               "huge.pnml");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_THAT(e.problem(), HasSubstr("exceeds the largest token count"));
    EXPECT_LT(e.problem().size(), 300u);
  }
}

// Seeded mutations of the corpus (truncations, byte flips, deleted and duplicated spans): each must either read as
// a net or raise an InputError; never another exception, a crash or a hang. Under the sanitizer build this also
// checks memory safety.
TEST(PnmlImport, MutatedFilesGiveAnInputErrorOrANet) {
  std::vector<std::string> originals;
  for (const char* file :
       {"kanban-1.pnml", "philosophers-2.pnml", "producer-consumer.pnml", "epnk-references.pnml", "two-nets.pnml"}) {
    originals.push_back(slurp(kData / file));
  }
  std::mt19937 rng(4242);
  const auto pick = [&](std::size_t n) { return std::uniform_int_distribution<std::size_t>(0, n - 1)(rng); };
  static constexpr char kRaw[] = "<>/&;\"'=- 0123456789abcxyz:!?\0\xff";  // includes a NUL byte
  const std::string kBytes(kRaw, sizeof(kRaw) - 1);
  std::size_t parsed = 0;
  std::size_t rejected = 0;
  for (int i = 0; i < 3000; ++i) {
    std::string text = originals[pick(originals.size())];
    for (std::size_t k = 0, n = 1 + pick(4); k < n; ++k) {
      const std::size_t at = pick(text.size());
      switch (pick(4)) {
        case 0:
          text.resize(at);
          break;
        case 1:
          text[at] = kBytes[pick(kBytes.size())];
          break;
        case 2:
          text.erase(at, pick(40));
          break;
        default:
          text.insert(at, text.substr(pick(text.size()), pick(60)));
          break;
      }
      if (text.empty()) text = "<";
    }
    try {
      const Net net = parse_pnml(text, "mutant.pnml");
      expect_same_net(net, parse_pnml(to_pnml(net), "mutant-again.pnml"));
      ++parsed;
    } catch (const InputError& e) {
      EXPECT_EQ(e.where().file, "mutant.pnml");
      EXPECT_FALSE(e.problem().empty());
      ++rejected;
    }
  }
  // Both outcomes must occur, or the mutations are not testing anything.
  EXPECT_GT(parsed, 100u);
  EXPECT_GT(rejected, 100u);
}

// ---------------------------------------------------------------------------------------------------------------
// Export and round trips.

// A net as the task compiler builds it: kinds, origins, robot starts, a region, final places.
Net cellwright_net() {
  NetBuilder b("hand over <A & B>");
  const auto add_place = [&](std::string id, Tokens initial, PlaceKind kind, Origin origin) {
    Place p;
    p.id = id;
    p.name = id + " \"quoted\"";
    p.initial = initial;
    p.kind = kind;
    p.origin = std::move(origin);
    return b.add_place(std::move(p));
  };
  const PlaceId start1 = add_place("r1.start", 1, PlaceKind::kStart, {"r1", 0, 0, "", "", -1});
  const PlaceId exec1 = add_place("r1.l1.exec", 0, PlaceKind::kExecuting, {"r1", 1, 1, "Pick A", "approach A", 0});
  const PlaceId done1 = add_place("r1.done", 0, PlaceKind::kDone, {"r1", 0, 0, "", "", -1});
  const PlaceId start2 = add_place("r2.start", 1, PlaceKind::kStart, {"r2", 0, 0, "", "", -1});
  const PlaceId wait2 = add_place("r2.l2.wait", 0, PlaceKind::kWaiting, {"r2", 2, 12, "Get r1", "wait step2", 3});
  const PlaceId done2 = add_place("r2.done", 0, PlaceKind::kDone, {"r2", 0, 0, "", "", -1});
  const PlaceId event = add_place("step2", 0, PlaceKind::kEvent, {});
  const PlaceId region = add_place("region.table", 1, PlaceKind::kRegion, {});
  const auto add_transition = [&](std::string id, std::vector<Arc> in, std::vector<Arc> out, Origin origin,
                                  std::optional<std::uint32_t> robot, int primitive) {
    Transition t;
    t.id = id;
    t.name = id;
    t.inputs = std::move(in);
    t.outputs = std::move(out);
    t.origin = std::move(origin);
    t.starts_robot = robot;
    t.starts_primitive = primitive;
    b.add_transition(std::move(t));
  };
  add_transition("r1.l1.begin", {{start1, 1}, {region, 1}}, {{exec1, 1}},
                 {"r1", 1, 1, "Pick A", "approach A\n(then <grasp>)", 0}, 0u, 0);
  add_transition("r1.l1.end", {{exec1, 1}}, {{done1, 1}, {event, 2}, {region, 1}}, {"r1", 1, 1, "Pick A", "", 0},
                 std::nullopt, -1);
  add_transition("r2.l2.begin", {{start2, 1}}, {{wait2, 1}}, {"r2", 2, 12, "Get r1", "wait step2", 3}, 1u, 3);
  add_transition("r2.l2.end", {{wait2, 1}, {event, 2}}, {{done2, 1}}, {"r2", 2, 12, "Get r1", "", -1}, std::nullopt, 7);
  b.set_robots({"r1", "r2"});
  b.add_region(Region{"table", {exec1}, 1});
  b.set_final({{done1, 1}, {done2, 1}});
  return std::move(b).build();
}

TEST(PnmlExport, WritesStandardPtNetElements) {
  const std::string xml = to_pnml(cellwright_net());
  EXPECT_THAT(xml, HasSubstr("<?xml version=\"1.0\" encoding=\"UTF-8\"?>"));
  EXPECT_THAT(xml, HasSubstr("<pnml xmlns=\"http://www.pnml.org/version-2009/grammar/pnml\">"));
  EXPECT_THAT(xml, HasSubstr("type=\"http://www.pnml.org/version-2009/grammar/ptnet\""));
  EXPECT_THAT(xml, HasSubstr("<initialMarking>"));
  EXPECT_THAT(xml, HasSubstr("<inscription>"));
  EXPECT_THAT(xml, HasSubstr("<toolspecific tool=\"cellwright\" version=\"1\">"));
  EXPECT_THAT(xml, HasSubstr("hand over &lt;A &amp; B&gt;"));
  // One initialMarking per marked place (3 of 8) and one inscription per arc of weight > 1 (2 of 12).
  const auto count = [&](const std::string& what) {
    std::size_t n = 0;
    for (std::size_t at = xml.find(what); at != std::string::npos; at = xml.find(what, at + 1)) ++n;
    return n;
  };
  EXPECT_EQ(count("<initialMarking>"), 3u);
  EXPECT_EQ(count("<inscription>"), 2u);
  EXPECT_EQ(count("<arc "), 12u);
  EXPECT_EQ(count("<place "), 8u);
}

TEST(PnmlExport, CellwrightNetRoundTripsExactly) {
  const Net net = cellwright_net();
  const Net back = parse_pnml(to_pnml(net), "roundtrip.pnml");
  expect_same_net(net, back);
  // And a second trip gives the same text: export is deterministic.
  EXPECT_EQ(to_pnml(back), to_pnml(net));
}

TEST(PnmlExport, CorpusNetsRoundTrip) {
  for (const char* file :
       {"kanban-1.pnml", "philosophers-2.pnml", "producer-consumer.pnml", "epnk-references.pnml", "two-nets.pnml"}) {
    SCOPED_TRACE(file);
    const Net net = read_pnml(kData / file);
    expect_same_net(net, parse_pnml(to_pnml(net), file));
  }
}

// A net or node without <name> is named by its id, with the white space around the id dropped as around a name, so
// that the export reads back as the same net (found by tests/fuzz/pnml_fuzz: a net id "   x" gave the name "   x",
// whose export read back as "x").
TEST(PnmlExport, NamesTakenFromIdsWithSpacesRoundTrip) {
  const Net net = parse_pnml(R"(<pnml><net id="   net x "><page id="pg"><place id=" p1"/><transition id="t1 "/>
                                <arc id="a" source=" p1" target="t1 "/></page></net></pnml>)",
                             "spaces.pnml");
  EXPECT_EQ(net.name(), "net x");
  ASSERT_EQ(net.places().size(), 1U);
  EXPECT_EQ(net.places()[0].id, " p1");
  EXPECT_EQ(net.places()[0].name, "p1");
  ASSERT_EQ(net.transitions().size(), 1U);
  EXPECT_EQ(net.transitions()[0].name, "t1");
  expect_same_net(net, parse_pnml(to_pnml(net), "spaces-again.pnml"));
}

// Also: an empty name stays empty (a file without <name> would be read as named by the id).
TEST(PnmlExport, GeneratedIdsAvoidNodeIdsAndEmptyNamesStayEmpty) {
  NetBuilder b("clash");
  for (const char* id : {"net", "page0", "a0", "a1"}) b.add_place(Place{id, id, 1, PlaceKind::kPlain, {}});
  Transition t;
  t.id = "t";
  t.inputs = {{0, 1}, {1, 1}};
  t.outputs = {{2, 1}, {3, 1}};
  b.add_transition(t);
  const Net net = std::move(b).build();
  const Net back = parse_pnml(to_pnml(net), "clash.pnml");  // a duplicate id would be an error here
  expect_same_net(net, back);
}

// Random nets with hostile text: XML specials, quotes, unicode, spaces inside ids, large weights and markings.
// `small`: token counts and weights up to 3, so that the reachability graph stays small enough to analyse.
Net random_net(std::mt19937& rng, bool small = false) {
  const auto pick = [&](std::size_t n) { return std::uniform_int_distribution<std::size_t>(0, n - 1)(rng); };
  static const std::vector<std::string> kPieces = {"a",   "<", ">",     "&",  "\"", "'",  "é",  "→", "x y",  "\\",
                                                   "]]>", "7", "&amp;", "\t", "ü",  "\r", "\n", " ", "\r\n", "\x01"};
  const auto text = [&](std::size_t max_pieces) {
    std::string s;
    const std::size_t n = 1 + pick(max_pieces);
    for (std::size_t i = 0; i < n; ++i) s += kPieces[pick(kPieces.size())];
    return s;
  };
  const auto tokens = [&]() -> Tokens {
    if (small) return static_cast<Tokens>(pick(4));
    switch (pick(4)) {
      case 0:
        return 0;
      case 1:
        return 1;
      case 2:
        return static_cast<Tokens>(pick(100));
      default:
        return std::uniform_int_distribution<Tokens>(0, std::numeric_limits<Tokens>::max())(rng);
    }
  };
  const auto origin = [&]() {
    Origin o;
    if (pick(2) == 0) return o;
    o.robot = "r" + std::to_string(pick(3));
    o.line = static_cast<int>(pick(500));
    o.column = static_cast<int>(pick(80));
    o.task = pick(2) ? text(4) : "";
    o.motion = pick(2) ? text(4) : "";
    o.primitive = static_cast<int>(pick(20)) - 1;
    return o;
  };
  NetBuilder b("N" + text(3) + "N");
  const std::size_t np = 1 + pick(12);
  const std::size_t nt = pick(10);
  for (std::size_t i = 0; i < np; ++i) {
    Place p;
    p.id = "p" + std::to_string(i) + (pick(3) == 0 ? "_" + text(2) : "");
    // Names without edge white space: PNML readers trim it (see pnml.hpp).
    p.name = pick(4) == 0 ? "" : "n" + text(5) + "n";
    p.initial = tokens();
    p.kind = static_cast<PlaceKind>(pick(7));
    p.origin = origin();
    b.add_place(std::move(p));
  }
  std::vector<std::string> robots;
  for (std::size_t r = 0, n = pick(3); r < n; ++r) robots.push_back("robot " + std::to_string(r) + text(1));
  for (std::size_t i = 0; i < nt; ++i) {
    Transition t;
    t.id = "t" + std::to_string(i) + (pick(3) == 0 ? "_" + text(2) : "");
    t.name = pick(4) == 0 ? "" : "n" + text(4) + "n";
    std::vector<PlaceId> order(np);
    for (std::size_t k = 0; k < np; ++k) order[k] = static_cast<PlaceId>(k);
    std::shuffle(order.begin(), order.end(), rng);
    for (std::size_t k = 0, n = pick(std::min<std::size_t>(np, 4) + 1); k < n; ++k) {
      t.inputs.push_back({order[k], std::max<Tokens>(1, tokens())});
    }
    std::shuffle(order.begin(), order.end(), rng);
    for (std::size_t k = 0, n = pick(std::min<std::size_t>(np, 4) + 1); k < n; ++k) {
      t.outputs.push_back({order[k], std::max<Tokens>(1, tokens())});
    }
    t.origin = origin();
    if (!robots.empty() && pick(2) == 0) t.starts_robot = static_cast<std::uint32_t>(pick(robots.size()));
    t.starts_primitive = static_cast<int>(pick(10)) - 1;
    b.add_transition(std::move(t));
  }
  std::vector<PlaceId> all(np);
  for (std::size_t k = 0; k < np; ++k) all[k] = static_cast<PlaceId>(k);
  for (std::size_t r = 0, n = pick(3); r < n; ++r) {
    std::shuffle(all.begin(), all.end(), rng);
    b.add_region(Region{"region " + std::to_string(r) + text(2),
                        std::vector<PlaceId>(all.begin(), all.begin() + static_cast<long>(1 + pick(np))),
                        static_cast<Tokens>(1 + pick(3))});
  }
  std::shuffle(all.begin(), all.end(), rng);
  std::vector<Arc> final_places;
  for (std::size_t k = 0, n = pick(np + 1); k < n; ++k)
    final_places.push_back({all[k], 1 + static_cast<Tokens>(pick(3))});
  b.set_final(std::move(final_places));
  b.set_robots(std::move(robots));
  return std::move(b).build();
}

TEST(PnmlExport, RandomNetsRoundTrip) {
  std::mt19937 rng(20240611);  // fixed seed: a failure reproduces
  for (int i = 0; i < 300; ++i) {
    SCOPED_TRACE("random net #" + std::to_string(i));
    const Net net = random_net(rng);
    const std::string xml = to_pnml(net);
    expect_same_net(net, parse_pnml(xml, "random.pnml"));
    if (::testing::Test::HasFailure()) {
      ADD_FAILURE() << xml;
      break;
    }
  }
}

// ---------------------------------------------------------------------------------------------------------------
// Analysis of imported nets: the figures must match independent counts, and survive a round trip.

void expect_same_analysis(const AnalysisResult& a, const AnalysisResult& b) {
  EXPECT_EQ(a.complete, b.complete);
  EXPECT_EQ(a.states, b.states);
  EXPECT_EQ(a.edges, b.edges);
  EXPECT_EQ(a.deadlocks, b.deadlocks);
  EXPECT_EQ(a.final_states, b.final_states);
  EXPECT_EQ(a.bounded, b.bounded);
  EXPECT_EQ(a.unbounded_places, b.unbounded_places);
  EXPECT_EQ(a.place_bounds, b.place_bounds);
  EXPECT_EQ(a.dead_transitions, b.dead_transitions);
  EXPECT_EQ(a.mutex_ok, b.mutex_ok);
  EXPECT_EQ(a.ok(), b.ok());
}

// The same net with every initial marking multiplied by n.
Net scaled(const Net& net, Tokens n) {
  NetBuilder b(net.name());
  for (Place p : net.places()) {
    p.initial *= n;
    b.add_place(std::move(p));
  }
  for (const Transition& t : net.transitions()) b.add_transition(t);
  return std::move(b).build();
}

TEST(PnmlAnalysis, KanbanStateCountsFollowTheClosedForm) {
  // Ciardo and Tilgner's Kanban net: C(N+3,3)^2 * (3N^5+30N^4+115N^3+210N^2+182N+60)/60 reachable markings
  // (facts.md: 160 for N=1, 4,600 for N=2).
  const auto expected = [](std::uint64_t n) {
    const std::uint64_t c = (n + 3) * (n + 2) * (n + 1) / 6;
    return c * c * (3 * n * n * n * n * n + 30 * n * n * n * n + 115 * n * n * n + 210 * n * n + 182 * n + 60) / 60;
  };
  const Net kanban = read_pnml(kData / "kanban-1.pnml");
  for (Tokens n = 1; n <= 3; ++n) {
    SCOPED_TRACE("N=" + std::to_string(n));
    const AnalysisResult r = analyze(scaled(kanban, n));
    EXPECT_TRUE(r.complete);
    EXPECT_EQ(r.states, expected(n));
    EXPECT_EQ(r.deadlocks, 0u);
    EXPECT_TRUE(r.bounded);
    EXPECT_TRUE(r.ok());
  }
}

// A file saved with a UTF-8 byte-order mark reads as the same net; errors keep their lines.
TEST(PnmlImport, ByteOrderMarkIsAccepted) {
  std::ifstream in(kData / "kanban-1.pnml", std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  const Net net = parse_pnml("\xEF\xBB\xBF" + text.str(), "bom.pnml");
  EXPECT_EQ(net.name(), "Kanban-PT-0001");
  EXPECT_EQ(net.num_places(), 16u);
  try {
    (void)parse_pnml("\xEF\xBB\xBF<?xml version=\"1.0\"?>\n<pnml>\n<net id=\"n\">\n</pnml>\n", "bom.pnml");
    ADD_FAILURE() << "a broken file was accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.where().file, "bom.pnml");
    EXPECT_GE(e.where().line, 3) << e.what();
  }
}

TEST(PnmlAnalysis, PhilosophersDeadlockWhenBothHoldTheirLeftFork) {
  const Net net = read_pnml(kData / "philosophers-2.pnml");
  const AnalysisResult r = analyze(net);
  // By hand: both thinking; one holds the left fork (2 ways); both hold it (the deadlock); one eats (2 ways).
  EXPECT_EQ(r.states, 6u);
  EXPECT_EQ(r.deadlocks, 1u);
  EXPECT_FALSE(r.ok());
  ASSERT_FALSE(r.deadlock_examples.empty());
  std::vector<std::string> path;
  for (TransitionId t : r.deadlock_examples[0].path) path.push_back(net.transitions()[t].id);
  EXPECT_THAT(path, ::testing::UnorderedElementsAre("take_left1", "take_left2"));
}

TEST(PnmlAnalysis, ProducerConsumerBufferIsBoundedByItsCapacity) {
  const Net net = read_pnml(kData / "producer-consumer.pnml");
  const AnalysisResult r = analyze(net);
  // Producer (2 states) x consumer (2 states) x items in the buffer (0..3): all 16 reachable, none dead.
  EXPECT_EQ(r.states, 16u);
  EXPECT_EQ(r.deadlocks, 0u);
  EXPECT_TRUE(r.ok());
  EXPECT_EQ(r.place_bounds.at(*net.find_place("p-7A01-1B13-4")), 3u);  // buffer
}

TEST(PnmlAnalysis, FiguresSurviveARoundTrip) {
  for (const char* file : {"kanban-1.pnml", "philosophers-2.pnml", "producer-consumer.pnml", "epnk-references.pnml"}) {
    SCOPED_TRACE(file);
    const Net net = read_pnml(kData / file);
    expect_same_analysis(analyze(net), analyze(parse_pnml(to_pnml(net), file)));
  }
  const Net cw = cellwright_net();
  expect_same_analysis(analyze(cw), analyze(parse_pnml(to_pnml(cw), "cellwright.pnml")));

  std::mt19937 rng(77);
  AnalysisOptions options;
  options.max_states = 20'000;  // random nets may be unbounded or large; the limit is part of what must agree
  for (int i = 0; i < 100; ++i) {
    SCOPED_TRACE("random net #" + std::to_string(i));
    const Net net = random_net(rng, true);
    expect_same_analysis(analyze(net, options), analyze(parse_pnml(to_pnml(net), "random.pnml"), options));
  }
}

// ---------------------------------------------------------------------------------------------------------------
// Writing files.

class PnmlWrite : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("cw-pnml-test-" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::vector<std::string> entries() const {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(dir_)) names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
  }
  fs::path dir_;
};

TEST_F(PnmlWrite, WritesAReadableFileAndReplacesAnOldOne) {
  const fs::path file = dir_ / "net.pnml";
  {
    std::ofstream old(file);
    old << "old contents";
  }
  const Net net = cellwright_net();
  write_pnml(net, file);
  expect_same_net(net, read_pnml(file));
  EXPECT_THAT(entries(), ::testing::ElementsAre("net.pnml"));  // no temporary file left behind
  EXPECT_EQ(slurp(file), to_pnml(net));
}

TEST_F(PnmlWrite, AFailedWriteLeavesNothingBehind) {
  // The target is a directory: the final rename fails after the temporary file was written.
  fs::create_directory(dir_ / "taken.pnml");
  try {
    write_pnml(cellwright_net(), dir_ / "taken.pnml");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.where().file, (dir_ / "taken.pnml").string());
    EXPECT_THAT(e.problem(), HasSubstr("cannot write"));
  }
  EXPECT_THAT(entries(), ::testing::ElementsAre("taken.pnml"));
  EXPECT_TRUE(fs::is_directory(dir_ / "taken.pnml"));

  try {
    write_pnml(cellwright_net(), dir_ / "no-such-dir" / "net.pnml");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_THAT(e.problem(), HasSubstr("No such file or directory"));
  }
  EXPECT_THAT(entries(), ::testing::ElementsAre("taken.pnml"));
}

}  // namespace
}  // namespace cellwright::petri
