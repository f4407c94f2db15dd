// ContactPairs (twin/sim/contact_pairs.hpp): a step with the pairs it selects is MuJoCo's mj_step in its dynamic
// collision mode, bit for bit, while arms sweep through the cell, parts fall and tumble, and a part's collision masks
// are cleared and restored as RestingParts does; and it tests far fewer pairs than the broadphase.
#include "cellwright/twin/sim/contact_pairs.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <memory>
#include <random>

#include "cellwright/twin/scene.hpp"
#include "twin/mujoco_fixture.hpp"
#include "twin/sim/sim_helpers.hpp"

namespace cellwright::twin::sim {
namespace {

using Model = std::unique_ptr<mjModel, void (*)(mjModel*)>;
using Data = std::unique_ptr<mjData, void (*)(mjData*)>;

class ContactPairsTest : public cellwright::testing::MujocoTest {
 protected:
  ContactPairsTest() : scene_(build_scene(testing::paper_cell())) {}

  Model copy() const { return Model(mj_copyModel(nullptr, scene_.model()), mj_deleteModel); }
  Data data(const mjModel* m) const {
    Data d(mj_makeData(m), mj_deleteData);
    mj_copyData(d.get(), m, scene_.data());
    return d;
  }

  Scene scene_;
};

// Equal to the last bit: the same bytes.
template <typename T>
bool same(const T* a, const T* b, int n) {
  return std::memcmp(a, b, sizeof(T) * static_cast<std::size_t>(n)) == 0;
}

TEST_F(ContactPairsTest, StepsExactlyAsMujocoWithItsBroadphase) {
  Model dynamic = copy();
  Model paired = copy();
  ContactPairs pairs(paired.get());
  Data a = data(dynamic.get());
  Data b = data(paired.get());
  const mjModel* m = dynamic.get();
  ASSERT_GT(m->nu, 0);

  // Every actuator (the arms' servos, the fingers, the belts) gets a random target within its control range, held
  // for a random while: the arms swing through the parts, the conveyors and each other.
  std::mt19937 random(20261128);
  std::uniform_int_distribution<int> hold(20, 200);
  // One part's masks cleared for a while and restored (RestingParts's sleep), in both models alike.
  const int part = scene_.workpieces().front().geom;
  const int contype = m->geom_contype[part], conaffinity = m->geom_conaffinity[part];
  int next_change = 0;
  std::size_t pairs_kept = 0;
  int most_contacts = 0;
  constexpr int kSteps = 3000;
  for (int step = 0; step < kSteps; ++step) {
    if (step == next_change) {
      for (int u = 0; u < m->nu; ++u) {
        const double lo = m->actuator_ctrllimited[u] ? m->actuator_ctrlrange[2 * u] : -1.0;
        const double hi = m->actuator_ctrllimited[u] ? m->actuator_ctrlrange[2 * u + 1] : 1.0;
        a->ctrl[u] = b->ctrl[u] = std::uniform_real_distribution<double>(lo, hi)(random);
      }
      next_change += hold(random);
    }
    if (step == kSteps / 3 || step == 2 * kSteps / 3) {
      const bool asleep = step == kSteps / 3;
      for (mjModel* model : {dynamic.get(), paired.get()}) {
        model->geom_contype[part] = asleep ? 0 : contype;
        model->geom_conaffinity[part] = asleep ? 0 : conaffinity;
      }
    }
    mj_step(dynamic.get(), a.get());
    pairs.step(b.get());
    pairs_kept += static_cast<std::size_t>(pairs.selected());
    most_contacts = std::max(most_contacts, a->ncon);
    ASSERT_EQ(a->ncon, b->ncon) << "step " << step;
    for (int c = 0; c < a->ncon; ++c) {
      const mjContact& x = a->contact[c];
      const mjContact& y = b->contact[c];
      ASSERT_EQ(x.geom1, y.geom1) << "step " << step << " contact " << c;
      ASSERT_EQ(x.geom2, y.geom2) << "step " << step << " contact " << c;
      ASSERT_EQ(x.dim, y.dim) << "step " << step << " contact " << c;
      ASSERT_TRUE(same(x.pos, y.pos, 3) && same(x.frame, y.frame, 9) && same(&x.dist, &y.dist, 1))
          << "step " << step << " contact " << c;
      ASSERT_TRUE(same(x.friction, y.friction, 5) && same(x.solref, y.solref, mjNREF) &&
                  same(x.solimp, y.solimp, mjNIMP) && same(&x.includemargin, &y.includemargin, 1))
          << "step " << step << " contact " << c;
    }
    ASSERT_TRUE(same(a->qpos, b->qpos, m->nq) && same(a->qvel, b->qvel, m->nv)) << "step " << step;
  }
  expect_no_data_warnings(a.get());
  expect_no_data_warnings(b.get());
  // The run made contacts, and the selection tested a fraction of what can ever touch.
  EXPECT_GT(most_contacts, 4);
  EXPECT_LT(static_cast<double>(pairs_kept) / kSteps, 0.5 * static_cast<double>(pairs.listed()));
}

TEST_F(ContactPairsTest, ListsOnlyPairsMujocoWouldTest) {
  Model paired = copy();
  ContactPairs pairs(paired.get());
  const mjModel* m = paired.get();
  ASSERT_GT(pairs.listed(), 0u);
  pairs.select_all();
  ASSERT_EQ(static_cast<std::size_t>(m->npair), pairs.listed());
  EXPECT_EQ(m->opt.collision, mjCOL_PAIR);
  for (int p = 0; p < m->npair; ++p) {
    const int g1 = m->pair_geom1[p], g2 = m->pair_geom2[p];
    const int b1 = m->geom_bodyid[g1], b2 = m->geom_bodyid[g2];
    EXPECT_LT(b1, b2);
    EXPECT_NE(m->body_weldid[b1], m->body_weldid[b2]) << "pair " << p << " is welded together";
    EXPECT_TRUE((m->geom_contype[g1] & m->geom_conaffinity[g2]) || (m->geom_contype[g2] & m->geom_conaffinity[g1]));
    for (int e = 0; e < m->nexclude; ++e) EXPECT_NE(m->exclude_signature[e], m->pair_signature[p]);
    // In mj_collision's order: by body signature, then geom.
    if (p > 0) {
      const bool ordered = m->pair_signature[p - 1] < m->pair_signature[p] ||
                           (m->pair_signature[p - 1] == m->pair_signature[p] &&
                            (m->pair_geom1[p - 1] < g1 || (m->pair_geom1[p - 1] == g1 && m->pair_geom2[p - 1] < g2)));
      EXPECT_TRUE(ordered) << "pair " << p;
    }
  }
}

}  // namespace
}  // namespace cellwright::twin::sim
