// Binomial checkpointing (-checkpoint_budget): the schedule's recomputation count equals the
// revolve optimum t(n, s) = r n - beta(s+1, r-1) (itself checked against a brute-force dynamic
// programme), and a gradient computed within a budget equals the full-storage gradient to 1e-12
// for every integrator with an adjoint here, for field and scalar parameters and for dJ/dU0.
#include "flexipde/checkpoint.hpp"
#include "flexipde/scene.hpp"
#include "test_support.hpp"
#include <cmath>
#include <petsc/private/tsimpl.h> // TSTrajectory counters
#include <string>

using namespace flexipde;
using flexipde_test::QuietErrors;
using flexipde_test::rel_diff;
using flexipde_test::ScopedOptions;

namespace {

// t(l, c) by its defining recursion: reverse l steps with c checkpoints, one of them holding the
// start. Either advance l-1 steps unstored (c = 1), or advance m, store, reverse the right part
// with c-1 checkpoints, then the left part with c.
std::vector<std::vector<PetscInt64>> brute_force(PetscInt64 lmax, PetscInt64 cmax) {
  std::vector<std::vector<PetscInt64>> t(lmax + 1, std::vector<PetscInt64>(cmax + 1, 0));
  for (PetscInt64 l = 2; l <= lmax; ++l) {
    t[l][1] = (l - 1) + t[l - 1][1];
    for (PetscInt64 c = 2; c <= cmax; ++c) {
      PetscInt64 best = -1;
      for (PetscInt64 m = 1; m < l; ++m) {
        const PetscInt64 cost = m + t[l - m][c - 1] + t[m][c];
        if (best < 0 || cost < best) best = cost;
      }
      t[l][c] = best;
    }
  }
  return t;
}

// Runs a schedule without PETSc: the forward sweep, then the plans for k = n-1 .. 1, checking that
// every plan starts from a stored state before k, ends with the step k-1 -> k, and never holds
// more than the budget. Returns the recomputed steps (-1 on an inconsistency).
PetscInt64 simulate(PetscInt n, PetscInt s, PetscInt *peak) {
  BinomialSchedule sch;
  sch.reset(n, s);
  std::vector<PetscInt> stored;
  for (PetscInt step = 0; step <= n; ++step)
    if (sch.store_in_forward(step)) stored.push_back(step);
  if (sch.held() > s) return -1;
  PetscInt64 total = 0;
  std::vector<BinomialSchedule::Action> plan;
  for (PetscInt k = n - 1; k >= 1; --k) {
    if (sch.reverse(k, plan)) return -1;
    if (plan.empty() || plan.front().op != BinomialSchedule::Op::Restore || plan.front().step > k - 1) return -1;
    PetscInt at = plan.front().step;
    bool taped = false;
    for (auto &a : plan) {
      if (a.op == BinomialSchedule::Op::Advance && a.step <= at) return -1;
      if (a.op == BinomialSchedule::Op::Advance || a.op == BinomialSchedule::Op::Tape) at = a.step;
      if (a.op == BinomialSchedule::Op::Store && a.step != at) return -1;
      if (a.op == BinomialSchedule::Op::Tape) taped = (a.step == k);
    }
    if (!taped || at != k || sch.held() > s) return -1;
    total += BinomialSchedule::steps_in(plan, 0);
  }
  if (sch.held() != 0) return -1; // everything released at the end
  *peak = sch.peak();
  return total;
}

} // namespace

TEST(BinomialFormula, ClosedFormEqualsBruteForce) {
  const PetscInt64 lmax = 120, cmax = 8;
  auto t = brute_force(lmax, cmax);
  for (PetscInt64 c = 1; c <= cmax; ++c)
    for (PetscInt64 l = 1; l <= lmax; ++l)
      ASSERT_EQ(binomial_optimal_recomputations(l, c), t[l][c]) << "n = " << l << ", s = " << c;
  // Known values: one checkpoint re-runs n(n-1)/2 steps, enough of them n-1.
  EXPECT_EQ(binomial_optimal_recomputations(1000, 1), 1000 * 999 / 2);
  EXPECT_EQ(binomial_optimal_recomputations(1000, 999), 999);
  EXPECT_EQ(binomial_optimal_recomputations(1000, 5000), 999);
  EXPECT_EQ(binomial_beta(10, 5), 3003);
  EXPECT_EQ(binomial_repetitions(3003, 10), 5);
  EXPECT_EQ(binomial_repetitions(3004, 10), 6);
}

TEST(BinomialSchedule, RecomputationsEqualOptimum) {
  const std::vector<std::pair<PetscInt, PetscInt>> cases = {
      {1, 1},      {2, 1},      {2, 5},       {3, 2},        {10, 1},    {10, 3},     {55, 3},
      {56, 3},     {100, 5},    {300, 10},    {1000, 10},    {1000, 30}, {1000, 100}, {3000, 100},
      {10000, 10}, {10000, 30}, {100000, 10}, {100000, 100}, {40, 400}};
  for (auto [n, s] : cases) {
    PetscInt peak = 0;
    const PetscInt64 got = simulate(n, s, &peak), opt = binomial_optimal_recomputations(n, s);
    EXPECT_EQ(got, opt) << "n = " << n << ", s = " << s;
    EXPECT_LE(peak, s);
    if (n >= 2) EXPECT_GE(peak, 1);
  }
  // Every small case, against the brute force as well.
  auto t = brute_force(60, 6);
  for (PetscInt s = 1; s <= 6; ++s)
    for (PetscInt n = 1; n <= 60; ++n) {
      PetscInt peak = 0;
      ASSERT_EQ(simulate(n, s, &peak), t[n][s]) << "n = " << n << ", s = " << s;
    }
}

namespace {

struct Result {
  PetscReal J = 0;
  OwnedVec g, gu0;
  CheckpointStats stats;
};

// J, dJ/dp and dJ/dU0 of the scene under `extra` options (a fresh scene each time).
PetscErrorCode run_gradient(const std::vector<std::pair<std::string, std::string>> &extra, Result &r) {
  ScopedOptions opts;
  for (auto &o : extra) opts.set(o.first, o.second);
  Scene scene;
  OwnedVec p, p_true;
  PetscFunctionBeginUser;
  PetscCall(scene.setup(PETSC_COMM_WORLD));
  PetscCall(scene.params.create_vec(p.out()));
  PetscCall(scene.params.create_vec(p_true.out()));
  PetscCall(scene.parameters_from_options("", p));
  PetscCall(scene.parameters_from_options("true_", p_true));
  PetscCall(scene.make_synthetic_data(p_true));
  PetscCall(VecDuplicate(p, r.g.out()));
  PetscCall(scene.sim.create_state(r.gu0.out()));
  PetscCall(scene.sim.gradient(p, &r.J, r.g, r.gu0));
  r.stats = scene.sim.checkpoint_stats();
  PetscFunctionReturn(0);
}

struct IntegratorCase {
  const char *name;
  std::vector<std::pair<std::string, std::string>> options;
};

std::ostream &operator<<(std::ostream &os, const IntegratorCase &c) { return os << c.name; }

class CheckpointGradient : public ::testing::TestWithParam<IntegratorCase> {};

} // namespace

// For each integrator: full storage against budgets 1, 4 and 13 (n = 60 or 24 steps), field
// parameters and dJ/dU0. The budgets force re-run steps far beyond full storage's n-1.
TEST_P(CheckpointGradient, EqualsFullStorage) {
  const IntegratorCase &ic = GetParam();
  std::vector<std::pair<std::string, std::string>> base = {{"-da_grid_x", "61"},
                                                           {"-ts_max_time", "0.12"},
                                                           {"-wave_c_field", "1"},
                                                           {"-wave_c", "0.9"},
                                                           {"-true_wave_c_profile", "gaussian"},
                                                           {"-true_wave_c_bump", "0.1"},
                                                           {"-true_wave_c", "1.0"}};
  for (auto &o : ic.options) base.push_back(o);
  Result full;
  PETSC_ASSERT_OK(run_gradient(base, full));
  const PetscInt n = full.stats.steps;
  ASSERT_GE(n, 20);
  EXPECT_EQ(full.stats.budget, 0);
  EXPECT_GT(flexipde_test::norm(full.g), 0.0);
  EXPECT_GT(flexipde_test::norm(full.gu0), 0.0);
  for (const char *budget : {"1", "4", "13"}) {
    auto opts = base;
    opts.push_back({"-checkpoint_budget", budget});
    Result cp;
    PETSC_ASSERT_OK(run_gradient(opts, cp));
    const PetscInt s = std::stoi(budget);
    const PetscReal dJ = rel_diff(cp.J, full.J), dg = rel_diff(cp.g, full.g), du = rel_diff(cp.gu0, full.gu0);
    PetscPrintf(
        PETSC_COMM_WORLD,
        "  [%s, n = %d, budget %d] held %d, recomputed %lld (optimum %lld); rel diff J %.1e, dJ/dp %.1e, dJ/dU0 %.1e\n",
        ic.name, (int)n, (int)s, (int)cp.stats.stored_peak, (long long)cp.stats.recomputed_steps,
        (long long)cp.stats.optimal_recomputations, (double)dJ, (double)dg, (double)du);
    EXPECT_EQ(cp.J, full.J); // the forward solve does not depend on the trajectory
    EXPECT_LE(dg, 1e-12) << "budget " << budget;
    EXPECT_LE(du, 1e-12) << "budget " << budget;
    EXPECT_EQ(cp.stats.budget, s);
    EXPECT_EQ(cp.stats.steps, n);
    EXPECT_LE(cp.stats.stored_peak, s);
    EXPECT_EQ(cp.stats.stored_peak, std::min<PetscInt>(s, n - 1));
    EXPECT_EQ(cp.stats.recomputed_steps, binomial_optimal_recomputations(n, s));
    EXPECT_GT(cp.stats.recomputed_steps, (PetscInt64)n - 1);
  }
}

INSTANTIATE_TEST_SUITE_P(
    Wave, CheckpointGradient,
    ::testing::Values(
        IntegratorCase{"rk4", {{"-ts_type", "rk"}, {"-ts_rk_type", "4"}, {"-ts_dt", "2e-3"}}},
        IntegratorCase{"rk3bs_fsal", {{"-ts_type", "rk"}, {"-ts_rk_type", "3bs"}, {"-ts_dt", "2e-3"}}},
        IntegratorCase{"rk2a_2_stages", {{"-ts_type", "rk"}, {"-ts_rk_type", "2a"}, {"-ts_dt", "2e-3"}, {"-sim_stability_check", "0"}}},
        IntegratorCase{"rk3", {{"-ts_type", "rk"}, {"-ts_rk_type", "3"}, {"-ts_dt", "2e-3"}}},
        IntegratorCase{"rk1fe_1_stage", {{"-ts_type", "rk"}, {"-ts_rk_type", "1fe"}, {"-ts_dt", "2e-3"}, {"-sim_stability_check", "0"}}},
        IntegratorCase{"theta0.7", {{"-ts_type", "theta"}, {"-ts_theta_theta", "0.7"}, {"-ts_dt", "5e-3"}}},
        IntegratorCase{"cn", {{"-ts_type", "cn"}, {"-ts_dt", "5e-3"}}},
        IntegratorCase{"beuler", {{"-ts_type", "beuler"}, {"-ts_dt", "5e-3"}}}),
    [](const ::testing::TestParamInfo<IntegratorCase> &i) {
      std::string s = i.param.name;
      for (auto &ch : s)
        if (!isalnum((unsigned char)ch)) ch = '_';
      return s;
    });

// A scalar parameter (dG/dp a dense column), and the smallest step counts (1 and 2 steps).
TEST(CheckpointGradient, ScalarParameterAndShortRuns) {
  for (const char *T : {"0.002", "0.004", "0.2"}) {
    std::vector<std::pair<std::string, std::string>> base = {
        {"-da_grid_x", "81"}, {"-ts_max_time", T}, {"-ts_dt", "2e-3"}, {"-wave_c", "0.9"}, {"-true_wave_c", "1.0"}};
    Result full, solution_only, cp;
    PETSC_ASSERT_OK(run_gradient(base, full));
    auto base_solution_only = base;
    base_solution_only.push_back({"-checkpoint_keep_stages_max_mb", "0"}); // no room for the stages
    PETSC_ASSERT_OK(run_gradient(base_solution_only, solution_only));
    base.push_back({"-checkpoint_budget", "3"});
    PETSC_ASSERT_OK(run_gradient(base, cp));
    const PetscInt n = full.stats.steps;
    EXPECT_LE(rel_diff(cp.g, full.g), 1e-12) << "T = " << T;
    EXPECT_LE(rel_diff(cp.gu0, full.gu0), 1e-12) << "T = " << T;
    EXPECT_LE(rel_diff(solution_only.g, full.g), 1e-12) << "T = " << T;
    EXPECT_LE(rel_diff(solution_only.gu0, full.gu0), 1e-12) << "T = " << T;
    EXPECT_GT(flexipde_test::norm(full.g), 0.0);
    EXPECT_EQ(cp.stats.recomputed_steps, binomial_optimal_recomputations(n, 3));
    // Full storage keeps n states; with the stages (the default at this size) it re-runs nothing,
    // with the solution only (no room for the stages: -checkpoint_keep_stages_max_mb 0) every step but
    // the last once.
    EXPECT_EQ(full.stats.recomputed_steps, 0);
    EXPECT_EQ(full.stats.stored_peak, n);
    EXPECT_EQ(solution_only.stats.recomputed_steps, (PetscInt64)n - 1);
    EXPECT_EQ(solution_only.stats.stored_peak, n);
  }
}

// Full storage with an FSAL method (3bs) keeps the stages: PETSc's solution-only memory trajectory
// would re-run steps without restarting the FSAL derivative (3e-5 relative error here). The
// gradient agrees with central differences, with and without a budget.
TEST(CheckpointGradient, FsalMatchesFiniteDifferences) {
  const std::vector<std::pair<std::string, std::string>> base = {
      {"-da_grid_x", "201"}, {"-ts_max_time", "0.3"}, {"-ts_dt", "1e-3"},         {"-ts_rk_type", "3bs"},
      {"-wave_c", "0.9"},    {"-true_wave_c", "1.0"}, {"-objective_type", "l2sq"}};
  const PetscReal c = 0.9, h = 1e-6;
  auto J_at = [&](PetscReal cc, const char *budget, Result &r) {
    auto opts = base;
    opts.push_back({"-wave_c", std::to_string(cc)});
    if (budget) opts.push_back({"-checkpoint_budget", budget});
    return run_gradient(opts, r);
  };
  Result plus, minus;
  PETSC_ASSERT_OK(J_at(c + h, nullptr, plus));
  PETSC_ASSERT_OK(J_at(c - h, nullptr, minus));
  const PetscReal fd = (plus.J - minus.J) / (2 * h);
  for (const char *budget : {(const char *)nullptr, "7"}) {
    Result r;
    PETSC_ASSERT_OK(J_at(c, budget, r));
    std::vector<PetscReal> g;
    PETSC_ASSERT_OK(flexipde_test::gather_all(r.g, g));
    ASSERT_EQ(g.size(), 1u);
    PetscPrintf(PETSC_COMM_WORLD, "  [3bs, budget %s] adjoint %.12e, central difference %.12e, rel diff %.1e\n",
                budget ? budget : "full", (double)g[0], (double)fd, (double)rel_diff(g[0], fd));
    EXPECT_LE(rel_diff(g[0], fd), 1e-8) << (budget ? budget : "full storage");
  }
}

// -checkpoint_memory: the binomial budget is the number of states that fit per rank (the rank holding
// the most decides), the gradient equals full storage's, and a memory that holds every state gives
// full storage itself. Sizes are parsed with their units; bad sizes and both bounds at once are refused.
TEST(CheckpointGradient, MemoryBudget) {
  EXPECT_EQ(parse_memory_size("4GB"), 4.0 * 1024 * 1024 * 1024);
  EXPECT_EQ(parse_memory_size("512mb"), 512.0 * 1024 * 1024);
  EXPECT_EQ(parse_memory_size("1.5k"), 1536.0);
  EXPECT_EQ(parse_memory_size("1000"), 1000.0);
  for (const char *bad : {"", "GB", "4XB", "-1MB", "0", "4 GBs"}) EXPECT_LT(parse_memory_size(bad), 0) << bad;
  for (const char *ts : {"leapfrog", "rk"}) {
    std::vector<std::pair<std::string, std::string>> base = {{"-da_grid_x", "61"},       {"-ts_max_time", "0.12"},
                                                             {"-ts_dt", "2e-3"},         {"-ts_type", ts},
                                                             {"-wave_c_field", "1"},     {"-wave_c", "0.9"},
                                                             {"-true_wave_c", "1.0"},    {"-true_wave_c_profile", "gaussian"},
                                                             {"-true_wave_c_bump", "0.1"}};
    Result full;
    PETSC_ASSERT_OK(run_gradient(base, full));
    ASSERT_EQ(full.stats.budget, 0);
    // one state: (u, v) at every point of the rank that holds the most
    PetscInt n = (61 + 1) / 2;
    PetscMPIInt size;
    MPI_Comm_size(PETSC_COMM_WORLD, &size);
    if (size == 1) n = 61;
    const PetscReal state = 2.0 * n * sizeof(PetscScalar);
    for (const char *memory : {"10kB", "1GB"}) {
      auto opts = base;
      opts.push_back({"-checkpoint_memory", memory});
      Result cp;
      PETSC_ASSERT_OK(run_gradient(opts, cp));
      const PetscReal fit = std::floor(parse_memory_size(memory) / state);
      const PetscInt expected = fit >= full.stats.steps + 1 ? 0 : (PetscInt)fit;
      PetscPrintf(PETSC_COMM_WORLD, "  [%s, %s] state %.0f B, budget %d, recomputed %lld; rel diff dJ/dp %.1e\n", ts, memory,
                  (double)state, (int)cp.stats.budget, (long long)cp.stats.recomputed_steps, (double)rel_diff(cp.g, full.g));
      EXPECT_EQ(cp.stats.budget, expected) << memory;
      EXPECT_NEAR(cp.stats.state_mb * 1048576.0, state, 1e-6);
      EXPECT_EQ(cp.J, full.J);
      EXPECT_LE(rel_diff(cp.g, full.g), 1e-12) << memory;
      if (expected > 0) EXPECT_EQ(cp.stats.recomputed_steps, binomial_optimal_recomputations(full.stats.steps, expected));
    }
    Result r;
    for (auto extra : std::vector<std::vector<std::pair<std::string, std::string>>>{
             {{"-checkpoint_memory", "4XB"}},
             {{"-checkpoint_memory", "100B"}}, // less than one state
             {{"-checkpoint_memory", "1GB"}, {"-checkpoint_budget", "4"}}}) {
      auto opts = base;
      for (auto &o : extra) opts.push_back(o);
      PetscErrorCode ierr;
      {
        flexipde_test::QuietErrors q;
        ierr = run_gradient(opts, r);
      }
      EXPECT_NE(ierr, 0) << extra[0].second;
    }
  }
}

// -checkpoint_precision single: the states kept as floats. The gradient differs from the double one by
// the states' rounding (not 0, below 1e-5 relative), J not at all (the forward solve is the same), and
// the trajectory takes half the memory of the double states (the leapfrog's positions) or less (RK4 and
// CN, whose double storage also keeps stages or records); refused with the binomial schedule.
TEST(CheckpointGradient, SinglePrecision) {
  for (const char *ts : {"leapfrog", "rk", "cn"}) {
    std::vector<std::pair<std::string, std::string>> base = {{"-da_grid_x", "61"},       {"-ts_max_time", "0.12"},
                                                             {"-ts_dt", "2e-3"},         {"-ts_type", ts},
                                                             {"-wave_c_field", "1"},     {"-wave_c", "0.9"},
                                                             {"-true_wave_c", "1.0"},    {"-true_wave_c_profile", "gaussian"},
                                                             {"-true_wave_c_bump", "0.1"}};
    Result full, single;
    PETSC_ASSERT_OK(run_gradient(base, full));
    auto opts = base;
    opts.push_back({"-checkpoint_precision", "single"});
    PETSC_ASSERT_OK(run_gradient(opts, single));
    const PetscReal d = rel_diff(single.g, full.g);
    PetscPrintf(PETSC_COMM_WORLD, "  [%s] single-precision states: rel diff dJ/dp %.1e, trajectory %.3f MB against %.3f MB\n", ts,
                (double)d, (double)single.stats.stored_mb, (double)full.stats.stored_mb);
    EXPECT_EQ(single.J, full.J);
    EXPECT_GT(d, 0.0);
    EXPECT_LT(d, 1e-5); // measured 5.5e-7 to 7.4e-7 (largest entry's difference over the largest entry)
    EXPECT_GT(single.stats.stored_mb, 0.0);
    EXPECT_LE(single.stats.stored_mb, 0.51 * full.stats.stored_mb + 1e-3);
    opts.push_back({"-checkpoint_budget", "4"});
    PetscErrorCode ierr;
    {
      flexipde_test::QuietErrors q;
      ierr = run_gradient(opts, single);
    }
    EXPECT_NE(ierr, 0) << "single precision with the binomial schedule";
  }
}

// Repeated evaluations on one Simulation (as TAO does) give identical results and statistics.
TEST(CheckpointGradient, RepeatedEvaluations) {
  ScopedOptions opts{{"-da_grid_x", "81"}, {"-ts_max_time", "0.1"}, {"-ts_dt", "2e-3"},         {"-wave_c_field", "1"},
                     {"-wave_c", "0.9"},   {"-true_wave_c", "1.0"}, {"-checkpoint_budget", "5"}};
  Scene scene;
  OwnedVec p, p_true, g1, g2;
  PETSC_ASSERT_OK(scene.setup(PETSC_COMM_WORLD));
  PETSC_ASSERT_OK(scene.params.create_vec(p.out()));
  PETSC_ASSERT_OK(scene.params.create_vec(p_true.out()));
  PETSC_ASSERT_OK(scene.parameters_from_options("", p));
  PETSC_ASSERT_OK(scene.parameters_from_options("true_", p_true));
  PETSC_ASSERT_OK(scene.make_synthetic_data(p_true));
  PETSC_ASSERT_OK(VecDuplicate(p, g1.out()));
  PETSC_ASSERT_OK(VecDuplicate(p, g2.out()));
  PetscReal J1, J2;
  PETSC_ASSERT_OK(scene.sim.gradient(p, &J1, g1, nullptr));
  const CheckpointStats first = scene.sim.checkpoint_stats();
  PETSC_ASSERT_OK(scene.sim.gradient(p, &J2, g2, nullptr));
  const CheckpointStats &second = scene.sim.checkpoint_stats();
  EXPECT_EQ(J1, J2);
  EXPECT_EQ(rel_diff(g1, g2), 0.0);
  EXPECT_EQ(first.recomputed_steps, second.recomputed_steps);
  EXPECT_EQ(first.stores, second.stores);
  EXPECT_EQ(second.recomputed_steps, binomial_optimal_recomputations(50, 5));
}

namespace {

// Plain PETSc use of the trajectory type: u' = A u (a damped oscillator, 2 unknowns, on
// PETSC_COMM_SELF), RK 3bs (FSAL), 50 steps; lambda(0) for lambda(T) = (1, 0) after two
// forward/adjoint cycles on the same TS. Returns lambda(0) and the re-run steps of each cycle.
PetscErrorCode oscillator_adjoint(const char *type, PetscInt budget, std::vector<PetscReal> &lam0,
                                  std::vector<PetscInt> &recomps) {
  TS ts;
  Mat A;
  Vec u, lambda;
  TSTrajectory tj;
  const PetscInt n = 50;
  const PetscReal dt = 0.02;
  PetscFunctionBeginUser;
  PetscCall(MatCreateSeqDense(PETSC_COMM_SELF, 2, 2, nullptr, &A));
  PetscCall(MatSetValue(A, 0, 1, 1.0, INSERT_VALUES));
  PetscCall(MatSetValue(A, 1, 0, -4.0, INSERT_VALUES));
  PetscCall(MatSetValue(A, 1, 1, -0.1, INSERT_VALUES));
  PetscCall(MatAssemblyBegin(A, MAT_FINAL_ASSEMBLY));
  PetscCall(MatAssemblyEnd(A, MAT_FINAL_ASSEMBLY));
  PetscCall(MatCreateVecs(A, &u, &lambda));
  PetscCall(TSCreate(PETSC_COMM_SELF, &ts));
  PetscCall(TSSetProblemType(ts, TS_LINEAR));
  PetscCall(TSSetRHSFunction(ts, nullptr, TSComputeRHSFunctionLinear, nullptr));
  PetscCall(TSSetRHSJacobian(ts, A, A, TSComputeRHSJacobianConstant, nullptr));
  PetscCall(TSSetType(ts, TSRK));
  PetscCall(TSRKSetType(ts, TSRK3BS));
  PetscCall(TSSetMaxSteps(ts, n));
  PetscCall(TSSetMaxTime(ts, 10.0));
  PetscCall(TSSetExactFinalTime(ts, TS_EXACTFINALTIME_MATCHSTEP));
  {
    TSAdapt adapt;
    PetscCall(TSGetAdapt(ts, &adapt));
    PetscCall(TSAdaptSetType(adapt, TSADAPTNONE));
  }
  PetscCall(TSSetSaveTrajectory(ts));
  PetscCall(TSGetTrajectory(ts, &tj));
  PetscCall(register_binomial_trajectory());
  PetscCall(TSTrajectorySetType(tj, ts, type));
  PetscCall(TSTrajectorySetSolutionOnly(tj, PETSC_FALSE)); // memory: keep the stages (FSAL-safe)
  if (budget > 0) PetscCall(binomial_trajectory_set_budget(tj, budget));
  lam0.clear();
  recomps.clear();
  for (int cycle = 0; cycle < 2; ++cycle) {
    PetscCall(TSSetTime(ts, 0.0));
    PetscCall(TSSetStepNumber(ts, 0));
    PetscCall(TSSetTimeStep(ts, dt));
    PetscCall(VecSetValue(u, 0, 1.0, INSERT_VALUES));
    PetscCall(VecSetValue(u, 1, 0.5, INSERT_VALUES));
    PetscCall(VecAssemblyBegin(u));
    PetscCall(VecAssemblyEnd(u));
    PetscCall(TSSolve(ts, u));
    PetscCall(VecSet(lambda, 0.0));
    PetscCall(VecSetValue(lambda, 0, 1.0, INSERT_VALUES));
    PetscCall(VecAssemblyBegin(lambda));
    PetscCall(VecAssemblyEnd(lambda));
    PetscCall(TSSetCostGradients(ts, 1, &lambda, nullptr));
    PetscCall(TSAdjointSolve(ts));
    const PetscScalar *l;
    PetscCall(VecGetArrayRead(lambda, &l));
    lam0.push_back(PetscRealPart(l[0]));
    lam0.push_back(PetscRealPart(l[1]));
    PetscCall(VecRestoreArrayRead(lambda, &l));
    recomps.push_back(tj->recomps);
  }
  PetscCall(TSDestroy(&ts));
  PetscCall(VecDestroy(&u));
  PetscCall(VecDestroy(&lambda));
  PetscCall(MatDestroy(&A));
  PetscFunctionReturn(0);
}

} // namespace

TEST(BinomialTrajectory, PlainTSRepeatedSolves) {
  std::vector<PetscReal> ref, got;
  std::vector<PetscInt> ref_re, got_re;
  PETSC_ASSERT_OK(oscillator_adjoint(TSTRAJECTORYMEMORY, 0, ref, ref_re));
  PETSC_ASSERT_OK(oscillator_adjoint(FLEXIPDE_TSTRAJECTORY_BINOMIAL, 4, got, got_re));
  ASSERT_EQ(ref.size(), 4u);
  ASSERT_EQ(got.size(), 4u);
  EXPECT_GT(std::fabs(ref[0]) + std::fabs(ref[1]), 0.1);
  for (size_t i = 0; i < 4; ++i) EXPECT_LE(std::fabs(got[i] - ref[i]), 1e-13 * std::fabs(ref[i & 1u])) << i;
  EXPECT_EQ(ref_re[0], 0); // stages stored: nothing re-run
  EXPECT_EQ(got_re[0], binomial_optimal_recomputations(50, 4));
  EXPECT_EQ(got_re[1], got_re[0]); // the second cycle planned and ran the same schedule
}

// A budget that is not a positive number of states, or adaptive steps with a budget, are refused.
TEST(CheckpointErrors, BadBudgetAndAdaptiveSteps) {
  const std::vector<std::vector<std::pair<std::string, std::string>>> bad = {
      {{"-checkpoint_budget", "0"}},
      {{"-checkpoint_budget", "-4"}},
      {{"-checkpoint_budget", "10"}, {"-ts_rk_type", "3bs"}, {"-ts_adapt_type", "basic"}}};
  for (auto &extra : bad) {
    auto opts = extra;
    for (auto o : std::vector<std::pair<std::string, std::string>>{
             {"-da_grid_x", "41"}, {"-ts_max_time", "0.02"}, {"-ts_dt", "2e-3"}})
      opts.push_back(o);
    Result r;
    PetscErrorCode ierr;
    {
      QuietErrors q;
      ierr = run_gradient(opts, r);
    }
    EXPECT_NE(ierr, 0) << extra.front().first << " " << extra.front().second;
  }
}
