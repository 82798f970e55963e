// Example: one point of the advection work-precision study (run/bench_advection.sh runs many).
//
// Math. u_t + a u_x = 0 on [0, 2 pi) periodic, u0 = s(x) (sinusoid, gaussian or square pulse,
// -advection_ic ...), a = -advection_a (default 1.05), integrated to T (default 2 pi). The exact
// solution is u(x, T) = s(x - a T). Reported:
//   forward:  the relative discrete L2 error ||u_h(T) - s(x_i - a T)|| / ||s(x_i - a T)||, the
//             overshoot max u_h - max s and undershoot min s - min u_h (new extrema), and the
//             median wall time of -wp_repeats forward solves;
//   gradient: J = 1/2 sum_i (u_i(T) - d_i)^2 with the data d_i = s(x_i - a_d T) sampled from the
//             exact solution for a_d = -wp_data_a (default 1). h J approximates
//             J_c(a) = 1/2 int (s(x - a T) - s(x - a_d T))^2 dx, whose exact derivative is
//             dJ_c/da = T int s(y + delta) s'(y) dy, delta = (a - a_d) T:
//               sinusoid  T m pi sin(m delta)                    (s = sin(m x), L = 2 pi)
//               gaussian  the same integral by a 2^16-point periodic quadrature
//               square    T sign(delta)                          (0 < |delta| < width)
//             and the relative error of h dJ/da (adjoint) against it, with the median wall time
//             of -wp_repeats gradient evaluations (forward + adjoint); the fastest of the repeats is
//             printed too (on a shared machine the minimum is the least disturbed measurement).
// The step follows the grid: dt = -wp_cfl h / a (an explicit step must stay below the stability
// limit, which the Simulation checks).
//
// Sample runs (as root add --allow-run-as-root to mpiexec):
//   build/advection_work_precision -advection_scheme fd4 -da_grid_x 128
//   build/advection_work_precision -advection_scheme spectral -advection_ic square -advection_ic_width 2 -ts_type cn -wp_cfl 1
//   mpiexec -n 2 build/advection_work_precision -advection_scheme upwind -advection_ic gaussian -advection_ic_width 0.8
#include "flexipde/scene.hpp"
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

using namespace flexipde;

static PetscErrorCode default_option(const char *name, const char *value) {
  PetscBool set;
  PetscFunctionBeginUser;
  PetscCall(PetscOptionsHasName(nullptr, nullptr, name, &set));
  if (!set) PetscCall(PetscOptionsSetValue(nullptr, name, value));
  PetscFunctionReturn(0);
}

// The initial profile as the model defines it (src/models/advection.cpp), on [0, 2 pi).
struct Profile {
  PetscInt kind = 0, mode = 1; // sinusoid, gaussian, square
  PetscReal center = PETSC_PI, width = 0.2 * PETSC_PI;
  PetscReal operator()(PetscReal x) const {
    const PetscReal L = 2 * PETSC_PI;
    if (kind == 0) return std::sin(mode * x);
    PetscReal d = x - center;
    d -= L * std::floor(d / L + 0.5);
    if (kind == 1) return std::exp(-(d / width) * (d / width));
    return std::fabs(d) < 0.5 * width ? 1.0 : 0.0;
  }
  PetscReal derivative(PetscReal x) const { // smooth profiles only
    const PetscReal L = 2 * PETSC_PI;
    if (kind == 0) return mode * std::cos(mode * x);
    PetscReal d = x - center;
    d -= L * std::floor(d / L + 0.5);
    return -2 * d / (width * width) * std::exp(-(d / width) * (d / width));
  }
};

static PetscReal median(std::vector<PetscReal> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

static PetscErrorCode fill(const Grid &g, Vec v, const std::function<PetscReal(PetscReal)> &f) {
  PetscFunctionBeginUser;
  Array a(v);
  PetscCall(a.error());
  for (PetscInt il = 0; il < g.xm(); ++il) a[il] = f(g.x(g.xs() + il));
  PetscFunctionReturn(0);
}

static PetscErrorCode run() {
  MPI_Comm comm = PETSC_COMM_WORLD;
  const char *const ics[] = {"sinusoid", "gaussian", "square"};
  Profile s;
  PetscReal a = 1.05, a_data = 1.0, cfl = 0.5, T = 2 * PETSC_PI;
  PetscInt repeats = 3, n = 128;
  PetscFunctionBeginUser;
  // 1. Options: the study's own, then the scene's (its defaults set here, the command line wins).
  PetscOptionsBegin(comm, nullptr, "Advection work-precision point", "WorkPrecision");
  PetscCall(PetscOptionsEList("-advection_ic", "Initial profile", "", ics, 3, ics[0], &s.kind, nullptr));
  PetscCall(PetscOptionsReal("-advection_ic_width", "Profile width", "", s.width, &s.width, nullptr));
  PetscCall(PetscOptionsReal("-advection_a", "Velocity a", "", a, &a, nullptr));
  PetscCall(PetscOptionsInt("-da_grid_x", "Grid points", "", n, &n, nullptr));
  PetscCall(PetscOptionsReal("-wp_data_a", "Velocity of the exact solution sampled as data", "", a_data, &a_data, nullptr));
  PetscCall(PetscOptionsReal("-wp_cfl", "Courant number a dt / h", "", cfl, &cfl, nullptr));
  PetscCall(PetscOptionsReal("-ts_max_time", "Final time T", "", T, &T, nullptr));
  PetscCall(PetscOptionsInt("-wp_repeats", "Timed repetitions (median reported)", "", repeats, &repeats, nullptr));
  PetscOptionsEnd();
  PetscCheck(a > 0 && cfl > 0 && repeats > 0, comm, PETSC_ERR_ARG_OUTOFRANGE, "-advection_a, -wp_cfl and -wp_repeats must be positive");
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.17g", (double)a);
  PetscCall(default_option("-advection_a", buf));
  std::snprintf(buf, sizeof buf, "%.17g", (double)(cfl * 2 * PETSC_PI / n / a));
  PetscCall(PetscOptionsSetValue(nullptr, "-ts_dt", buf));
  PetscCall(default_option("-objective_type", "l2sq"));
  SceneDefaults defaults;
  defaults.model = "advection";
  defaults.grid.n = n;
  defaults.grid.x0 = 0;
  defaults.grid.x1 = 2 * PETSC_PI;
  defaults.grid.periodic = PETSC_TRUE;
  defaults.final_time = T;
  Scene scene;
  PetscCall(scene.setup(comm, defaults));
  OwnedVec p, grad, U, E;
  PetscCall(scene.params.create_vec(p.out()));
  PetscCall(scene.params.create_vec(grad.out()));
  PetscCall(scene.parameters_from_options("", p));
  PetscCall(scene.sim.create_state(U.out()));
  PetscCall(scene.sim.create_state(E.out()));
  const PetscInt ka = scene.params.find("advection_a");

  // 2. Forward: error against the exact solution, new extrema, median time (after one untimed
  //    warm-up solve, which pays for first-touch allocations and FFTW's plans being cold).
  std::vector<PetscReal> times;
  PetscCall(scene.sim.forward(p, U));
  for (PetscInt r = 0; r < repeats; ++r) {
    PetscCall(MPI_Barrier(comm));
    const double t0 = MPI_Wtime();
    PetscCall(scene.sim.forward(p, U));
    times.push_back(MPI_Wtime() - t0);
  }
  const PetscReal t_forward = median(times), t_forward_min = *std::min_element(times.begin(), times.end());
  PetscCall(fill(scene.grid, E, [&](PetscReal x) { return s(x - a * T); }));
  PetscReal umax, umin, enorm, err;
  PetscCall(VecMax(U, nullptr, &umax));
  PetscCall(VecMin(U, nullptr, &umin));
  PetscCall(VecNorm(E, NORM_2, &enorm));
  PetscCall(VecAXPY(E, -1.0, U));
  PetscCall(VecNorm(E, NORM_2, &err));
  const PetscReal smax = 1.0, smin = s.kind == 0 ? -1.0 : 0.0; // extrema of the exact solution

  // 3. Gradient: data from the exact solution for a_data, adjoint dJ/da, median time.
  PetscCall(fill(scene.grid, scene.objective.data(), [&](PetscReal x) { return s(x - a_data * T); }));
  PetscReal J = 0, g = 0;
  times.clear();
  for (PetscInt r = 0; r < repeats; ++r) {
    PetscCall(MPI_Barrier(comm));
    const double t0 = MPI_Wtime();
    PetscCall(scene.sim.gradient(p, &J, grad, nullptr));
    times.push_back(MPI_Wtime() - t0);
  }
  const PetscReal t_gradient = median(times), t_gradient_min = *std::min_element(times.begin(), times.end());
  PetscCall(scene.params.scalar(grad, ka, &g));
  const PetscReal delta = (a - a_data) * T, h = scene.grid.h();
  PetscReal exact = 0;
  if (s.kind == 0) exact = T * s.mode * PETSC_PI * std::sin(s.mode * delta);
  else if (s.kind == 2) exact = T * (delta > 0 ? 1.0 : -1.0);
  else {
    const PetscInt m = 1 << 16;
    for (PetscInt i = 0; i < m; ++i) {
      const PetscReal y = 2 * PETSC_PI * i / m;
      exact += s(y + delta) * s.derivative(y);
    }
    exact *= T * 2 * PETSC_PI / m;
  }
  const SimulationStats &st = scene.sim.stats();
  PetscCall(PetscPrintf(comm,
                        "wp N=%" PetscInt_FMT " steps=%" PetscInt_FMT " dt=%.6e forward_time=%.6e forward_error=%.6e "
                        "overshoot=%.6e undershoot=%.6e gradient_time=%.6e gradient=%.12e gradient_exact=%.12e "
                        "gradient_error=%.6e forward_time_min=%.6e gradient_time_min=%.6e\n",
                        n, st.steps, (double)st.dt, (double)t_forward, (double)(err / enorm), (double)(umax - smax),
                        (double)(smin - umin), (double)t_gradient, (double)(h * g), (double)exact,
                        (double)(std::fabs(h * g - exact) / std::fabs(exact)), (double)t_forward_min,
                        (double)t_gradient_min));
  PetscFunctionReturn(0);
}

int main(int argc, char **argv) {
  PetscCall(PetscInitialize(&argc, &argv, nullptr, "One point of the advection work-precision study\n"));
  PetscErrorCode ierr = run();
  if (ierr) MPI_Abort(MPI_COMM_WORLD, (int)ierr);
  PetscCall(PetscFinalize());
  return 0;
}
