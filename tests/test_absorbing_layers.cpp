// The wave's absorbing layers: what comes back from a sponge and from a perfectly matched layer of the
// same width, measured as run/absorber_reflection.sh does: receiver traces of the scene in [0,1]^D with
// the layer, against the same scene in [-1,2]^D (the same spacing, no layer), where nothing comes back
// before T. The largest difference over the direct wave's largest amplitude is the reflection; the
// PML's must be far below the sponge's.
#include "flexipde/scene.hpp"
#include "flexipde/survey.hpp"
#include "test_support.hpp"

using namespace flexipde;
using flexipde_test::ScopedOptions;

namespace {

// Traces of one shot (on every rank) of the scene of the current options, with the domain [lo, hi]^D.
std::vector<PetscReal> traces(int dim, PetscReal lo, PetscReal hi, PetscInt n) {
  ScopedOptions o{{"-grid_x0", std::to_string(lo).c_str()}, {"-grid_x1", std::to_string(hi).c_str()},
                  {"-da_grid_x", std::to_string(n).c_str()}};
  if (dim == 2) {
    o.set("-grid_y0", std::to_string(lo));
    o.set("-grid_y1", std::to_string(hi));
    o.set("-da_grid_y", std::to_string(n));
  }
  Scene s;
  OwnedVec p;
  EXPECT_EQ(s.setup(PETSC_COMM_WORLD), 0);
  EXPECT_EQ(s.params.create_vec(p.out()), 0);
  EXPECT_EQ(s.parameters_from_options("", p), 0);
  EXPECT_EQ(s.make_synthetic_data(p), 0);
  std::vector<PetscReal> t = s.objective.survey()->traces(); // rank 0
  PetscInt size = (PetscInt)t.size();
  MPI_Bcast(&size, 1, MPIU_INT, 0, PETSC_COMM_WORLD);
  t.resize(size);
  MPI_Bcast(t.data(), (int)size, MPIU_REAL, 0, PETSC_COMM_WORLD);
  return t;
}

// max |a - b| / max |b| over each receiver's trace; the worst receiver.
PetscReal reflection(const std::vector<PetscReal> &a, const std::vector<PetscReal> &b, PetscInt receivers) {
  const size_t nt = b.size() / receivers;
  PetscReal worst = 0;
  for (PetscInt r = 0; r < receivers; ++r) {
    PetscReal d = 0, m = 0;
    for (size_t k = 0; k < nt; ++k) {
      d = std::max(d, std::fabs(a[r * nt + k] - b[r * nt + k]));
      m = std::max(m, std::fabs(b[r * nt + k]));
    }
    worst = std::max(worst, d / m);
  }
  return worst;
}

struct LayerCase {
  const char *name;
  int dim;
  PetscInt n; // points on [0, 1]
  PetscReal pml_below;  // the PML's reflection must stay below this (measured: see the printout)
};

class AbsorbingLayers : public ::testing::TestWithParam<LayerCase> {};

} // namespace

TEST_P(AbsorbingLayers, PmlReflectsLessThanSponge) {
  const LayerCase c = GetParam();
  const std::string m = c.dim == 1 ? "-wave_" : "-wave2d_";
  ScopedOptions o{{"-model", c.dim == 1 ? "wave" : "wave2d"}, {"-ts_type", "rk"}, {"-ts_rk_type", "4"},
                  {"-ts_dt", "2e-3"}, {"-ts_max_time", "1.1"}, {"-objective_type", "receivers"},
                  {"-survey_sources_x", "0.5"}, {"-survey_ricker_f0", "5"}, {"-survey_receivers_x", "0.5,0.75"}};
  o.set(m + "ic", "zero");
  o.set(m + "c", "1");
  if (c.dim == 2) {
    o.set("-survey_sources_y", "0.5");
    o.set("-survey_receivers_y", "0.75,0.65");
  }
  std::vector<PetscReal> reference, sponge, pml;
  {
    ScopedOptions none{{(m + "sponge_width").c_str(), "0"}};
    reference = traces(c.dim, -1, 2, 3 * (c.n - 1) + 1);
  }
  {
    ScopedOptions layer{{(m + "sponge_width").c_str(), "0.1"}, {(m + "sponge_strength").c_str(), "60"}};
    sponge = traces(c.dim, 0, 1, c.n);
  }
  {
    ScopedOptions layer{{(m + "pml_width").c_str(), "0.1"}};
    pml = traces(c.dim, 0, 1, c.n);
  }
  ASSERT_EQ(sponge.size(), reference.size());
  ASSERT_EQ(pml.size(), reference.size());
  const PetscReal rs = reflection(sponge, reference, 2), rp = reflection(pml, reference, 2);
  PetscPrintf(PETSC_COMM_WORLD, "  [%s] reflection, layers of width 0.1 (10 points): sponge %.2e, PML %.2e\n", c.name,
              (double)rs, (double)rp);
  EXPECT_GT(rs, 0.0);
  EXPECT_LT(rp, 0.1 * rs);
  EXPECT_LT(rp, c.pml_below);
}

INSTANTIATE_TEST_SUITE_P(Wave, AbsorbingLayers,
                         // measured (RK4, f0 = 5: 20 points per wavelength, 10 in the layers): 1D sponge 4.5e-1, PML 1.6e-2; 2D sponge
// 1.3e-1, PML 5.9e-3
                         ::testing::Values(LayerCase{"wave_1d", 1, 101, 3e-2}, LayerCase{"wave2d", 2, 101, 1.2e-2}),
                         flexipde_test::CaseName());
