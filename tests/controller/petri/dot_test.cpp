// DOT export: every node and weight is drawn, text from the net is escaped so that Graphviz accepts any id or name,
// and the output renders with `dot` when it is installed.
#include "cellwright/petri/dot.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "cellwright/common/error.hpp"
#include "cellwright/petri/pnml.hpp"

namespace cellwright::petri {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::Not;

const fs::path kData = fs::path(CW_SOURCE_DIR) / "tests/controller/petri/data";

std::size_t count(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (std::size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

bool have_dot() {
  return std::system("command -v dot >/dev/null 2>&1") == 0;
}

// Renders DOT text to SVG with Graphviz; returns the SVG, or fails the test when dot rejects the input.
std::string render_svg(const std::string& dot_text) {
  const fs::path dir = fs::temp_directory_path();
  const std::string stem = "cw-dot-test-" + std::to_string(::getpid());
  const fs::path in = dir / (stem + ".dot");
  const fs::path out = dir / (stem + ".svg");
  const fs::path err = dir / (stem + ".err");
  {
    std::ofstream f(in, std::ios::binary);
    f << dot_text;
  }
  const std::string cmd = "dot -Tsvg '" + in.string() + "' -o '" + out.string() + "' 2>'" + err.string() + "'";
  const int status = std::system(cmd.c_str());
  std::ostringstream svg;
  svg << std::ifstream(out).rdbuf();
  std::ostringstream errors;
  errors << std::ifstream(err).rdbuf();
  fs::remove(in);
  fs::remove(out);
  fs::remove(err);
  EXPECT_EQ(status, 0) << "dot rejected:\n" << dot_text << "\n" << errors.str();
  // Graphviz reports syntax problems as warnings with exit status 0 in some versions; none are expected.
  EXPECT_EQ(errors.str(), "") << dot_text;
  return svg.str();
}

Net small_net() {
  NetBuilder b("small");
  b.add_place(Place{"idle", "robot idle", 2, PlaceKind::kStart, Origin{"r1", 1, 1, "", "", -1}});
  b.add_place(Place{"busy", "robot busy", 0, PlaceKind::kExecuting, Origin{"r1", 2, 3, "Pick A", "approach A", 0}});
  b.add_place(Place{"sem", "", 1, PlaceKind::kEvent, Origin{}});
  Transition go;
  go.id = "go";
  go.name = "begin pick";
  go.inputs = {{0, 2}, {2, 1}};
  go.outputs = {{1, 1}};
  go.origin = Origin{"r1", 2, 3, "Pick A", "approach A", 0};
  b.add_transition(go);
  Transition back;
  back.id = "back";
  back.name = "end pick";
  back.inputs = {{1, 1}};
  back.outputs = {{0, 2}, {2, 1}};
  b.add_transition(back);
  return std::move(b).build();
}

TEST(Dot, DrawsEveryPlaceTransitionTokenAndWeight) {
  const std::string dot = to_dot(small_net());
  EXPECT_EQ(dot.rfind("digraph \"small\" {", 0), 0u);
  EXPECT_THAT(dot, HasSubstr("p0 [shape=circle"));
  EXPECT_THAT(dot, HasSubstr("p1 [shape=circle"));
  EXPECT_THAT(dot, HasSubstr("p2 [shape=circle"));
  EXPECT_THAT(dot, HasSubstr("t0 [shape=box"));
  EXPECT_THAT(dot, HasSubstr("t1 [shape=box"));
  EXPECT_EQ(count(dot, "shape=circle"), 3u);
  EXPECT_EQ(count(dot, "shape=box"), 2u);
  // Tokens inside the circles: 2 in idle, none drawn in busy, 1 in sem.
  EXPECT_THAT(dot, HasSubstr("label=\"2\", xlabel=\"robot idle\\nr1, line 1\""));
  EXPECT_THAT(dot, HasSubstr("label=\"\", xlabel=\"robot busy\\nr1, line 2\""));
  EXPECT_THAT(dot, HasSubstr("label=\"1\", xlabel=\"sem\""));  // no name: the id
  // A transition tells the command it begins: name, robot and line, task and motion commands.
  EXPECT_THAT(dot, HasSubstr("label=\"begin pick\\nr1, line 2: Pick A\\n(approach A)\""));
  EXPECT_THAT(dot, HasSubstr("tooltip=\"transition go\""));
  // Arcs, with weights above 1 as labels.
  EXPECT_THAT(dot, HasSubstr("p0 -> t0 [label=\"2\"];"));
  EXPECT_THAT(dot, HasSubstr("p2 -> t0;"));
  EXPECT_THAT(dot, HasSubstr("t0 -> p1;"));
  EXPECT_THAT(dot, HasSubstr("t1 -> p0 [label=\"2\"];"));
  EXPECT_EQ(count(dot, " -> "), 6u);
}

TEST(Dot, DrawsAGivenMarking) {
  DotOptions options;
  options.marking = Marking{0, 1, 0};
  const std::string dot = to_dot(small_net(), options);
  EXPECT_THAT(dot, HasSubstr("label=\"\", xlabel=\"robot idle"));
  EXPECT_THAT(dot, HasSubstr("label=\"1\", xlabel=\"robot busy"));
  options.marking = Marking{1, 2};  // wrong size: a caller's bug
  EXPECT_THROW(to_dot(small_net(), options), InternalError);
  options.marking.reset();
  options.rankdir = "sideways";
  EXPECT_THROW(to_dot(small_net(), options), InternalError);
}

TEST(Dot, ClustersGroupEachRobotsNodes) {
  NetBuilder b("two robots");
  b.add_place(Place{"a", "a", 1, PlaceKind::kStart, Origin{"r1", 1, 1, "", "", -1}});
  b.add_place(Place{"b", "b", 1, PlaceKind::kStart, Origin{"r2", 1, 1, "", "", -1}});
  b.add_place(Place{"ev", "ev", 0, PlaceKind::kEvent, Origin{}});
  Transition t;
  t.id = "t";
  t.inputs = {{0, 1}};
  t.outputs = {{2, 1}};
  t.origin.robot = "r1";
  b.add_transition(t);
  Transition u;
  u.id = "u";
  u.inputs = {{1, 1}, {2, 1}};
  u.origin.robot = "r2";
  b.add_transition(u);
  b.set_robots({"r1", "r2"});
  const Net net = std::move(b).build();

  EXPECT_THAT(to_dot(net), Not(HasSubstr("subgraph")));
  DotOptions options;
  options.cluster_per_robot = true;
  const std::string dot = to_dot(net, options);
  const auto r1 = dot.find("subgraph cluster_0 {");
  const auto r2 = dot.find("subgraph cluster_1 {");
  ASSERT_NE(r1, std::string::npos) << dot;
  ASSERT_NE(r2, std::string::npos) << dot;
  EXPECT_THAT(dot, HasSubstr("label=\"robot r1\""));
  EXPECT_THAT(dot, HasSubstr("label=\"robot r2\""));
  // r1's place and transition sit in the first cluster, r2's in the second, the shared event outside both.
  const auto end_r1 = dot.find("  }\n", r1);
  const auto end_r2 = dot.find("  }\n", r2);
  const auto at = [&](const std::string& node) { return dot.find("    " + node + " ["); };
  EXPECT_GT(at("p0"), r1);
  EXPECT_LT(at("p0"), end_r1);
  EXPECT_GT(at("t0"), r1);
  EXPECT_LT(at("t0"), end_r1);
  EXPECT_GT(at("p1"), r2);
  EXPECT_LT(at("p1"), end_r2);
  EXPECT_GT(at("t1"), r2);
  EXPECT_LT(at("t1"), end_r2);
  EXPECT_EQ(at("p2"), std::string::npos);
  EXPECT_THAT(dot, HasSubstr("\n  p2 ["));
  if (have_dot()) render_svg(dot);
}

// Ids and names with every character that means something to DOT, SVG or a shell.
Net hostile_net() {
  NetBuilder b("net \"quoted\" {braces}; \\");
  b.add_place(Place{"p\"1\\", "name with \"quotes\" and \\backslash\\", 1, PlaceKind::kPlain, Origin{}});
  b.add_place(Place{"p -> 2;", "<b>html</b> & {record|field}\nsecond line", 0, PlaceKind::kRegion, Origin{}});
  b.add_place(Place{"ends with backslash\\", "tab\there \\N \\G \\l", 0, PlaceKind::kDone, Origin{}});
  Transition t;
  t.id = "t\"; digraph x {";
  t.name = "\\";
  t.inputs = {{0, 1}};
  t.outputs = {{1, 3}, {2, 1}};
  t.origin = Origin{"r\"1", 4, 2, "Put \"A\" {x}", "move 'over' \\ there", 1};
  b.add_transition(t);
  return std::move(b).build();
}

TEST(Dot, EscapesTextSoThatGraphvizReadsItBack) {
  const std::string dot = to_dot(hostile_net());
  EXPECT_THAT(dot, HasSubstr("xlabel=\"name with \\\"quotes\\\" and \\\\backslash\\\\\""));
  EXPECT_THAT(dot, HasSubstr("tooltip=\"place p\\\"1\\\\\""));
  EXPECT_THAT(dot, HasSubstr("tab here"));  // control characters become spaces
  if (!have_dot()) GTEST_SKIP() << "Graphviz dot is not on PATH";
  const std::string svg = render_svg(dot);
  // Graphviz decoded the labels to the original text (then XML-escaped it for SVG).
  EXPECT_THAT(svg, HasSubstr("name with &quot;quotes&quot; and \\backslash\\"));
  EXPECT_THAT(svg, HasSubstr("&lt;b&gt;html&lt;/b&gt; &amp; {record|field}"));
  EXPECT_THAT(svg, HasSubstr("second line"));
  EXPECT_THAT(svg, HasSubstr("\\N \\G \\l"));
  EXPECT_THAT(svg, HasSubstr("r&quot;1, line 4: Put &quot;A&quot; {x}"));
  for (const char* node : {"<title>p0</title>", "<title>p1</title>", "<title>p2</title>", "<title>t0</title>"}) {
    EXPECT_THAT(svg, HasSubstr(node));
  }
}

TEST(Dot, CorpusNetsRenderWithGraphviz) {
  if (!have_dot()) GTEST_SKIP() << "Graphviz dot is not on PATH";
  for (const char* file : {"kanban-1.pnml", "philosophers-2.pnml", "producer-consumer.pnml", "epnk-references.pnml"}) {
    SCOPED_TRACE(file);
    const Net net = read_pnml(kData / file);
    DotOptions options;
    options.rankdir = "LR";
    const std::string svg = render_svg(to_dot(net, options));
    for (std::size_t p = 0; p < net.num_places(); ++p) {
      EXPECT_THAT(svg, HasSubstr("<title>p" + std::to_string(p) + "</title>"));
      EXPECT_THAT(svg, HasSubstr(">" + net.places()[p].name + "<"));
    }
    for (std::size_t t = 0; t < net.num_transitions(); ++t) {
      EXPECT_THAT(svg, HasSubstr("<title>t" + std::to_string(t) + "</title>"));
      EXPECT_THAT(svg, HasSubstr(">" + net.transitions()[t].name + "<"));
    }
  }
}

}  // namespace
}  // namespace cellwright::petri
