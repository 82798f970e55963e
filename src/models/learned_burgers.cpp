// Viscous Burgers on a coarse periodic grid with a learned flux: the weights that reconstruct the
// solution at each cell face are parameters, trained through the exact adjoint so that the coarse
// grid reproduces what a fine grid computes (examples/learned_burgers_train.cpp,
// docs/learned_discretisation.md).
//
//   u_t + (u^2/2)_x = (nu u_x)_x,   G_i = -(F_{i+1/2} - F_{i-1/2}) / h + nu (u_{i+1} - 2 u_i + u_{i-1}) / h^2,
//
//   F_{i+1/2} = EO(u-, u+) = max(u-, 0)^2 / 2 + min(u+, 0)^2 / 2        (Engquist-Osher: upwind),
//   u- = u_i     + w_1 (u_{i-1} - u_i)     + w_2 (u_{i+1} - u_i) + w_3 (u_{i+2} - u_i),
//   u+ = u_{i+1} + v_1 (u_{i+2} - u_{i+1}) + v_2 (u_i - u_{i+1}) + v_3 (u_{i-1} - u_{i+1}),
//
// u- a left-biased and u+ the mirrored right-biased reconstruction from the four values around the
// face. Written as differences, the weights of each sum to 1 for any w, v: a constant state is
// reproduced exactly (consistency), and the flux form conserves sum_i u_i exactly. w = v = 0 is the
// first-order Engquist-Osher scheme of -model burgers; (0, 1/2, 0) the centred one; (-1/6, 1/3, 0)
// the third-order upwind-biased (kappa = 1/3) reconstruction; (-1/2, 0, 0) second-order upwind.
//
// The weights are the parameter vector learned_burgers_theta, in one of two forms
// (-learned_burgers_weights):
//   constant  w = v = theta (3 entries): one stencil for the whole grid;
//   network   w = n(f), v = n(f mirrored), a network of the face's three differences
//             d = (u_i - u_{i-1}, u_{i+1} - u_i, u_{i+2} - u_{i+1}) scaled to f = d / sqrt(|d|^2 + eps^2):
//             n(f) = b2 + W2 s(W1 f + b1), H hidden units, 7 H + 3 entries (W1, b1, W2, b2), with the
//             activation s(a) = a / sqrt(1 + a^2) (smooth and bounded like tanh, and several times
//             cheaper: the adjoint evaluates the network about 25 times per point and step stage).
//             Burgers is symmetric under (x, u) -> (-x, -u), which maps the left state's stencil to the
//             right one's with the differences reversed: v = n(d3, d2, d1).
// The network starts at W2 = 0 (so the scheme is the one b2 gives) with W1, b1 drawn from
// -learned_burgers_init_seed. Its gradient, like every parameter vector's, costs the same whatever
// the number of entries (pointwise.hpp, reverse.hpp).
//
// Start: "random" (random_start.hpp, the function -burgers_ic random uses) averaged over
// -learned_burgers_ic_subsamples points per cell, the cell average of the fine grid that many times
// finer; or "sine".
//
//   mpiexec -n 2 ./flexipde -model learned_burgers -ts_dt 0.005 -ts_max_time 0.5 -task gradient -check_fd
//           -true_learned_burgers_theta 0,0,0
//   mpiexec -n 2 ./flexipde -model learned_burgers -ts_dt 0.005 -ts_max_time 0.5 -task taylor
//           -learned_burgers_weights network -objective_type mean_square
//   ./flexipde -model learned_burgers -ts_dt 0.005 -ts_max_time 0.5 -task forward -learned_burgers_weights network
//           -learned_burgers_theta_file learned_burgers.h5          (weights from examples/learned_burgers_train)
//   (each one command line)
#include "flexipde/pointwise.hpp"
#include "flexipde/random_start.hpp"

namespace flexipde {

class LearnedBurgers {
public:
  static constexpr int dim = 1, components = 1, radius = 2, parameters = 1;
  enum Parameter { nu = 0 };

  const char *name() const { return "learned_burgers"; }
  const char *component_name(int) const { return "u"; }
  void grid_defaults(GridOptions &o) const {
    o.n = 32;
    o.periodic = PETSC_TRUE;
  }

  PetscErrorCode setup(const Grid &grid, Declarations &decl) {
    const char *forms[] = {"constant", "network"}, *ics[] = {"random", "sine"};
    PetscInt init_seed = 7;
    PetscReal nu_value = 0.01;
    PetscReal w0[3] = {-1.0 / 6, 1.0 / 3, 0.0};
    PetscInt nw = 3;
    PetscBool w_set = PETSC_FALSE;
    PetscFunctionBeginUser;
    PetscOptionsBegin(grid.comm(), nullptr, "Burgers with a learned flux", "LearnedBurgers");
    PetscCall(PetscOptionsEList("-learned_burgers_weights", "Face weights: one stencil (constant) or a network of the local differences",
                                "LearnedBurgers", forms, 2, forms[form_], &form_, nullptr));
    PetscCall(PetscOptionsInt("-learned_burgers_hidden", "Network: hidden units H (7 H + 3 weights)", "LearnedBurgers",
                              hidden_, &hidden_, nullptr));
    PetscCall(PetscOptionsReal("-learned_burgers_eps", "Network: eps in the feature scaling d / sqrt(|d|^2 + eps^2)",
                               "LearnedBurgers", eps_, &eps_, nullptr));
    PetscCall(PetscOptionsInt("-learned_burgers_init_seed", "Network: seed of the initial W1, b1", "LearnedBurgers", init_seed,
                              &init_seed, nullptr));
    PetscCall(PetscOptionsRealArray("-learned_burgers_init_weights", "Default weights (w1, w2, w3): theta (constant), b2 (network)",
                                    "LearnedBurgers", w0, &nw, &w_set));
    PetscCall(PetscOptionsReal("-learned_burgers_nu", "Viscosity nu", "LearnedBurgers", nu_value, &nu_value, nullptr));
    PetscCall(PetscOptionsEList("-learned_burgers_ic", "Initial condition", "LearnedBurgers", ics, 2, ics[ic_], &ic_, nullptr));
    PetscCall(PetscOptionsReal("-learned_burgers_ic_amplitude", "Amplitude A of the start", "LearnedBurgers", amplitude_,
                               &amplitude_, nullptr));
    PetscCall(PetscOptionsInt("-learned_burgers_ic_seed", "Random start: seed", "LearnedBurgers", seed_, &seed_, nullptr));
    PetscCall(PetscOptionsInt("-learned_burgers_ic_modes", "Random start: number of sine modes", "LearnedBurgers", modes_,
                              &modes_, nullptr));
    PetscCall(PetscOptionsInt("-learned_burgers_ic_subsamples", "Start: mean of the start at this many points per cell",
                              "LearnedBurgers", subsamples_, &subsamples_, nullptr));
    PetscOptionsEnd();
    PetscCheck(grid.periodic(), grid.comm(), PETSC_ERR_ARG_WRONG, "learned_burgers: the grid must be periodic (-grid_periodic 1)");
    PetscCheck(hidden_ > 0, grid.comm(), PETSC_ERR_ARG_OUTOFRANGE, "-learned_burgers_hidden must be positive");
    PetscCheck(eps_ > 0, grid.comm(), PETSC_ERR_ARG_OUTOFRANGE, "-learned_burgers_eps must be positive");
    PetscCheck(nu_value >= 0, grid.comm(), PETSC_ERR_ARG_OUTOFRANGE, "Viscosity must be non-negative, found nu = %g", (double)nu_value);
    PetscCheck(!w_set || nw == 3, grid.comm(), PETSC_ERR_ARG_SIZ, "-learned_burgers_init_weights takes 3 values, got %" PetscInt_FMT, nw);
    PetscCheck(modes_ > 0 && subsamples_ > 0, grid.comm(), PETSC_ERR_ARG_OUTOFRANGE,
               "-learned_burgers_ic_modes and -learned_burgers_ic_subsamples must be positive");
    x0_ = grid.x0(), length_ = grid.x1() - grid.x0();
    start_.make((unsigned)seed_, (int)modes_, amplitude_, 0.0, length_);
    decl.fixed(nu, nu_value);
    std::vector<PetscReal> theta(w0, w0 + 3);
    if (form_ == 1) { // W1 (H x 3), b1 (H) random; W2 (3 x H) zero; b2 = the default weights
      const PetscInt H = hidden_;
      theta.assign(7 * H + 3, 0.0);
      std::mt19937 gen((unsigned)init_seed);
      const double s = 1 / std::sqrt(3.0);
      for (PetscInt k = 0; k < 4 * H; ++k) theta[k] = s * (2 * (double)gen() / 4294967296.0 - 1);
      for (int k = 0; k < 3; ++k) theta[7 * H + k] = w0[k];
    }
    theta_ = decl.vector("learned_burgers_theta", theta);
    PetscFunctionReturn(0);
  }

  template <class P> void rhs(const P &pt, typename P::Number *g) const {
    using T = typename P::Number;
    const T u[5] = {pt.u(0, -2), pt.u(0, -1), pt.u(0, 0), pt.u(0, 1), pt.u(0, 2)};
    const double ih = pt.inv_h();
    const T visc = pt.param(nu) * (u[3] - 2.0 * u[2] + u[1]) * (ih * ih);
    g[0] = -(face_flux(pt, u + 1) - face_flux(pt, u)) * ih + visc;
  }

  template <class P> void initial(const P &pt, typename P::Number *u) const {
    const double x = pt.x(), h = pt.h();
    if (ic_ == 1) {
      u[0] = amplitude_ * std::sin(2 * PETSC_PI * (x - x0_) / length_);
      return;
    }
    double s = 0; // the mean over the cell's sub-points, as the fine grid's cell average sees the start
    for (PetscInt m = 0; m < subsamples_; ++m) s += start_(x - 0.5 * h + (m + 0.5) * h / subsamples_);
    u[0] = s / subsamples_;
  }

private:
  // The flux through the face between s[1] and s[2] (s: the four values around it).
  template <class P, class T> T face_flux(const P &pt, const T *s) const {
    T w[3], v[3];
    weights(pt, s[1] - s[0], s[2] - s[1], s[3] - s[2], w);
    weights(pt, s[3] - s[2], s[2] - s[1], s[1] - s[0], v);
    const T left = s[1] + w[0] * (s[0] - s[1]) + w[1] * (s[2] - s[1]) + w[2] * (s[3] - s[1]);
    const T right = s[2] + v[0] * (s[3] - s[2]) + v[1] * (s[1] - s[2]) + v[2] * (s[0] - s[2]);
    return 0.5 * sqr(max(left, T(0.0))) + 0.5 * sqr(min(right, T(0.0)));
  }
  // The three weights for a stencil whose differences (towards the face) are d1, d2, d3.
  template <class P, class T> void weights(const P &pt, const T &d1, const T &d2, const T &d3, T *w) const {
    if (form_ == 0) {
      for (int k = 0; k < 3; ++k) w[k] = pt.theta(theta_ + k);
      return;
    }
    const PetscInt H = hidden_, W1 = theta_, B1 = W1 + 3 * H, W2 = B1 + H, B2 = W2 + 3 * H;
    const T r = 1.0 / sqrt(d1 * d1 + d2 * d2 + d3 * d3 + eps_ * eps_);
    const T f[3] = {d1 * r, d2 * r, d3 * r};
    for (int k = 0; k < 3; ++k) w[k] = pt.theta(B2 + k);
    for (PetscInt j = 0; j < H; ++j) {
      const T a = pt.theta(B1 + j) + pt.theta(W1 + 3 * j) * f[0] + pt.theta(W1 + 3 * j + 1) * f[1] +
                  pt.theta(W1 + 3 * j + 2) * f[2];
      const T z = a / sqrt(1.0 + a * a);
      for (int k = 0; k < 3; ++k) w[k] += pt.theta(W2 + k * H + j) * z;
    }
  }

  PetscInt form_ = 0, hidden_ = 32, ic_ = 0, seed_ = 1, modes_ = 3, subsamples_ = 1, theta_ = 0;
  PetscReal eps_ = 0.05, amplitude_ = 1.0, x0_ = 0, length_ = 1;
  RandomStart start_;
};

FLEXIPDE_REGISTER_MODEL("learned_burgers", PointwiseModel<LearnedBurgers>);

} // namespace flexipde
