// Shots in parallel (-shot_groups G): the ranks split into G groups, each running a block of the
// survey's shots on its own copy of the grid. The misfit, the gradient and the recorded traces must
// equal those of the shots run one after another on all ranks (1e-12), for a field and a scalar
// parameter, with 5 shots in blocks of unequal size. On 2 ranks: 2 groups of 1; on 4
// (ctest unit_shot_groups_np4): 2 groups of 2 and 4 groups of 1.
#include "flexipde/scene.hpp"
#include "flexipde/survey.hpp"
#include "test_support.hpp"

using namespace flexipde;
using flexipde_test::rel_diff;
using flexipde_test::ScopedOptions;

namespace {

void survey_options(ScopedOptions &o, bool field) {
  o.set("-model", "wave2d");
  o.set("-da_grid_x", "33");
  o.set("-da_grid_y", "29");
  o.set("-ts_max_time", "0.4");
  o.set("-ts_dt", "4e-3");
  o.set("-wave2d_c_field", field ? "1" : "0");
  o.set("-wave2d_c", "1.0");
  if (field) {
    o.set("-true_wave2d_c_profile", "linear");
    o.set("-true_wave2d_c_left", "0.9");
    o.set("-true_wave2d_c_right", "1.2");
  } else o.set("-true_wave2d_c", "1.1");
  o.set("-objective_type", "receivers");
  o.set("-survey_sources_x", "0.25,0.35,0.45,0.55,0.65");
  o.set("-survey_sources_y", "0.3");
  o.set("-survey_receivers_spread", "0.2,0.8,6");
  o.set("-survey_receivers_y", "0.65");
  o.set("-survey_ricker_f0", "5");
}

} // namespace

TEST(ShotGroups, MatchSequentialShots) {
  PetscMPIInt size;
  MPI_Comm_size(PETSC_COMM_WORLD, &size);
  if (size < 2) GTEST_SKIP() << "shot groups need 2 ranks or more";
  for (bool field : {true, false}) {
    ScopedOptions o;
    survey_options(o, field);
    flexipde_test::SceneProblem seq;
    PETSC_ASSERT_OK(seq.setup(PETSC_COMM_WORLD));
    OwnedVec g_seq;
    PetscReal J_seq;
    PETSC_ASSERT_OK(VecDuplicate(seq.p, g_seq.out()));
    PETSC_ASSERT_OK(seq.scene.gradient(seq.p, &J_seq, g_seq));
    for (PetscMPIInt groups = 2; groups <= size; ++groups) {
      if (size % groups) continue;
      SCOPED_TRACE(std::to_string(groups) + " groups, c " + (field ? "field" : "scalar"));
      ScopedOptions og{{"-shot_groups", std::to_string(groups).c_str()}};
      flexipde_test::SceneProblem grouped;
      PETSC_ASSERT_OK(grouped.setup(PETSC_COMM_WORLD));
      EXPECT_EQ(grouped.scene.shot_groups(), groups);
      OwnedVec g;
      PetscReal J, Jv;
      PETSC_ASSERT_OK(VecDuplicate(grouped.p, g.out()));
      PETSC_ASSERT_OK(grouped.scene.gradient(grouped.p, &J, g));
      PETSC_ASSERT_OK(grouped.scene.value(grouped.p, &Jv));
      EXPECT_GT(J_seq, 0.0);
      EXPECT_LT(rel_diff(J, J_seq), 1e-12);
      EXPECT_LT(rel_diff(Jv, J_seq), 1e-12);
      EXPECT_GT(flexipde_test::norm(g_seq), 0.0);
      EXPECT_LT(rel_diff(g, g_seq), 1e-12) << "gradient of the groups against the shots in sequence";
      // the traces each group recorded, gathered on rank 0
      const std::vector<PetscReal> &a = grouped.scene.objective.survey()->traces(), &b = seq.scene.objective.survey()->traces();
      ASSERT_EQ(a.size(), b.size());
      PetscReal worst = flexipde_test::max_rel_diff(a, b);
      MPI_Allreduce(MPI_IN_PLACE, &worst, 1, MPIU_REAL, MPI_MAX, PETSC_COMM_WORLD);
      EXPECT_LT(worst, 1e-12) << "traces recorded by the groups";
      PetscPrintf(PETSC_COMM_WORLD, "  [%d groups, c %s] J = %.12e (in sequence %.12e), gradient rel diff %.2e\n", groups,
                  field ? "field" : "scalar", (double)J, (double)J_seq, (double)rel_diff(g, g_seq));
    }
  }
}
