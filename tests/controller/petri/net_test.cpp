// Net structure: building, validation with errors that name the element, lookups, final markings.
#include "cellwright/petri/net.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <functional>
#include <stdexcept>

#include "cellwright/common/error.hpp"
#include "controller/petri/test_nets.hpp"

namespace cellwright::petri {
namespace {

using ::testing::HasSubstr;
using testnets::add_place;
using testnets::add_transition;

// A valid two-place net a -> b that each test breaks in one way.
struct Fixture {
  NetBuilder b{"fx"};
  PlaceId a = add_place(b, "a", 1);
  PlaceId p = add_place(b, "b");
  TransitionId t = add_transition(b, "t", {{a, 1}}, {{p, 1}});
};

std::string build_error(NetBuilder& b) {
  try {
    (void)std::move(b).build();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(Net, BuildKeepsElementsInOrderAndFindsThemById) {
  Fixture f;
  f.b.set_final({{f.p, 1}});
  const Net net = std::move(f.b).build();
  EXPECT_EQ(net.name(), "fx");
  ASSERT_EQ(net.num_places(), 2u);
  ASSERT_EQ(net.num_transitions(), 1u);
  EXPECT_EQ(net.places()[1].id, "b");
  EXPECT_EQ(net.find_place("b"), std::optional<PlaceId>(1));
  EXPECT_EQ(net.find_transition("t"), std::optional<TransitionId>(0));
  EXPECT_FALSE(net.find_place("t"));
  EXPECT_FALSE(net.find_transition("a"));
  EXPECT_FALSE(net.find_place(""));
  EXPECT_EQ(net.initial_marking(), (Marking{1, 0}));
}

TEST(Net, BuilderGivesMutableAccessForLateArcs) {
  Fixture f;
  const PlaceId c = add_place(f.b, "c");
  f.b.transition(f.t).outputs.push_back({c, 2});
  f.b.place(c).initial = 4;
  EXPECT_THROW(f.b.transition(7), std::out_of_range);
  EXPECT_THROW(f.b.place(9), std::out_of_range);
  const Net net = std::move(f.b).build();
  EXPECT_EQ(net.transitions()[0].outputs.size(), 2u);
  EXPECT_EQ(net.initial_marking(), (Marking{1, 0, 4}));
}

TEST(Net, RejectsEmptyAndDuplicateIds) {
  {
    Fixture f;
    add_place(f.b, "");
    EXPECT_THAT(build_error(f.b), HasSubstr("place #2 has an empty id"));
  }
  {
    Fixture f;
    add_place(f.b, "a");
    EXPECT_THAT(build_error(f.b), HasSubstr("duplicate place id 'a'"));
  }
  {
    Fixture f;
    add_transition(f.b, "", {}, {});
    EXPECT_THAT(build_error(f.b), HasSubstr("transition #1 has an empty id"));
  }
  {
    Fixture f;
    add_transition(f.b, "t", {}, {});
    EXPECT_THAT(build_error(f.b), HasSubstr("duplicate transition id 't'"));
  }
  {
    Fixture f;
    add_transition(f.b, "a", {}, {});
    EXPECT_THAT(build_error(f.b), HasSubstr("id 'a' is used by both a place and a transition"));
  }
}

TEST(Net, RejectsBadArcs) {
  {
    Fixture f;
    f.b.transition(f.t).inputs.push_back({5, 1});
    EXPECT_THAT(build_error(f.b), HasSubstr("transition 't': input arc to place #5, but the net has 2 places"));
  }
  {
    Fixture f;
    f.b.transition(f.t).outputs.push_back({f.p, 3});
    EXPECT_THAT(build_error(f.b), HasSubstr("transition 't': two output arcs to place 'b'"));
  }
  {
    Fixture f;
    f.b.transition(f.t).inputs[0].weight = 0;
    EXPECT_THAT(build_error(f.b), HasSubstr("transition 't': input arc to place 'a' has weight 0"));
  }
  {
    // A place in both the pre- and the post-set is a self-loop, which is fine.
    Fixture f;
    f.b.transition(f.t).outputs.push_back({f.a, 1});
    EXPECT_NO_THROW((void)std::move(f.b).build());
  }
}

TEST(Net, RejectsBadRegionsRobotsAndFinalPlaces) {
  {
    Fixture f;
    f.b.add_region({"Z", {f.a, 9}, 1});
    EXPECT_THAT(build_error(f.b), HasSubstr("region 'Z' names place #9, but the net has 2 places"));
  }
  {
    Fixture f;
    f.b.add_region({"Z", {f.a, f.a}, 1});
    EXPECT_THAT(build_error(f.b), HasSubstr("region 'Z' names place 'a' twice"));
  }
  {
    Fixture f;
    f.b.add_region({"", {f.a}, 1});
    EXPECT_THAT(build_error(f.b), HasSubstr("a region has an empty name"));
  }
  {
    Fixture f;
    f.b.add_region({"Z", {f.a}, 1});
    f.b.add_region({"Z", {f.p}, 1});
    EXPECT_THAT(build_error(f.b), HasSubstr("duplicate region 'Z'"));
  }
  {
    Fixture f;
    f.b.set_robots({"r1", "r1"});
    EXPECT_THAT(build_error(f.b), HasSubstr("duplicate robot label 'r1'"));
  }
  {
    Fixture f;
    f.b.set_robots({"r1"});
    f.b.transition(f.t).starts_robot = 1;
    EXPECT_THAT(build_error(f.b), HasSubstr("transition 't' starts a command of robot #1, but the net has 1 robots"));
  }
  {
    Fixture f;
    f.b.set_final({{f.p, 0}});
    EXPECT_THAT(build_error(f.b), HasSubstr("final marking needs 0 tokens in place 'b'"));
  }
  {
    Fixture f;
    f.b.set_final({{4, 1}});
    EXPECT_THAT(build_error(f.b), HasSubstr("final marking names place #4"));
  }
}

TEST(Net, ErrorsNameTheNet) {
  Fixture f;
  add_place(f.b, "b");
  EXPECT_THAT(build_error(f.b), HasSubstr("net 'fx': "));
}

TEST(Net, FinalMeansDeadAndCoveringTheFinalPlaces) {
  Fixture f;
  f.b.set_final({{f.p, 1}});
  const Net net = std::move(f.b).build();
  EXPECT_FALSE(net.is_final({1, 0}));  // t is enabled
  EXPECT_TRUE(net.is_final({0, 1}));
  EXPECT_TRUE(net.is_final({0, 3}));   // covers
  EXPECT_FALSE(net.is_final({0, 0}));  // dead, but not at the end
  EXPECT_THROW((void)net.is_final({0}), InternalError);

  Fixture g;
  const Net no_final = std::move(g.b).build();
  EXPECT_FALSE(no_final.is_final({0, 1}));
}

TEST(Net, PlaceKindNames) {
  EXPECT_STREQ(to_string(PlaceKind::kPlain), "plain");
  EXPECT_STREQ(to_string(PlaceKind::kStart), "start");
  EXPECT_STREQ(to_string(PlaceKind::kExecuting), "executing");
  EXPECT_STREQ(to_string(PlaceKind::kWaiting), "waiting");
  EXPECT_STREQ(to_string(PlaceKind::kDone), "done");
  EXPECT_STREQ(to_string(PlaceKind::kEvent), "event");
  EXPECT_STREQ(to_string(PlaceKind::kRegion), "region");
}

}  // namespace
}  // namespace cellwright::petri
