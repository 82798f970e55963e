// Acoustic wave equation with a spatially varying speed, in D dimensions from one source file, as a
// first-order system (registered as "wave", "wave2d" and "wave3d" for D = 1, 2 and 3):
//
//   u_t = v,    v_t = c(x)^2 Lap_h u - sigma(x) v + w(t) delta_h(x - x_s),
//
// Lap_h u = sum_d L_d u, L_d u = (w_0 u + sum_{k=1..R} w_k (u(x - k h_d e_d) + u(x + k h_d e_d))) / h_d^2,
// the centred second differences of order 2R (-fd_order 2|4|8, weights in differentiator.hpp). The
// last term is a point source (survey.hpp).
// Ends of non-periodic directions (-<m>_boundary): "walls" (default) holds the end points at u = v = 0
// and gives them no equation, the state beyond a wall being the odd reflection of the inside (so that
// the fourth-order stencil next to a wall stays consistent with u = 0 on it); "zero_outside" updates
// every point and takes the values outside the grid as 0.
//
// Absorbing layers along the walls, of width W, at fraction s_d = (W - depth_d)/W into the layer along d:
//   sponge (-<m>_sponge_width W, -<m>_sponge_strength sigma_max; W = 0.15 in 2D, 0 in 1D):
//     sigma = sigma_max s^2 (s from the nearest wall). The system keeps the second-order form
//     (G_u = v, G_v = a(u) - sigma v) that the leapfrog integrates, the damping in its kicks.
//   perfectly matched layer (-<m>_pml_width W, -<m>_pml_strength sigma_max, -<m>_pml_alpha alpha_max):
//     the complex-frequency-shifted stretching d/dx_d -> (1/s_d) d/dx_d, s_d = 1 + sigma_d/(alpha_d + i omega),
//     sigma_d = sigma_max s_d^2, alpha_d = alpha_max (1 - s_d), applied twice to u_tt = c^2 sum_d u_{x_d x_d}.
//     Each application is a memory variable (1/s - 1) f = psi, psi_t = -(alpha + sigma) psi - sigma f:
//       v_t     = c^2 sum_d (L_d u + D_d phi_d + chi_d) + w(t) delta_h,
//       phi_d,t = -(alpha_d + sigma_d) phi_d - sigma_d D_d u,
//       chi_d,t = -(alpha_d + sigma_d) chi_d - sigma_d (L_d u + D_d phi_d),
//     D_d the centred first difference of order 2R. phi and chi start at 0 and stay 0 outside the layer,
//     where the equation is the plain wave's. The default sigma_max = 1.5 ln(1000) / W is the strength
//     whose continuous reflection is 1e-3 for c = 1 (scale it with c).
// The parameter c is one scalar (-<m>_c_field 0) or a field (-<m>_c_field 1), never below -<m>_c_min.
// <m> is "wave" in 1D, "wave2d" in 2D and "wave3d" in 3D.
//
// Initial condition (-<m>_ic), from the pulse P(x) = exp(-|x - x_c|^2 / w^2) (-<m>_ic_width w; centre
// -wave_ic_center in 1D, -<m>_ic_x, -<m>_ic_y (and -wave3d_ic_z) in 2D and 3D):
//   "pulse" or "rest"  u0 = P, v0 = 0;
//   "travelling"       u0 = P, v0 = -c dP/dx, a pulse moving in +x (the 1D default);
//   "zero"             u0 = v0 = 0, for waves made by point sources only (the 2D default);
//   "two_level"        u0 = P, v0 = (u^1 - u^0)/dt - (dt/2) c^2 Lap_h u^0 with u^0 = P, u^1 = P(x - c dt e_x):
//                      the first Stormer-Verlet step of the integrator's dt (Model::set_time_step) lands
//                      on u^1, so that the leapfrog reproduces u^{k+1} = 2 u^k - u^{k-1} + dt^2 c^2 Lap_h u^k.
// The travelling and two-level starts depend on c: dU0/dc enters the gradient.
//
// Every Jacobian, transpose and adjoint sweep is derived from rhs() and initial() by the pointwise layer.
//
//   mpiexec -n 2 ./flexipde -task gradient -wave_c_field 1 -wave_c 0.9 -check_fd
//   mpiexec -n 2 ./flexipde -task taylor -wave_c_field 1 -wave_c 0.9 -true_wave_c 1.0 -wave_ic zero
//           -objective_type receivers -survey_sources_x 0.3,0.7 -survey_receivers_spread 0.05,0.95,10 -ts_max_time 1
//   mpiexec -n 2 ./flexipde -task gradient -ts_type leapfrog -wave_ic two_level -wave_boundary zero_outside
//           -fd_order 4 -wave_c_field 1 -wave_c 0.9 -check_fd
//   mpiexec -n 2 ./flexipde -model wave2d -task gradient -ts_type leapfrog -wave2d_sponge_width 0
//           -wave2d_ic pulse -wave2d_c_field 1 -wave2d_c 0.9 -true_wave2d_c 1
//   mpiexec -n 2 ./flexipde -model wave2d -task taylor -ts_type leapfrog -fd_order 8 -da_grid_x 41 -da_grid_y 41
//           -wave2d_c_field 1 -true_wave2d_c 1.1 -objective_type receivers -survey_sources_x 0.5 -survey_sources_y 0.3
//           -survey_receivers_spread 0.2,0.8,7 -survey_receivers_y 0.7 -ts_max_time 0.6 -ts_dt 2e-3
//   mpiexec -n 2 ./flexipde -model wave2d -task taylor -da_grid_x 41 -da_grid_y 41 -wave2d_c_field 1
//           -true_wave2d_c 1.1 -objective_type receivers -survey_sources_x 0.5 -survey_sources_y 0.3
//           -survey_receivers_spread 0.2,0.8,7 -survey_receivers_y 0.7 -ts_max_time 0.6 -ts_dt 2e-3
//   mpiexec -n 2 ./flexipde -model wave2d -task gradient -wave2d_pml_width 0.15 -wave2d_c_field 1
//           -true_wave2d_c 1.1 -objective_type receivers -survey_sources_x 0.5 -survey_sources_y 0.5
//           -survey_receivers_spread 0.2,0.8,7 -survey_receivers_y 0.7 -ts_max_time 0.6 -ts_dt 2e-3
//   mpiexec -n 2 ./flexipde -model wave3d -task taylor -ts_type leapfrog -da_grid_x 21 -da_grid_y 21 -da_grid_z 21
//           -wave3d_c_field 1 -true_wave3d_c 1.1 -objective_type receivers -survey_sources_x 0.5 -survey_sources_y 0.5
//           -survey_sources_z 0.3 -survey_receivers_spread 0.2,0.8,5 -survey_receivers_y 0.5 -survey_receivers_z 0.7
//           -ts_max_time 0.4 -ts_dt 5e-3
//   (each one command line)
#include "flexipde/differentiator.hpp"
#include "flexipde/pointwise.hpp"

namespace flexipde {

enum class Absorber { None, Sponge, Pml };

// D dimensions, stencil radius R (order 2R), with no absorbing layer, the sponge or the PML.
template <int D, int R, Absorber A>
class AcousticWave {
  static constexpr bool Damped = A == Absorber::Sponge, Pml = A == Absorber::Pml;

public:
  // u, v, and with the PML phi_d (2 + d) and chi_d (2 + D + d)
  static constexpr int dim = D, components = Pml ? 2 + 2 * D : 2, radius = R, parameters = 1;
  static constexpr int second_order_pairs = 1, forced_component = 1;
  static constexpr int coefficients = Damped ? 1 : 0; // the sponge's sigma(x)
  static constexpr bool linear = true;
  enum Parameter { c = 0 };

  const char *name() const { return D == 1 ? "wave" : D == 2 ? "wave2d" : "wave3d"; }
  const char *component_name(int k) const {
    static const char *names[] = {"u", "v", "phi_x", "phi_y", "phi_z", "chi_x", "chi_y", "chi_z"};
    return k < 2 ? names[k] : k < 2 + D ? names[k] : names[5 + (k - 2 - D)];
  }
  void grid_defaults(GridOptions &o) const {
    if (D == 2) o.n = o.ny = 101;
    if (D == 3) o.n = o.ny = o.nz = 41;
  }
  bool second_order_active() const { return !Pml; } // (the PML's memory variables have no such form)
  bool odd_walls() const { return boundary_ == Walls; }
  // The walls have no equation: the stencils read them as 0 whatever the state holds (no wall columns in dG/dU).
  bool held_walls() const { return boundary_ == Walls; }
  void set_time_step(PetscReal dt) { dt_ = dt; }

  PetscErrorCode setup(const Grid &grid, Declarations &decl) {
    const char *ics[] = {"travelling", "rest", "zero", "two_level", "pulse"}, *ends[] = {"walls", "zero_outside"};
    const std::string prefix = std::string(name()) + "_", title = std::string("Acoustic wave u_tt = c^2 Lap u (") + name() + ")";
    PetscBool c_field = PETSC_FALSE, sponge_set = PETSC_FALSE;
    PetscReal c_min = 0.01;
    PetscFunctionBeginUser;
    ic_ = D == 1 ? Travelling : Zero;
    ic_width_ = D == 1 ? 0.2 : 0.05;
    sponge_width_ = D == 1 ? 0.0 : 0.15;
    PetscOptionsBegin(grid.comm(), prefix.c_str(), title.c_str(), "Wave");
    PetscCall(PetscOptionsBool("-c_field", "Speed c is a field (one value per grid point), else one scalar", "Wave", c_field,
                               &c_field, nullptr));
    PetscCall(PetscOptionsReal("-c_min", "Smallest admissible speed: optimisers never go below it", "Wave", c_min, &c_min,
                               nullptr));
    PetscCall(PetscOptionsEList("-ic", "Initial condition (rest and pulse are the same; two_level: u^0 = pulse, u^1 = "
                                "pulse(x - c dt), the leapfrog's first step lands on u^1)", "Wave", ics, 5, ics[ic_], &ic_, nullptr));
    for (int d = 0; d < D; ++d)
      PetscCall(PetscOptionsReal(centre_option(d), "Centre of the initial pulse in this direction", "Wave", ic_x_[d], &ic_x_[d],
                                 nullptr));
    PetscCall(PetscOptionsReal("-ic_width", "Width w of the pulse exp(-|x - x_c|^2 / w^2)", "Wave", ic_width_, &ic_width_,
                               nullptr));
    PetscCall(PetscOptionsEList("-boundary", "Ends of non-periodic directions: walls (the end points held at 0) or "
                                "zero_outside (all points updated, values outside the grid 0)", "Wave", ends, 2, ends[boundary_],
                                &boundary_, nullptr));
    PetscCall(PetscOptionsReal("-sponge_width", "Width W of the absorbing sponge along each wall (0: none)", "Wave",
                               sponge_width_, &sponge_width_, &sponge_set));
    PetscCall(PetscOptionsReal("-sponge_strength", "Damping sigma_max at the outer edge of the sponge", "Wave", sigma_max_,
                               &sigma_max_, nullptr));
    PetscCall(PetscOptionsReal("-pml_width", "Width W of the perfectly matched layer along each wall (0: none; replaces "
                               "the sponge)", "Wave", pml_width_, &pml_width_, nullptr));
    pml_strength_ = pml_width_ > 0 ? 1.5 * std::log(1000.0) / pml_width_ : 0;
    PetscCall(PetscOptionsReal("-pml_strength", "PML damping sigma_max at its outer edge (default 1.5 ln(1000)/W: "
                               "reflection 1e-3 for c = 1)", "Wave", pml_strength_, &pml_strength_, nullptr));
    PetscCall(PetscOptionsReal("-pml_alpha", "PML frequency shift alpha_max at its inner edge (0 at the outer edge)", "Wave",
                               pml_alpha_, &pml_alpha_, nullptr));
    PetscOptionsEnd();
    if (pml_width_ > 0 && !sponge_set) sponge_width_ = 0;
    PetscCheck(pml_width_ >= 0 && pml_strength_ >= 0 && pml_alpha_ >= 0, grid.comm(), PETSC_ERR_ARG_OUTOFRANGE,
               "-%spml_width, -%spml_strength and -%spml_alpha must be non-negative", prefix.c_str(), prefix.c_str(),
               prefix.c_str());
    PetscCheck(!(pml_width_ > 0 && sponge_width_ > 0), grid.comm(), PETSC_ERR_ARG_INCOMP,
               "-%spml_width and -%ssponge_width: choose one absorbing layer (the other's width 0)", prefix.c_str(),
               prefix.c_str());
    PetscCheck(c_min > 0, grid.comm(), PETSC_ERR_ARG_OUTOFRANGE, "-%sc_min must be positive, got %g", prefix.c_str(), (double)c_min);
    PetscCheck(ic_width_ > 0, grid.comm(), PETSC_ERR_ARG_OUTOFRANGE, "-%sic_width must be positive, got %g", prefix.c_str(),
               (double)ic_width_);
    PetscCheck(sponge_width_ >= 0 && sigma_max_ >= 0, grid.comm(), PETSC_ERR_ARG_OUTOFRANGE,
               "-%ssponge_width and -%ssponge_strength must be non-negative", prefix.c_str(), prefix.c_str());
    SecondDerivative d2; // reads and checks -fd_order
    PetscCall(SecondDerivative::from_options(grid.comm(), nullptr, 2, d2));
    PetscCheck(d2.half_width() == R, grid.comm(), PETSC_ERR_PLIB, "wave: stencil radius %d for -fd_order %d", R,
               (int)(2 * d2.half_width()));
    bool any_wall = false;
    spectral_radius_ = 0;
    for (int d = 0; d < D; ++d) {
      spectral_radius_ += d2.spectral_radius(grid.h(d));
      lo_[d] = grid.lower(d), hi_[d] = grid.upper(d);
      periodic_[d] = grid.periodic(d);
      layer_scale_[d] = periodic_[d] || pml_width_ == 0 ? 0 : 1 / pml_width_;
      n_[d] = grid.n(d);
      any_wall = any_wall || !periodic_[d];
      PetscCheck(periodic_[d] || 2 * pml_width_ < hi_[d] - lo_[d], grid.comm(), PETSC_ERR_ARG_OUTOFRANGE,
                 "-%spml_width %g: the layers of two opposite walls would overlap (the domain is %g wide)", prefix.c_str(),
                 (double)pml_width_, (double)(hi_[d] - lo_[d]));
    }
    PetscCheck(!Pml || any_wall, grid.comm(), PETSC_ERR_ARG_WRONG, "-%spml_width: the grid has no wall to absorb at "
               "(-grid_periodic 0)", prefix.c_str());
    PetscCheck(boundary_ == Walls || any_wall, grid.comm(), PETSC_ERR_ARG_WRONG,
               "-%sboundary zero_outside needs a non-periodic grid (-grid_periodic 0)", prefix.c_str());
    decl.parameter(c, prefix + "c", c_field, c_min, 1.0);
    PetscFunctionReturn(0);
  }

  // G = [v ; c^2 Lap u - sigma v], or with the PML [v ; c^2 sum_d (L_d u + D_d phi_d + chi_d) ; G_phi ; G_chi];
  // 0 on the walls.
  template <class P> void rhs(const P &pt, typename P::Number *g) const {
    using T = typename P::Number;
    if (held(pt)) {
      for (int k = 0; k < components; ++k) g[k] = T(0.0);
      return;
    }
    T lap = T(0.0);
    for_each_direction<D>([&](auto d) {
      T s = weight(0) * pt.u(0, 0);
      for (int k = 1; k <= R; ++k) s += weight(k) * (along(pt, 0, d, -k) + along(pt, 0, d, k));
      s *= sqr(pt.inv_h(d));
      if constexpr (Pml) {
        const int phi = 2 + d, chi = 2 + D + d;
        const PetscReal f = layer_fraction(pt, d), sigma = pml_strength_ * f * f, decay = sigma + pml_alpha_ * (1 - f);
        T du = T(0.0), dphi = T(0.0);
        for (int k = 1; k <= R; ++k) {
          du += first_weight(k) * (along(pt, 0, d, k) - along(pt, 0, d, -k));
          dphi += first_weight(k) * (along(pt, phi, d, k) - along(pt, phi, d, -k));
        }
        s += dphi * pt.inv_h(d); // (1/s_d) d/dx_d of (1/s_d) du/dx_d, less its memory chi_d
        g[phi] = -decay * pt.u(phi, 0) - sigma * (du * pt.inv_h(d));
        g[chi] = -decay * pt.u(chi, 0) - sigma * s;
        s += pt.u(chi, 0);
      }
      lap += s;
    });
    g[0] = pt.u(1, 0);
    g[1] = sqr(pt.param(c)) * lap;
    if constexpr (Damped) g[1] -= pt.coefficient(0) * pt.u(1, 0);
  }
  template <class P> PetscReal coefficient(int, const P &pt) const { return sponge(pt); }

  template <class P> void initial(const P &pt, typename P::Number *u) const {
    using T = typename P::Number;
    for (int k = 0; k < components; ++k) u[k] = T(0.0);
    if (held(pt) || ic_ == Zero) return;
    const PetscReal u0 = pulse(pt, 0.0);
    u[0] = u0;
    if (ic_ == Travelling) u[1] = pt.param(c) * (2 * (pt.x(0) - ic_x_[0]) / sqr(ic_width_) * u0); // -c dP/dx
    if (ic_ == TwoLevel) {
      const T cp = pt.param(c);
      u[1] = (pulse(pt, cp * dt_) - u0) / dt_ - (0.5 * dt_) * sqr(cp) * lap_pulse(pt);
    }
  }
  PetscErrorCode check_initial(MPI_Comm comm) const {
    PetscFunctionBeginUser;
    PetscCheck(ic_ != TwoLevel || dt_ > 0, comm, PETSC_ERR_ORDER,
               "-%s_ic two_level needs the integrator's step: make the initial condition through "
               "Simulation::initial_condition (Model::set_time_step)", name());
    PetscFunctionReturn(0);
  }

  // Point sources force v everywhere but on the walls, which stay at u = v = 0.
  bool forced(PetscInt i, PetscInt j, PetscInt k) const {
    return boundary_ != Walls || !(on_wall(0, i) || (D > 1 && on_wall(1, j)) || (D > 2 && on_wall(2, k)));
  }

  // Eigenvalues of dG/dU: +-i c sqrt(eig(-Lap_h)) in the interior, damped by at most sigma_max.
  PetscErrorCode spectrum(const ParameterBounds &b, Spectrum *s) const {
    s->imag_radius = b.max[c] * std::sqrt(spectral_radius_);
    s->real_radius = Damped ? sigma_max_ : Pml ? pml_strength_ + pml_alpha_ : 0;
    return 0;
  }
  PetscErrorCode check_parameters(const ParameterBounds &b, MPI_Comm comm) const {
    PetscFunctionBeginUser;
    PetscCheck(b.min[c] > 0, comm, PETSC_ERR_ARG_OUTOFRANGE, "Wave speed must be positive, found c = %g", (double)b.min[c]);
    PetscFunctionReturn(0);
  }

private:
  enum Start { Travelling, Rest, Zero, TwoLevel, Pulse };
  enum Boundary { Walls, ZeroOutside };

  static const char *centre_option(int d) {
    if (D == 1) return "-ic_center";
    return d == 0 ? "-ic_x" : d == 1 ? "-ic_y" : "-ic_z";
  }
  // The centred second-difference weights: w_0 u_0 + sum_k w_k (u_-k + u_k), over h^2.
  static constexpr double weight(int k) { return SecondDerivative::weight(2 * R, k); }
  static constexpr double first_weight(int k) { return FirstDerivative::weight(2 * R, k); }
  // Component q at k points from the point along direction d.
  template <class P> static auto along(const P &pt, int q, int d, int k) {
    return d == 0 ? pt.u(q, k) : d == 1 ? pt.u(q, 0, k) : pt.u(q, 0, 0, k);
  }
  // How far into the PML along direction d, from 0 at its inner edge to 1 on the wall (0 outside it, and
  // along periodic directions, which have none).
  template <class P> PetscReal layer_fraction(const P &pt, int d) const {
    const PetscReal depth = std::min(pt.x(d) - lo_[d], hi_[d] - pt.x(d));
    return std::max<PetscReal>(0, pml_width_ - depth) * layer_scale_[d];
  }
  bool on_wall(int d, PetscInt i) const { return !periodic_[d] && (i == 0 || i == n_[d] - 1); }
  template <class P> bool held(const P &pt) const { return boundary_ == Walls && pt.on_wall(); }
  template <class P> PetscReal sponge(const P &pt) const {
    PetscReal depth = sponge_width_;
    for (int d = 0; d < D; ++d)
      if (!periodic_[d]) depth = std::min(depth, std::min(pt.x(d) - lo_[d], hi_[d] - pt.x(d)));
    const PetscReal s = std::max<PetscReal>(0, sponge_width_ - depth) / sponge_width_;
    return sigma_max_ * s * s;
  }

  // P at the point moved by `shift` along x and by k points along direction d (shift may carry
  // derivatives in c).
  template <class P, class T> T pulse(const P &pt, const T &shift, int d = 0, PetscInt k = 0) const {
    T r2 = T(0.0);
    for (int e = 0; e < D; ++e) r2 += sqr((pt.x(e) + (e == d ? k * pt.h(e) : 0.0) - (e == 0 ? shift : T(0.0)) - ic_x_[e]) / ic_width_);
    return exp(-r2);
  }
  // u^0 = P k points along direction d from the point, as the stencils see it: a periodic image, 0 on a
  // wall, the odd reflection beyond it, or 0 outside the grid (zero_outside).
  template <class P> PetscReal pulse_seen(const P &pt, int d, PetscInt k) const {
    const PetscInt i = pt.index(d), n = n_[d];
    PetscInt g = i + k;
    PetscReal sign = 1;
    if (periodic_[d]) g = (g % n + n) % n;
    else if (g < 0 || g >= n) {
      if (boundary_ == ZeroOutside) return 0;
      g = g < 0 ? -g : 2 * (n - 1) - g, sign = -1;
    }
    if (boundary_ == Walls && on_wall(d, g)) return 0;
    return sign * pulse(pt, 0.0, d, g - i);
  }
  template <class P> PetscReal lap_pulse(const P &pt) const {
    PetscReal lap = 0;
    for (int d = 0; d < D; ++d) {
      PetscReal s = weight(0) * pulse(pt, 0.0);
      for (int k = 1; k <= R; ++k) s += weight(k) * (pulse_seen(pt, d, -k) + pulse_seen(pt, d, k));
      lap += s * sqr(pt.inv_h(d));
    }
    return lap;
  }

  PetscInt ic_ = Travelling, boundary_ = Walls;
  PetscReal ic_x_[D], ic_width_ = 0.2, dt_ = 0;
  PetscReal sponge_width_ = 0, sigma_max_ = 60.0, spectral_radius_ = 0;
  PetscReal pml_width_ = 0, pml_strength_ = 0, pml_alpha_ = 10.0;
  PetscReal lo_[D], hi_[D];
  PetscInt n_[D];
  PetscReal layer_scale_[D]; // 1/W along directions with walls, 0 along periodic ones
  bool periodic_[D];

public:
  AcousticWave() {
    for (int d = 0; d < D; ++d) ic_x_[d] = 0.5, lo_[d] = 0, hi_[d] = 1, n_[d] = 1, layer_scale_[d] = 0, periodic_[d] = false;
  }
};

// The stencil radius and the absorbing layer are compile-time constants of the sweeps (no branch in
// their loops): -fd_order, -<m>_sponge_width and -<m>_pml_width pick the instance. The instances are
// compiled in four units, so that they build in parallel: this file (1D and 2D, no layer or the
// sponge), wave_pml.cpp (1D and 2D, the PML), wave3d.cpp and wave3d_pml.cpp (3D).
template <int D, int R> std::unique_ptr<Model> make_wave_plain(bool sponge) {
  if (sponge) return std::make_unique<PointwiseModel<AcousticWave<D, R, Absorber::Sponge>>>();
  return std::make_unique<PointwiseModel<AcousticWave<D, R, Absorber::None>>>();
}
template <int D, int R> std::unique_ptr<Model> make_wave_pml() {
  return std::make_unique<PointwiseModel<AcousticWave<D, R, Absorber::Pml>>>();
}
#define FLEXIPDE_WAVE_INSTANCES(D, kind, ...)                                                                        \
  template std::unique_ptr<Model> make_wave_##kind<D, 1>(__VA_ARGS__);                                              \
  template std::unique_ptr<Model> make_wave_##kind<D, 2>(__VA_ARGS__);                                              \
  template std::unique_ptr<Model> make_wave_##kind<D, 4>(__VA_ARGS__);
#if defined(FLEXIPDE_WAVE_PML_UNIT)
FLEXIPDE_WAVE_INSTANCES(1, pml)
FLEXIPDE_WAVE_INSTANCES(2, pml)
#elif defined(FLEXIPDE_WAVE_3D_UNIT)
FLEXIPDE_WAVE_INSTANCES(3, plain, bool)
#elif defined(FLEXIPDE_WAVE_3D_PML_UNIT)
FLEXIPDE_WAVE_INSTANCES(3, pml)
#else
extern template std::unique_ptr<Model> make_wave_plain<3, 1>(bool);
extern template std::unique_ptr<Model> make_wave_plain<3, 2>(bool);
extern template std::unique_ptr<Model> make_wave_plain<3, 4>(bool);
extern template std::unique_ptr<Model> make_wave_pml<1, 1>();
extern template std::unique_ptr<Model> make_wave_pml<1, 2>();
extern template std::unique_ptr<Model> make_wave_pml<1, 4>();
extern template std::unique_ptr<Model> make_wave_pml<2, 1>();
extern template std::unique_ptr<Model> make_wave_pml<2, 2>();
extern template std::unique_ptr<Model> make_wave_pml<2, 4>();
extern template std::unique_ptr<Model> make_wave_pml<3, 1>();
extern template std::unique_ptr<Model> make_wave_pml<3, 2>();
extern template std::unique_ptr<Model> make_wave_pml<3, 4>();
template <int D, int R> std::unique_ptr<Model> make_wave_absorbing(PetscReal sponge, PetscReal pml) {
  if (pml > 0) return make_wave_pml<D, R>();
  return make_wave_plain<D, R>(sponge > 0); // (negative widths are refused at setup)
}
template <int D> std::unique_ptr<Model> make_wave() {
  PetscInt order = 2;
  PetscReal sponge = D == 1 ? 0.0 : 0.15, pml = 0;
  PetscBool sponge_set = PETSC_FALSE;
  const std::string m = std::string("-") + (D == 1 ? "wave" : D == 2 ? "wave2d" : "wave3d") + "_";
  (void)PetscOptionsGetInt(nullptr, nullptr, "-fd_order", &order, nullptr);
  (void)PetscOptionsGetReal(nullptr, nullptr, (m + "sponge_width").c_str(), &sponge, &sponge_set);
  (void)PetscOptionsGetReal(nullptr, nullptr, (m + "pml_width").c_str(), &pml, nullptr);
  if (pml > 0 && !sponge_set) sponge = 0; // (both set: refused at setup)
  if (order == 4) return make_wave_absorbing<D, 2>(sponge, pml);
  if (order == 8) return make_wave_absorbing<D, 4>(sponge, pml);
  return make_wave_absorbing<D, 1>(sponge, pml); // other orders are refused at setup
}

static const ModelRegistration wave_1d("wave", make_wave<1>), wave_2d("wave2d", make_wave<2>), wave_3d("wave3d", make_wave<3>);
#endif

} // namespace flexipde
