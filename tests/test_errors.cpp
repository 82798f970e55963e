// Invalid configurations are refused with an error code (and nothing crashes or hangs), and the
// stability check draws the line exactly at the explicit RK stability limit.
//
// Every refusal here is collective: the condition is evaluated identically on every rank.
#include "flexipde/inversion.hpp"
#include "flexipde/scene.hpp"
#include "test_support.hpp"

using namespace flexipde;
using flexipde_test::QuietErrors;
using flexipde_test::rel_diff;
using flexipde_test::ScopedOptions;

namespace {

using OptionList = std::initializer_list<std::pair<const char *, const char *>>;

// Scene::setup under the given options; returns its error code.
PetscErrorCode try_setup(OptionList options) {
  ScopedOptions opts(options);
  Scene scene;
  QuietErrors q;
  return scene.setup(PETSC_COMM_WORLD);
}

// A working scene whose forward() and gradient() are expected to fail under `options`.
struct Runner {
  Scene scene;
  OwnedVec p, U, g;
  PetscErrorCode setup() {
    PetscFunctionBeginUser;
    PetscCall(scene.setup(PETSC_COMM_WORLD));
    PetscCall(scene.params.create_vec(p.out()));
    PetscCall(scene.params.create_vec(g.out()));
    PetscCall(scene.parameters_from_options("", p));
    PetscCall(scene.sim.create_state(U.out()));
    PetscFunctionReturn(0);
  }
  PetscErrorCode forward() {
    QuietErrors q;
    return scene.sim.forward(p, U);
  }
  PetscErrorCode gradient() {
    QuietErrors q;
    PetscReal J;
    return scene.sim.gradient(p, &J, g, nullptr);
  }
};

const OptionList small = {{"-da_grid_x", "101"}, {"-ts_max_time", "0.3"}, {"-ts_dt", "2e-3"}};

} // namespace

TEST(Errors, SetupSucceedsOnValidScene) {
  ScopedOptions base(small);
  EXPECT_EQ(try_setup({}), 0);
}

TEST(Errors, UnknownModel) {
  ScopedOptions base(small);
  EXPECT_EQ(try_setup({{"-model", "heat"}}), PETSC_ERR_ARG_UNKNOWN_TYPE);
  std::unique_ptr<Model> m;
  QuietErrors q;
  EXPECT_NE(create_model(PETSC_COMM_WORLD, "", m), 0);
  EXPECT_FALSE(m);
  EXPECT_EQ(create_model(PETSC_COMM_WORLD, "wave", m), 0);
  EXPECT_TRUE(m);
  // every registered model is listed, in the registry's order, and can be created by its name
  std::string listed;
  for (auto &kv : model_registry()) {
    listed += (listed.empty() ? "" : ", ") + kv.first;
    std::unique_ptr<Model> each;
    EXPECT_EQ(create_model(PETSC_COMM_WORLD, kv.first, each), 0) << kv.first;
    EXPECT_TRUE(each && kv.first == each->name()) << kv.first;
  }
  EXPECT_EQ(model_names(), listed);
  for (const char *known : {"advection", "burgers", "vlasov", "wave", "wave2d"})
    EXPECT_NE(listed.find(known), std::string::npos) << known;
}

TEST(Errors, BadGridAndModelOptions) {
  ScopedOptions base(small);
  // the grid's ghost width is 2R for a stencil of radius R (the pointwise layer's transposes): at least
  // 2 * 2R + 3 points
  EXPECT_NE(try_setup({{"-da_grid_x", "6"}}), 0);                    // fewer than 2*2+3 points
  EXPECT_EQ(try_setup({{"-da_grid_x", "7"}}), 0);
  EXPECT_NE(try_setup({{"-da_grid_x", "10"}, {"-fd_order", "4"}}), 0); // fewer than 2*4+3 points
  EXPECT_EQ(try_setup({{"-da_grid_x", "11"}, {"-fd_order", "4"}}), 0);
  EXPECT_NE(try_setup({{"-grid_x0", "1"}, {"-grid_x1", "0"}}), 0);
  EXPECT_NE(try_setup({{"-fd_order", "3"}}), 0);
  EXPECT_NE(try_setup({{"-wave_ic_width", "0"}}), 0);
  EXPECT_NE(try_setup({{"-wave_ic_width", "-0.1"}}), 0);
  EXPECT_NE(try_setup({{"-objective_component", "w"}}), 0);
  EXPECT_EQ(try_setup({{"-objective_component", "v"}}), 0);
}

TEST(Errors, NonPositiveWaveSpeed) {
  ScopedOptions base(small);
  ScopedOptions opts{{"-wave_c", "-1"}};
  Runner r;
  PETSC_ASSERT_OK(r.setup());
  EXPECT_NE(r.forward(), 0);
  EXPECT_NE(r.gradient(), 0);
}

TEST(Errors, IntegratorWithoutAdjoint) {
  ScopedOptions base(small);
  ScopedOptions opts{{"-ts_type", "euler"}};
  Runner r;
  PETSC_ASSERT_OK(r.setup());
  EXPECT_EQ(r.gradient(), PETSC_ERR_SUP) << "-ts_type euler has no adjoint and must be refused";
  // ...while the integrators documented as having an adjoint are accepted.
  for (const char *ts : {"rk", "cn", "beuler", "theta"}) {
    ScopedOptions t{{"-ts_type", ts}, {"-ts_max_time", "0.02"}};
    EXPECT_EQ(r.gradient(), 0) << "-ts_type " << ts;
  }
}

// An explicit step beyond the stability limit is refused before any step is taken: the error is
// PETSC_ERR_ARG_OUTOFRANGE (not the NaN check after the run) and the state still holds U0.
TEST(Errors, ExplicitStepBeyondStabilityLimit) {
  ScopedOptions base(small);
  ScopedOptions opts{{"-ts_rk_type", "4"}, {"-ts_dt", "0.1"}, {"-ts_max_time", "1000"}};
  Runner r;
  PETSC_ASSERT_OK(r.setup());
  EXPECT_EQ(r.forward(), PETSC_ERR_ARG_OUTOFRANGE);
  OwnedVec U0;
  PETSC_ASSERT_OK(VecDuplicate(r.U, U0.out()));
  PETSC_ASSERT_OK(r.scene.sim.initial_condition(r.p, U0));
  EXPECT_EQ(rel_diff(r.U, U0), 0.0) << "steps were taken before the refusal";
  EXPECT_EQ(r.gradient(), PETSC_ERR_ARG_OUTOFRANGE);
}

// RK4 is stable on the imaginary axis up to |z| = 2*sqrt(2); for the wave with c = 1, h = 0.01
// and -fd_order 2, the spectral radius is 2c/h = 200, so dt <= 0.0141421. With T = 0.3, dt is
// rounded to T/round(T/dt): 22 steps (dt = 0.013636) are accepted, 21 (dt = 0.014286) refused.
TEST(Errors, StabilityLimitIsSharp) {
  ScopedOptions base(small);
  ScopedOptions opts{{"-ts_rk_type", "4"}, {"-wave_c", "1"}};
  {
    ScopedOptions dt{{"-ts_dt", "0.0136364"}};
    Runner r;
    PETSC_ASSERT_OK(r.setup());
    EXPECT_EQ(r.forward(), 0);
    EXPECT_EQ(r.scene.sim.stats().steps, 22);
    PetscReal nrm;
    PETSC_ASSERT_OK(VecNorm(r.U, NORM_INFINITY, &nrm));
    EXPECT_LT(nrm, 10.0) << "an accepted step should not blow up";
  }
  {
    ScopedOptions dt{{"-ts_dt", "0.0142857"}};
    Runner r;
    PETSC_ASSERT_OK(r.setup());
    EXPECT_EQ(r.forward(), PETSC_ERR_ARG_OUTOFRANGE);
    EXPECT_EQ(r.scene.sim.stats().steps, 21);
  }
  { // c scales the limit: c = 0.9 makes 21 steps stable.
    ScopedOptions c{{"-ts_dt", "0.0142857"}, {"-wave_c", "0.9"}};
    Runner r;
    PETSC_ASSERT_OK(r.setup());
    EXPECT_EQ(r.forward(), 0);
  }
  { // -sim_stability_check 0 runs it anyway (and the result is large but finite after 21 steps).
    ScopedOptions dt{{"-ts_dt", "0.0142857"}, {"-sim_stability_check", "0"}};
    Runner r;
    PETSC_ASSERT_OK(r.setup());
    EXPECT_EQ(r.forward(), 0);
  }
}

// RK tableaux whose stability region misses the imaginary axis are refused at any dt.
TEST(Errors, RkTypeUnstableForWaves) {
  ScopedOptions base(small);
  for (const char *rk : {"2a", "1fe"}) {
    ScopedOptions opts{{"-ts_rk_type", rk}, {"-ts_dt", "1e-5"}, {"-ts_max_time", "1e-3"}};
    Runner r;
    PETSC_ASSERT_OK(r.setup());
    EXPECT_EQ(r.forward(), PETSC_ERR_ARG_OUTOFRANGE) << "-ts_rk_type " << rk;
    EXPECT_EQ(r.gradient(), PETSC_ERR_ARG_OUTOFRANGE) << "-ts_rk_type " << rk;
  }
  for (const char *rk : {"3", "4"}) { // these include a segment of the imaginary axis
    ScopedOptions opts{{"-ts_rk_type", rk}, {"-ts_dt", "1e-3"}, {"-ts_max_time", "0.01"}};
    Runner r;
    PETSC_ASSERT_OK(r.setup());
    EXPECT_EQ(r.forward(), 0) << "-ts_rk_type " << rk;
  }
}

TEST(Errors, NonPositiveTimes) {
  ScopedOptions base(small);
  {
    ScopedOptions opts{{"-ts_max_time", "-1"}};
    Runner r;
    PETSC_ASSERT_OK(r.setup());
    EXPECT_NE(r.forward(), 0);
  }
  {
    ScopedOptions opts{{"-ts_dt", "-1e-3"}};
    Runner r;
    PETSC_ASSERT_OK(r.setup());
    EXPECT_NE(r.forward(), 0);
  }
}

TEST(Errors, InvertedInversionBounds) {
  ScopedOptions base(small);
  ScopedOptions opts{{"-inv_lower", "2"}, {"-inv_upper", "1"}};
  Scene scene;
  PETSC_ASSERT_OK(scene.setup(PETSC_COMM_WORLD));
  Inversion inv;
  QuietErrors q;
  EXPECT_NE(inv.setup(scene, nullptr), 0);
}

TEST(Errors, NegativeTikhonovWeight) {
  ScopedOptions base(small);
  ScopedOptions opts{{"-inv_tikhonov", "-1"}};
  Scene scene;
  PETSC_ASSERT_OK(scene.setup(PETSC_COMM_WORLD));
  Inversion inv;
  QuietErrors q;
  EXPECT_NE(inv.setup(scene, nullptr), 0);
}

// After all these refusals a normal run still works (no state left behind by failed calls).
TEST(Errors, ValidRunAfterFailures) {
  ScopedOptions base(small);
  Runner r;
  PETSC_ASSERT_OK(r.setup());
  EXPECT_EQ(r.forward(), 0);
  EXPECT_EQ(r.gradient(), 0);
}
