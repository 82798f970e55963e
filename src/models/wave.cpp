// Acoustic wave equation with a spatially varying speed, in one or two dimensions from one source,
// as a first-order system:
//
//   u_t = v,    v_t = c(x)^2 Lap_h u - sigma(x) v + w(t) delta_h(x - x_s),
//
// Lap_h the centred second differences of order 2 or 4 in each direction (-fd_order 2|4); u = v = 0
// held on the walls of non-periodic directions, the state beyond a wall being the odd reflection of
// the inside (so that the fourth-order stencil next to a wall stays consistent with u = 0 on it).
// sigma is an absorbing sponge along the walls, sigma_max (d / W)^2 at depth d into a layer of width
// W (-<m>_sponge_width W, -<m>_sponge_strength sigma_max); with W = 0 the system is in second-order
// form (G_u = v, G_v independent of v) and the leapfrog integrator applies. The last term is a point
// source (survey.hpp). The parameter c is one scalar (-<m>_c_field 0) or a field (-<m>_c_field 1).
// <m> is "wave" in 1D and "wave2d" in 2D.
//
// Initial condition (-<m>_ic): "pulse" (or "rest") u0 = exp(-|x - x_c|^2 / w^2), v0 = 0 (-<m>_ic_x,
// -<m>_ic_y, -<m>_ic_width); "travelling" the same pulse moving in +x, v0 = -c du0/dx, so that U0
// depends on c; "zero", for waves made by point sources only.
//
// Every Jacobian, transpose and adjoint sweep is derived from rhs() and initial() by the pointwise layer.
//
//   mpiexec -n 2 ./flexipde -task gradient -wave_c_field 1 -wave_c 0.9 -check_fd
//   mpiexec -n 2 ./flexipde -task taylor -wave_c_field 1 -wave_c 0.9 -true_wave_c 1.0 -wave_ic zero
//           -objective_type receivers -survey_sources_x 0.3,0.7 -survey_receivers_spread 0.05,0.95,10 -ts_max_time 1
//   mpiexec -n 2 ./flexipde -model wave2d -task gradient -da_grid_x 101 -da_grid_y 101 -ts_type leapfrog
//           -wave2d_sponge_width 0 -wave2d_ic pulse -wave2d_c_field 1 -wave2d_c 0.9 -true_wave2d_c 1
//   (each one command line)
#include "flexipde/differentiator.hpp"
#include "flexipde/pointwise.hpp"

namespace flexipde {

// D dimensions, stencil radius R (order 2R).
template <int D, int R>
class AcousticWave {
public:
  static constexpr int dim = D, components = 2, radius = R, parameters = 1;
  static constexpr int second_order_pairs = 1, forced_component = 1;
  static constexpr bool linear = true;
  enum Parameter { c = 0 };

  const char *name() const { return D == 1 ? "wave" : "wave2d"; }
  const char *component_name(int k) const { return k == 0 ? "u" : "v"; }
  void grid_defaults(GridOptions &o) const {
    if (D == 2) o.n = o.ny = 101;
  }
  bool second_order_active() const { return sponge_width_ <= 0; }
  bool odd_walls() const { return true; }

  PetscErrorCode setup(const Grid &grid, Declarations &decl) {
    const char *ics[] = {"travelling", "rest", "zero", "pulse"};
    const std::string m = name(), title = std::string("Acoustic wave ") + (D == 1 ? "u_tt = c^2 u_xx" : "u_tt = c^2 (u_xx + u_yy)");
    PetscBool c_field = PETSC_FALSE;
    PetscReal c_min = 0.01;
    PetscFunctionBeginUser;
    ic_ = D == 1 ? 0 : 2;
    ic_width_ = D == 1 ? 0.2 : 0.05;
    sponge_width_ = D == 1 ? 0.0 : 0.15;
    PetscOptionsBegin(grid.comm(), nullptr, title.c_str(), "Wave");
    PetscCall(PetscOptionsBool(opt("_c_field").c_str(), "Speed c is a field (one value per grid point), else one scalar", "Wave",
                               c_field, &c_field, nullptr));
    PetscCall(PetscOptionsReal(opt("_c_min").c_str(), "Smallest admissible speed: optimisers never go below it", "Wave", c_min,
                               &c_min, nullptr));
    PetscCall(PetscOptionsEList(opt("_ic").c_str(), "Initial condition (rest and pulse are the same)", "Wave", ics, 4, ics[ic_],
                                &ic_, nullptr));
    PetscCall(PetscOptionsReal(opt("_ic_x").c_str(), "Centre x of the initial pulse", "Wave", ic_x_[0], &ic_x_[0], nullptr));
    if (D == 2) PetscCall(PetscOptionsReal(opt("_ic_y").c_str(), "Centre y of the initial pulse", "Wave", ic_x_[1], &ic_x_[1], nullptr));
    PetscCall(PetscOptionsReal(opt("_ic_width").c_str(), "Width w of the pulse exp(-|x - x_c|^2 / w^2)", "Wave", ic_width_,
                               &ic_width_, nullptr));
    PetscCall(PetscOptionsReal(opt("_sponge_width").c_str(), "Width W of the absorbing layer along each wall (0: none)", "Wave",
                               sponge_width_, &sponge_width_, nullptr));
    PetscCall(PetscOptionsReal(opt("_sponge_strength").c_str(), "Damping sigma_max at the outer edge of the layer", "Wave",
                               sigma_max_, &sigma_max_, nullptr));
    PetscOptionsEnd();
    PetscCheck(c_min > 0, grid.comm(), PETSC_ERR_ARG_OUTOFRANGE, "%s must be positive, got %g", opt("_c_min").c_str(), (double)c_min);
    PetscCheck(ic_width_ > 0, grid.comm(), PETSC_ERR_ARG_OUTOFRANGE, "%s must be positive, got %g", opt("_ic_width").c_str(),
               (double)ic_width_);
    PetscCheck(sponge_width_ >= 0 && sigma_max_ >= 0, grid.comm(), PETSC_ERR_ARG_OUTOFRANGE,
               "%s and %s must be non-negative", opt("_sponge_width").c_str(), opt("_sponge_strength").c_str());
    SecondDerivative d2;
    PetscCall(SecondDerivative::from_options(grid.comm(), nullptr, 2, d2));
    PetscCheck(d2.half_width() == R, grid.comm(), PETSC_ERR_PLIB, "wave: stencil radius %d for -fd_order %d", R,
               (int)(2 * d2.half_width()));
    spectral_radius_ = 0;
    for (int d = 0; d < D; ++d) {
      const PetscReal h = d == 0 ? grid.h() : grid.hy();
      spectral_radius_ += d2.spectral_radius(h);
      lo_[d] = d == 0 ? grid.x0() : grid.y0(), hi_[d] = d == 0 ? grid.x1() : grid.y1();
      periodic_[d] = d == 0 ? grid.periodic() : grid.periodic_y();
    }
    decl.parameter(c, name() + std::string("_c"), c_field, c_min, 1.0);
    PetscFunctionReturn(0);
  }

  // G = [v ; c^2 Lap u - sigma v], 0 on the walls.
  template <class P> void rhs(const P &pt, typename P::Number *g) const {
    using T = typename P::Number;
    if (pt.on_wall()) {
      g[0] = g[1] = T(0.0);
      return;
    }
    T lap = T(0.0);
    for (int d = 0; d < D; ++d) {
      T s = weight(0) * pt.u(0, 0);
      for (int k = 1; k <= R; ++k) s += weight(k) * (d == 0 ? pt.u(0, -k) + pt.u(0, k) : pt.u(0, 0, -k) + pt.u(0, 0, k));
      lap += s * sqr(pt.inv_h(d));
    }
    g[0] = pt.u(1, 0);
    g[1] = sqr(pt.param(c)) * lap;
    if (sponge_width_ > 0) g[1] -= sponge(pt) * pt.u(1, 0);
  }

  template <class P> void initial(const P &pt, typename P::Number *u) const {
    using T = typename P::Number;
    u[0] = u[1] = T(0.0);
    if (pt.on_wall() || ic_ == 2) return;
    PetscReal r2 = 0;
    for (int d = 0; d < D; ++d) r2 += sqr((pt.x(d) - ic_x_[d]) / ic_width_);
    const PetscReal u0 = std::exp(-r2);
    u[0] = u0;
    if (ic_ == 0) u[1] = pt.param(c) * (2 * (pt.x(0) - ic_x_[0]) / sqr(ic_width_) * u0); // -c du0/dx
  }

  // Eigenvalues of dG/dU: +-i c sqrt(eig(-Lap_h)) in the interior, damped by at most sigma_max.
  PetscErrorCode spectrum(const ParameterBounds &b, Spectrum *s) const {
    s->imag_radius = b.max[c] * std::sqrt(spectral_radius_);
    s->real_radius = sponge_width_ > 0 ? sigma_max_ : 0;
    return 0;
  }
  PetscErrorCode check_parameters(const ParameterBounds &b, MPI_Comm comm) const {
    PetscFunctionBeginUser;
    PetscCheck(b.min[c] > 0, comm, PETSC_ERR_ARG_OUTOFRANGE, "Wave speed must be positive, found c = %g", (double)b.min[c]);
    PetscFunctionReturn(0);
  }

private:
  std::string opt(const char *suffix) const { return std::string("-") + name() + suffix; }
  // The centred second-difference weights: w_0 u_0 + sum_k w_k (u_-k + u_k), over h^2.
  static constexpr double weight(int k) {
    if (R == 1) return k == 0 ? -2.0 : 1.0;
    return k == 0 ? -30.0 / 12 : (k == 1 ? 16.0 / 12 : -1.0 / 12);
  }
  template <class P> PetscReal sponge(const P &pt) const {
    PetscReal depth = sponge_width_;
    for (int d = 0; d < D; ++d)
      if (!periodic_[d]) depth = std::min(depth, std::min(pt.x(d) - lo_[d], hi_[d] - pt.x(d)));
    const PetscReal s = std::max<PetscReal>(0, sponge_width_ - depth) / sponge_width_;
    return sigma_max_ * s * s;
  }

  PetscInt ic_ = 0;
  PetscReal ic_x_[2] = {0.5, 0.5}, ic_width_ = 0.2;
  PetscReal sponge_width_ = 0, sigma_max_ = 60.0, spectral_radius_ = 0;
  PetscReal lo_[2] = {0, 0}, hi_[2] = {1, 1};
  bool periodic_[2] = {false, false};
};

// The stencil radius is a compile-time constant of the sweeps: -fd_order picks the instance.
template <int D> std::unique_ptr<Model> make_wave() {
  PetscInt order = 2;
  (void)PetscOptionsGetInt(nullptr, nullptr, "-fd_order", &order, nullptr);
  if (order == 4) return std::make_unique<PointwiseModel<AcousticWave<D, 2>>>();
  return std::make_unique<PointwiseModel<AcousticWave<D, 1>>>(); // other orders are refused at setup
}

static const ModelRegistration wave_1d("wave", make_wave<1>), wave_2d("wave2d", make_wave<2>);

} // namespace flexipde
