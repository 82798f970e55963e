// What a gradient with respect to many flux weights costs: learned_burgers with one stencil (3 weights)
// and with networks of -cost_hidden units (7 H + 3 weights each), timed in one process.
//
// For each variant: the median wall time of a forward solve and of a gradient (value and dJ/dtheta by
// the adjoint, a terminal misfit against data from weights 1 % off), alternating between the variants
// repetition by repetition, and their ratio. The weights are a parameter vector: their transposes
// (dG/dtheta)^T x come from one reverse-mode sweep per product, whatever their number. For scale, the
// same product by forward-mode lanes, one per weight, is measured as NP products dG/dtheta v (one
// direction each) against one transpose product, at one state.
//
//   ./learned_burgers_gradient_cost
//   ./learned_burgers_gradient_cost -cost_hidden 4,16,64 -cost_repeats 7 -da_grid_x 64
#include "learned_burgers_common.hpp"
#include <algorithm>

using namespace flexipde;
using namespace learned;

static const char help[] = "Gradient cost of learned_burgers with 3 and with hundreds of weights.\n";

struct Variant {
  std::string label;
  std::unique_ptr<Scene> scene;
  OwnedVec p, g, U;
  std::vector<double> forward, gradient;
};

static double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

// Median seconds of one dG/dtheta v product (a tangent sweep) and of one (dG/dtheta)^T x product.
static PetscErrorCode products(Variant &v, PetscInt repeats, double *tangent, double *transpose) {
  OwnedMat Jp;
  OwnedVec x, y, dp;
  std::vector<double> a, b;
  PetscFunctionBeginUser;
  Model &m = *v.scene->model;
  PetscCall(m.set_parameters(v.p));
  PetscCall(v.scene->sim.initial_condition(v.p, v.U));
  PetscCall(m.create_jacobian_p(Jp.out()));
  PetscCall(m.rhs_jacobian_p(0, v.U, Jp));
  PetscCall(VecDuplicate(v.U, x.out()));
  PetscCall(VecDuplicate(v.U, y.out()));
  PetscCall(VecDuplicate(v.p, dp.out()));
  PetscCall(VecSet(x, 1.0));
  PetscCall(VecSet(dp, 1.0));
  for (PetscInt r = 0; r < repeats; ++r) {
    double t0 = MPI_Wtime();
    for (int k = 0; k < 20; ++k) PetscCall(MatMult(Jp, dp, y));
    double t1 = MPI_Wtime();
    for (int k = 0; k < 20; ++k) PetscCall(MatMultTranspose(Jp, x, dp));
    a.push_back((t1 - t0) / 20), b.push_back((MPI_Wtime() - t1) / 20);
  }
  *tangent = median(a), *transpose = median(b);
  PetscFunctionReturn(0);
}

static PetscErrorCode run(MPI_Comm comm) {
  PetscInt hidden[16] = {64}, nh = 16, repeats = 5;
  PetscBool hidden_set = PETSC_FALSE;
  Settings s;
  PetscFunctionBeginUser;
  PetscOptionsBegin(comm, nullptr, "Gradient cost of learned weights", "learned_burgers_gradient_cost");
  PetscCall(PetscOptionsIntArray("-cost_hidden", "Networks to time: their hidden units", "", hidden, &nh, &hidden_set));
  PetscCall(PetscOptionsInt("-cost_repeats", "Timed repetitions (medians)", "", repeats, &repeats, nullptr));
  PetscOptionsEnd();
  if (!hidden_set) nh = 1;
  PetscCheck(nh > 0 && repeats > 0, comm, PETSC_ERR_ARG_OUTOFRANGE, "-cost_hidden needs a value and -cost_repeats must be positive");
  PetscCall(s.from_options(comm));
  std::vector<Variant> variants;
  std::vector<std::vector<std::pair<std::string, std::string>>> options = {{{"-learned_burgers_weights", "constant"}}};
  for (PetscInt k = 0; k < nh; ++k) {
    PetscCheck(hidden[k] > 0, comm, PETSC_ERR_ARG_OUTOFRANGE, "-cost_hidden values must be positive");
    options.push_back({{"-learned_burgers_weights", "network"}, {"-learned_burgers_hidden", std::to_string(hidden[k])}});
  }
  PetscBool help = PETSC_FALSE;
  PetscCall(PetscOptionsHasHelp(nullptr, &help));
  for (auto &o : options) {
    if (help) { // the model's options, once, then stop
      Scene scene;
      PetscCall(coarse_scene(comm, scene, s.n, s.dt, s.T, 1, 1, o));
      PetscFunctionReturn(0);
    }
    Variant v;
    OwnedVec p_true;
    v.scene = std::make_unique<Scene>();
    PetscCall(coarse_scene(comm, *v.scene, s.n, s.dt, s.T, 1, 1, o));
    Scene &sc = *v.scene;
    PetscCall(sc.params.create_vec(v.p.out()));
    PetscCall(sc.parameters_from_options("", v.p));
    PetscCall(VecDuplicate(v.p, v.g.out()));
    PetscCall(VecDuplicate(v.p, p_true.out()));
    PetscCall(VecCopy(v.p, p_true));
    PetscCall(VecScale(p_true, 1.01));
    PetscCall(sc.make_synthetic_data(p_true));
    PetscCall(sc.sim.create_state(v.U.out()));
    PetscReal J;
    PetscCall(sc.gradient(v.p, &J, v.g)); // warm-up
    v.label = std::to_string(sc.params.global_size()) + " weights (" + o[0].second + (o.size() > 1 ? ", H = " + o[1].second : "") + ")";
    variants.push_back(std::move(v));
  }
  for (PetscInt r = 0; r < repeats; ++r)
    for (Variant &v : variants) {
      PetscReal J;
      PetscCallMPI(MPI_Barrier(comm));
      const double t0 = MPI_Wtime();
      PetscCall(v.scene->sim.forward(v.p, v.U));
      PetscCallMPI(MPI_Barrier(comm));
      const double t1 = MPI_Wtime();
      PetscCall(v.scene->gradient(v.p, &J, v.g));
      PetscCallMPI(MPI_Barrier(comm));
      v.forward.push_back(t1 - t0), v.gradient.push_back(MPI_Wtime() - t1);
    }
  PetscCall(PetscPrintf(comm, "learned_burgers on %" PetscInt_FMT " cells, %" PetscInt_FMT " RK4 steps, medians of %" PetscInt_FMT " (one process, alternating):\n",
                        s.n, s.steps(), repeats));
  PetscCall(PetscPrintf(comm, "%-34s %12s %12s %10s %14s %14s %12s\n", "variant", "forward s", "gradient s", "grad/fwd",
                        "tangent dG/dp", "transpose", "NP tangents"));
  for (Variant &v : variants) {
    double tan, tr;
    PetscCall(products(v, repeats, &tan, &tr));
    const PetscInt np = v.scene->params.global_size();
    const double f = median(v.forward), g = median(v.gradient);
    PetscCall(PetscPrintf(comm, "%-34s %12.6f %12.6f %10.2f %14.3e %14.3e %11.1fx\n", v.label.c_str(), f, g, g / f, tan, tr,
                          np * tan / tr));
  }
  PetscCall(PetscPrintf(comm, "(tangent: one product dG/dtheta v; transpose: one (dG/dtheta)^T x for every weight at once; "
                              "NP tangents: what forward-mode lanes would cost for the same transpose, relative to it)\n"));
  PetscFunctionReturn(0);
}

int main(int argc, char **argv) {
  PetscCall(PetscInitialize(&argc, &argv, nullptr, help));
  PetscErrorCode ierr = run(PETSC_COMM_WORLD);
  if (ierr) MPI_Abort(MPI_COMM_WORLD, (int)ierr);
  PetscCall(PetscFinalize());
  return 0;
}
