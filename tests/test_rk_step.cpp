// The explicit RK forward step of rk_step.hpp against PETSc's own TSStep_RK, on 1 and 2 ranks: a
// nonlinear ODE system solved by a plain TS with each tableau, once with PETSc's step and once with
// rk_step_install. Rows of A with one nonzero earlier slope (1fe, 2a, 4) give the same numbers as
// PETSc's copy + multi-AXPY; rows with several are summed in another order (1e-14); FSAL tableaux,
// adaptive steps and an interpolated final time are handed to PETSc's step (exactly equal). The final
// time is not a multiple of the step, so the shortened last step is checked too.
#include "flexipde/rk_step.hpp"
#include "test_support.hpp"
#include <cmath>
#include <string>

using namespace flexipde;
using flexipde_test::rel_diff;
using flexipde_test::ScopedOptions;

namespace {

// u_k' = -u_k |u_k| + cos(3 t + k) u_{k+1 mod n on this rank} + 0.1: nonlinear, time-dependent,
// coupled.
PetscErrorCode ode(TS, PetscReal t, Vec U, Vec F, void *) {
  const PetscScalar *u;
  PetscScalar *f;
  PetscInt n, lo;
  PetscFunctionBeginUser;
  PetscCall(VecGetLocalSize(U, &n));
  PetscCall(VecGetOwnershipRange(U, &lo, nullptr));
  PetscCall(VecGetArrayRead(U, &u));
  PetscCall(VecGetArray(F, &f));
  for (PetscInt k = 0; k < n; ++k)
    f[k] = -u[k] * std::fabs(u[k]) + std::cos(3 * t + (PetscReal)(lo + k)) * u[(k + 1) % n] + 0.1;
  PetscCall(VecRestoreArrayRead(U, &u));
  PetscCall(VecRestoreArray(F, &f));
  PetscFunctionReturn(0);
}

struct Solved {
  OwnedVec U;
  PetscReal t = 0;
  PetscInt steps = 0;
};

// The ODE from u_k = sin(k) over [0, 0.37] with dt = 0.05 (the last step 0.02), by TSRK `type`.
PetscErrorCode solve(const char *type, bool ours, Solved *out) {
  TS ts;
  PetscFunctionBeginUser;
  PetscCall(VecCreateMPI(PETSC_COMM_WORLD, 40, PETSC_DETERMINE, out->U.out()));
  PetscInt lo, hi;
  PetscCall(VecGetOwnershipRange(out->U, &lo, &hi));
  for (PetscInt k = lo; k < hi; ++k) PetscCall(VecSetValue(out->U, k, std::sin((PetscReal)k), INSERT_VALUES));
  PetscCall(VecAssemblyBegin(out->U));
  PetscCall(VecAssemblyEnd(out->U));
  PetscCall(TSCreate(PETSC_COMM_WORLD, &ts));
  PetscCall(TSSetProblemType(ts, TS_NONLINEAR));
  PetscCall(TSSetRHSFunction(ts, nullptr, ode, nullptr));
  PetscCall(TSSetType(ts, TSRK));
  PetscCall(TSRKSetType(ts, type));
  PetscCall(TSSetTimeStep(ts, 0.05));
  PetscCall(TSSetMaxTime(ts, 0.37));
  PetscCall(TSSetMaxSteps(ts, 100000));
  PetscCall(TSSetExactFinalTime(ts, TS_EXACTFINALTIME_MATCHSTEP));
  TSAdapt adapt;
  PetscCall(TSGetAdapt(ts, &adapt));
  PetscCall(TSAdaptSetType(adapt, TSADAPTNONE));
  PetscCall(TSSetOptionsPrefix(ts, "rkstep_"));
  PetscCall(TSSetFromOptions(ts));
  if (ours) PetscCall(rk_step_install(ts));
  PetscCall(TSSolve(ts, out->U));
  PetscCall(TSGetTime(ts, &out->t));
  PetscCall(TSGetStepNumber(ts, &out->steps));
  PetscCall(TSDestroy(&ts));
  PetscFunctionReturn(0);
}

struct StepCase {
  const char *type;
  PetscReal tol; // 0: the same numbers; else also not the same (this step ran: it sums in another order)
  std::vector<std::pair<const char *, const char *>> opts;
};

class RkStep : public ::testing::TestWithParam<StepCase> {};

TEST_P(RkStep, EqualsPetscsStep) {
  const StepCase &c = GetParam();
  ScopedOptions opts;
  for (auto &o : c.opts) opts.set(o.first, o.second);
  Solved petsc, ours;
  PETSC_ASSERT_OK(solve(c.type, false, &petsc));
  PETSC_ASSERT_OK(solve(c.type, true, &ours));
  EXPECT_EQ(ours.steps, petsc.steps);
  EXPECT_EQ(ours.t, petsc.t);
  EXPECT_GE(petsc.t, 0.37 - 1e-14);
  PetscReal nrm;
  PETSC_ASSERT_OK(VecNorm(petsc.U, NORM_2, &nrm));
  EXPECT_GT(nrm, 0.5);
  if (c.tol == 0) {
    PETSC_ASSERT_OK(VecAXPY(ours.U, -1.0, petsc.U));
    PETSC_ASSERT_OK(VecNorm(ours.U, NORM_INFINITY, &nrm));
    EXPECT_EQ(nrm, 0.0) << c.type;
  } else {
    const PetscReal d = rel_diff(ours.U, petsc.U);
    EXPECT_LE(d, c.tol) << c.type;
    EXPECT_GT(d, 0.0) << c.type << ": the same rounding as PETSc's step, so rk_step's did not run";
  }
}

INSTANTIATE_TEST_SUITE_P(
    Tableaux, RkStep,
    ::testing::Values(StepCase{"1fe", 0, {}}, StepCase{"2a", 0, {}}, StepCase{"4", 0, {}}, StepCase{"3", 1e-14, {}},
                      StepCase{"5f", 1e-14, {}}, // rows of up to five slopes (more than three: copy + multi-AXPY)
                      StepCase{"3bs", 0, {}},    // FSAL: PETSc's step
                      StepCase{"5f", 0, {{"-rkstep_ts_adapt_type", "basic"}}}, // adaptive: PETSc's step
                      StepCase{"4", 0, {{"-rkstep_ts_exact_final_time", "interpolate"}}}),
    [](const ::testing::TestParamInfo<StepCase> &i) {
      std::string n = std::string("rk") + i.param.type + (i.param.opts.empty() ? "" : "_petsc_path");
      return n + "_" + std::to_string(i.index);
    });

} // namespace
