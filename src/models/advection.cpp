// Linear advection-diffusion of one scalar on a periodic grid, in 1D or 2D:
//
//   1D (default):          u_t + a u_x         = (D u_x)_x                on [x0, x1) periodic
//   2D (-advection_dim 2): u_t + a u_x + b u_y = (D u_x)_x + (D u_y)_y    on [x0, x1) x [y0, y1)
//   u(x, 0) = A s(x)
//
// The velocities a (-advection_a) and, in 2D, b (-advection_b) are scalar parameters. Diffusion is
// optional: -advection_diffusion (default on exactly when -advection_D, -advection_D_field or
// -advection_D_profile is given) adds the parameter D, a scalar or a field (-advection_D_field 1).
// Without it the scene declares no D and G has no diffusion term.
//
// Space (-advection_scheme), per direction d with spacing h, v the velocity along d:
//   fd2       h v (u_d)_i = v (u_{i+1} - u_{i-1}) / 2                                  order 2
//   fd4       h v (u_d)_i = v (u_{i-2} - 8u_{i-1} + 8u_{i+1} - u_{i+2}) / 12           order 4
//   upwind    h v (u_d)_i = v+ (u_i - u_{i-1}) + v- (u_{i+1} - u_i),  v+ = max(v, 0), v- = min(v, 0):
//             order 1, monotone; at v = 0 dG/dv is the backward difference
//   spectral  u_d = F^-1 i kappa_d F u (FFTW-MPI, include/flexipde/spectral.hpp); N even
// Diffusion, finite differences, in flux form G_i += -(B^T diag(D_f) B u)_i with the face gradient B
// and the face diffusivity D_f at f = i + 1/2 (-fd_order, default 4 with fd4, else 2):
//   order 2: h (Bu)_f = u_{i+1} - u_i,                              D_f = (D_i + D_{i+1}) / 2
//   order 4: h (Bu)_f = (u_{i-1} - 27u_i + 27u_{i+1} - u_{i+2}) / 24,  D_f = (-D_{i-1} + 9D_i + 9D_{i+1} - D_{i+2}) / 16
// symmetric, negative semi-definite while D_f >= 0, conservative, of the stated order for a smooth D.
// Diffusion, spectral: a scalar D multiplies the Laplacian F^-1 (-|kappa|^2) F u; a field D gives
// sum_d E_d ((P D) .* E_d u), E_d = P d/dx_d, P the 2/3-rule truncation: both factors of the flux and
// the flux itself are truncated (de-aliased), and the operator is symmetric negative semi-definite
// while P D >= 0 (checked). dG/dD is then P(...): the gradient with respect to D is truncated too.
//
// Finite differences state G in flux form, the advection as a source S = -sum_d v_d u_d and the
// diffusive flux -D_f (Bu)_f at the faces (source() and flux() below); the spectral scheme states G at
// one point (rhs()). The pointwise layer (include/flexipde/pointwise.hpp) derives dG/dU, dG/dp, their
// transposes and the adjoint sweeps. The spectral scheme is stated through its non-local
// maps: auxiliary fields read at points (u_d, the Laplacian, E_d u), outputs (the flux (P D) E_d u)
// that enter G through E_d, and the parameter map P of a field D.
//
// Spectrum (the explicit stability check): with no D or a scalar D the operator is a sum of circulants,
// normal, and its eigenvalues, the symbols per mode, are all passed. With a field D they lie in the
// field of values, inside W(advection) + [-Dmax rho, 0] (rho the largest |symbol|^2 of the face
// gradients): its boundary is passed.
//
// Initial condition (-advection_ic, u0 = A s; -advection_ic_amplitude A, a parameter with
// -advection_ic_amplitude_param 1):
//   sinusoid  s = sin(2 pi m (x - x0) / Lx [+ 2 pi m_y (y - y0) / Ly] + phi)
//   gaussian  s = exp(-|d|^2 / w^2)                       d the periodic distance to the centre
//   square    s = 1 where |d_x| < w/2 [and |d_y| < w/2], else 0
//
//   mpiexec -n 2 ./flexipde -model advection -grid_periodic 1 -grid_x1 6.283185307179586 -da_grid_x 64
//           -ts_dt 0.01 -ts_max_time 1 -task taylor -objective_type mean_square
//           -advection_ic_amplitude_param 1 -advection_D 0.05 -advection_D_field 1
//   mpiexec -n 2 ./flexipde -model advection -grid_periodic 1 -task gradient -advection_scheme upwind
//           -advection_a 0.8 -true_advection_a 1 -ts_type cn -ts_dt 1e-3 -ts_max_time 0.5 -check_fd
//   mpiexec -n 2 ./flexipde -model advection -grid_periodic 1 -grid_x1 6.283185307179586 -da_grid_x 64
//           -advection_scheme spectral -advection_a 0.8 -true_advection_a 1 -ts_dt 0.01 -ts_max_time 1
//           -task gradient -check_fd
//   mpiexec -n 2 ./flexipde -model advection -advection_dim 2 -da_grid_x 32 -da_grid_y 32
//           -advection_a 0.8 -advection_b 0.5 -true_advection_b 0.6 -advection_D 0.01 -ts_dt 0.005
//           -ts_max_time 0.2 -task gradient -check_fd
//   (each one command line)
#include "flexipde/differentiator.hpp"
#include "flexipde/pointwise.hpp"
#include "flexipde/spectral.hpp"
#include <algorithm>
#include <complex>

namespace flexipde {
namespace advection {

const char *const schemes[] = {"fd2", "fd4", "upwind", "spectral"};
enum Scheme : int { FD2, FD4, UPWIND, SPECTRAL };
// The diffusion term: none; finite-difference faces of order 2 or 4; spectral with a scalar or a field D.
enum Diffusion : int { NONE, FACES2, FACES4, SCALAR_D, FIELD_D };
const char *const ic_names[] = {"sinusoid", "gaussian", "square"};
enum InitialCondition : PetscInt { SINUSOID, GAUSSIAN, SQUARE };
constexpr PetscReal default_diffusion = 0.01; // D when diffusion is on without a value
constexpr PetscInt default_points_2d = 64;
using cplx = std::complex<PetscReal>;

// What fixes the equations' shape (dimension, stencil, non-local maps), read before the grid exists.
struct Choice {
  PetscInt dim = 1, scheme = FD2, order = 2;
  PetscBool diffusion = PETSC_FALSE, field = PETSC_FALSE;
  int diffusion_term() const {
    if (!diffusion) return NONE;
    if (scheme == SPECTRAL) return field ? FIELD_D : SCALAR_D;
    return order == 4 ? FACES4 : FACES2;
  }
};
inline PetscErrorCode read_choice(Choice &c) {
  PetscBool given[3];
  PetscFunctionBeginUser;
  PetscCall(PetscOptionsGetInt(nullptr, nullptr, "-advection_dim", &c.dim, nullptr));
  PetscCall(PetscOptionsGetEList(nullptr, nullptr, "-advection_scheme", schemes, 4, &c.scheme, nullptr));
  PetscCall(PetscOptionsHasName(nullptr, nullptr, "-advection_D", &given[0]));
  PetscCall(PetscOptionsHasName(nullptr, nullptr, "-advection_D_field", &given[1]));
  PetscCall(PetscOptionsHasName(nullptr, nullptr, "-advection_D_profile", &given[2]));
  c.diffusion = given[0] || given[1] || given[2] ? PETSC_TRUE : PETSC_FALSE;
  PetscCall(PetscOptionsGetBool(nullptr, nullptr, "-advection_diffusion", &c.diffusion, nullptr));
  PetscCall(PetscOptionsGetBool(nullptr, nullptr, "-advection_D_field", &c.field, nullptr));
  c.order = c.scheme == FD4 ? 4 : 2;
  PetscCall(PetscOptionsGetInt(nullptr, nullptr, "-fd_order", &c.order, nullptr));
  PetscFunctionReturn(0);
}

// The spectral scheme's operators: d/dx_d, the Laplacian, E_d = P d/dx_d, and P itself (dealias).
struct SpectralMaps {
  SpectralDifferentiator fft;
  SpectralDifferentiator::Symbol derivative[2], dealiased[2], laplacian;
  std::vector<const SpectralDifferentiator::Symbol *> aux;     // the auxiliary fields' symbols, in order
  std::vector<SpectralDifferentiator::Symbol> aux_t, dealiased_t; // their transposes: conj(s)
  std::vector<const SpectralDifferentiator::Symbol *> aux_adjoint; // aux_t, in order
  std::vector<const SpectralDifferentiator::Symbol *> outputs, outputs_t; // the outputs' maps E_m and their transposes
  mutable SpectralDifferentiator::Symbol combined;                // sum_k r_k (the auxiliary fields' symbols)
  mutable std::vector<PetscScalar> combined_r;                    // ... for these r
  OwnedVec work;
};
struct NoMaps {};

// The equations in Dim dimensions for scheme S and diffusion term Df (template arguments, so that the
// sweeps have no branch on them).
template <int Dim, int S, int Df>
class Advection {
  static constexpr bool spectral = S == SPECTRAL;
  enum Parameter { A_VEL = 0, B_VEL = 1, DIFF = Dim, AMP = Dim + 1 }; // the velocity along d is slot d

public:
  static constexpr int dim = Dim, components = 1, parameters = Dim + 2;
  static constexpr int rhs_parameters = Dim + 1; // the amplitude enters U0 alone
  static constexpr int radius = spectral ? 0 : std::max(S == FD4 ? 2 : 1, Df == FACES4 ? 3 : 1);
  static constexpr int auxiliaries = spectral ? Dim + (Df == SCALAR_D ? 1 : Df == FIELD_D ? Dim : 0) : 0;
  static constexpr int outputs = Df == FIELD_D ? Dim : 0;
  static constexpr bool linear = true;
  static constexpr bool flux_form = !spectral; // finite differences: source() and flux(); spectral: rhs()

  const char *name() const { return "advection"; }
  const char *component_name(int) const { return "u"; }
  void grid_defaults(GridOptions &o) const {
    o.periodic = o.periodic_y = PETSC_TRUE; // the only boundary offered
    if (Dim == 2) o.n = o.ny = default_points_2d;
  }

  PetscErrorCode setup(const Grid &grid, Declarations &decl) {
    Choice c;
    PetscBool amplitude_param = PETSC_FALSE;
    PetscReal amplitude = 1;
    PetscFunctionBeginUser;
    PetscCall(read_choice(c));
    const PetscReal Lx = grid.x1() - grid.x0(), Ly = grid.y1() - grid.y0();
    center_[0] = 0.5 * (grid.x0() + grid.x1()), center_[1] = 0.5 * (grid.y0() + grid.y1());
    width_ = 0.1 * Lx;
    PetscOptionsBegin(grid.comm(), nullptr, "Advection-diffusion model u_t + a u_x (+ b u_y) = div(D grad u)", "Advection");
    PetscCall(PetscOptionsInt("-advection_dim", "Space dimension: 1, or 2 (velocity (a, b), grid -da_grid_x x -da_grid_y)",
                              "Advection", c.dim, &c.dim, nullptr));
    PetscCall(PetscOptionsEList("-advection_scheme", "First derivative of the advection: fd2, fd4 (centred), upwind, or spectral (FFTW)",
                                "Advection", schemes, 4, schemes[c.scheme], &c.scheme, nullptr));
    PetscCall(PetscOptionsBool("-advection_diffusion", "Add div(D grad u) with the parameter D (default: on when -advection_D* is given)",
                               "Advection", c.diffusion, &c.diffusion, nullptr));
    PetscCall(PetscOptionsBool("-advection_D_field", "Diffusivity D is a field (one value per grid point), else one scalar",
                               "Advection", c.field, &c.field, nullptr));
    PetscCall(PetscOptionsEList("-advection_ic", "Initial profile", "Advection", ic_names, 3, ic_names[ic_], &ic_, nullptr));
    PetscCall(PetscOptionsBool("-advection_ic_amplitude_param", "Declare the amplitude A of u0 = A s(x) as the parameter advection_ic_amplitude",
                               "Advection", amplitude_param, &amplitude_param, nullptr));
    if (!amplitude_param)
      PetscCall(PetscOptionsReal("-advection_ic_amplitude", "Amplitude A of u0 = A s(x)", "Advection", amplitude, &amplitude, nullptr));
    else PetscCall(PetscOptionsGetReal(nullptr, nullptr, "-advection_ic_amplitude", &amplitude, nullptr));
    PetscCall(PetscOptionsInt("-advection_ic_mode", "sinusoid: number m of periods in x", "Advection", mode_[0], &mode_[0], nullptr));
    PetscCall(PetscOptionsReal("-advection_ic_phase", "sinusoid: phase phi", "Advection", phase_, &phase_, nullptr));
    PetscCall(PetscOptionsReal("-advection_ic_center", "gaussian, square: centre (x)", "Advection", center_[0], &center_[0], nullptr));
    if (Dim == 2) {
      PetscCall(PetscOptionsInt("-advection_ic_mode_y", "sinusoid: number of periods in y", "Advection", mode_[1], &mode_[1], nullptr));
      PetscCall(PetscOptionsReal("-advection_ic_center_y", "gaussian, square: centre (y)", "Advection", center_[1], &center_[1], nullptr));
    }
    PetscCall(PetscOptionsReal("-advection_ic_width", "gaussian: width w of exp(-(d/w)^2); square: full width", "Advection",
                               width_, &width_, nullptr));
    PetscOptionsEnd();
    PetscCheck(c.dim == 1 || c.dim == 2, grid.comm(), PETSC_ERR_ARG_OUTOFRANGE,
               "-advection_dim %" PetscInt_FMT " is not offered: choose 1 or 2", c.dim);
    PetscCheck(grid.periodic() && (Dim == 1 || grid.periodic_y()), grid.comm(), PETSC_ERR_ARG_WRONG,
               "Model advection needs a periodic grid (-grid_periodic 1%s): inflow and outflow boundaries are not implemented",
               Dim == 2 ? " -grid_periodic_y 1" : "");
    PetscCheck(width_ > 0, grid.comm(), PETSC_ERR_ARG_OUTOFRANGE, "-advection_ic_width must be positive, got %g", (double)width_);
    if (c.diffusion && c.scheme != SPECTRAL) { // reads and checks -fd_order (listed by -help)
      SecondDerivative order;
      PetscCall(SecondDerivative::from_options(grid.comm(), nullptr, c.scheme == FD4 ? 4 : 2, order));
      c.order = order.order();
      PetscCheck(c.order == 2 || c.order == 4, grid.comm(), PETSC_ERR_ARG_OUTOFRANGE,
                 "-fd_order %" PetscInt_FMT " is not offered for advection's diffusion faces: choose 2 or 4", c.order);
    }
    // The model was made for the choice read before the grid existed; -help must not change it.
    PetscCheck(c.dim == Dim && c.scheme == S && c.diffusion_term() == Df, grid.comm(), PETSC_ERR_PLIB,
               "advection: the options changed between the model's creation and its setup");
    field_ = c.field;
    for (int d = 0; d < Dim; ++d) {
      n_[d] = d == 0 ? grid.n() : grid.ny(), length_[d] = d == 0 ? Lx : Ly, x0_[d] = d == 0 ? grid.x0() : grid.y0();
      h_[d] = length_[d] / n_[d];
    }
    if constexpr (spectral) PetscCall(make_spectral_maps(grid));

    decl.parameter(A_VEL, "advection_a", false, PETSC_NINFINITY, 1.0);
    if (Dim == 2) decl.parameter(B_VEL, "advection_b", false, PETSC_NINFINITY, 1.0);
    if (Df != NONE) decl.parameter(DIFF, "advection_D", c.field, 0.0, default_diffusion);
    else decl.fixed(DIFF, 0.0);
    if (amplitude_param) decl.parameter(AMP, "advection_ic_amplitude", false, PETSC_NINFINITY, amplitude);
    else decl.fixed(AMP, amplitude);
    PetscFunctionReturn(0);
  }

  // Finite differences: G = S - sum_d div_d F_d with the advection S = -sum_d v_d u_d and the
  // diffusive flux F_d = -D_f (B u)_f at the faces, h (div F)_i = sum_k w_k F_{i - n/2 + k + 1/2}.
  static constexpr auto divergence() {
    if constexpr (Df == FACES4) return std::array<double, 4>{1.0 / 24, -27.0 / 24, 27.0 / 24, -1.0 / 24};
    else if constexpr (Df == FACES2) return std::array<double, 2>{-1.0, 1.0};
    else return std::array<double, 0>{};
  }
  template <class P> void source(const P &pt, typename P::Number *g) const {
    g[0] = -advective<0>(pt) * pt.inv_h(0);
    if constexpr (Dim == 2) g[0] -= advective<1>(pt) * pt.inv_h(1);
  }
  // F_d at the face i + 1/2 along d (pt at i).
  template <class P, int d> void flux(const P &pt, Direction<d>, typename P::Number *F) const {
    using T = typename P::Number;
    if constexpr (Df == FACES4) {
      const T grad = (u<d>(pt, -1) - u<d>(pt, 2) + 27.0 * (u<d>(pt, 1) - u<d>(pt, 0))) * (1.0 / 24);
      const T D_face = (9.0 * (D<d>(pt, 0) + D<d>(pt, 1)) - D<d>(pt, -1) - D<d>(pt, 2)) * (1.0 / 16);
      F[0] = -D_face * grad * pt.inv_h(d);
    } else F[0] = -0.5 * (D<d>(pt, 0) + D<d>(pt, 1)) * (u<d>(pt, 1) - u<d>(pt, 0)) * pt.inv_h(d);
  }

  // Spectral: G = -sum_d v_d a_d (+ D a_Dim for a scalar D; g[1 + d]: the flux (P D) E_d u of a field D).
  template <class P> void rhs(const P &pt, typename P::Number *g) const {
    using T = typename P::Number;
    T G = T(0.0);
    for (int d = 0; d < Dim; ++d) G -= pt.param(d) * pt.aux(d);
    if constexpr (Df == SCALAR_D) G += pt.param(DIFF) * pt.aux(Dim);
    if constexpr (Df == FIELD_D)
      for (int d = 0; d < Dim; ++d) g[1 + d] = pt.param(DIFF) * pt.aux(Dim + d);
    g[0] = G;
  }

  template <class P> void initial(const P &pt, typename P::Number *u) const {
    u[0] = pt.param(AMP) * profile(pt.x(0), Dim == 2 ? pt.x(1) : 0.0);
  }

  // The spectral maps: a_k = L_k U (k < Dim: d/dx_k; then the Laplacian or E_d) and G += E_m h_m, with
  // their transposes, all fields at once (one forward transform of u for every auxiliary field, one
  // backward transform for a sum of several fields' terms), and sum_k r_k L_k as the one symbol
  // sum_k r_k s_k; a field D is read as P D.
  PetscErrorCode auxiliary_fields(Vec U, const Vec *a) const { return maps_.fft.apply_many(maps_.aux, U, {a, a + auxiliaries}); }
  PetscErrorCode auxiliary_fields_transpose(const Vec *z, Vec y) const {
    PetscFunctionBeginUser;
    PetscCall(maps_.fft.apply_sum(maps_.aux_adjoint, {z, z + auxiliaries}, maps_.work));
    PetscCall(VecAXPY(y, 1.0, maps_.work));
    PetscFunctionReturn(0);
  }
  PetscErrorCode auxiliary_fields_adjoint(Vec x, const Vec *w) const {
    return maps_.fft.apply_many(maps_.aux_adjoint, x, {w, w + auxiliaries});
  }
  PetscErrorCode auxiliary_combination(const PetscScalar *r, Vec x, Vec y, bool transpose) const {
    if (maps_.combined_r.size() != (size_t)auxiliaries || !std::equal(r, r + auxiliaries, maps_.combined_r.begin())) {
      maps_.combined_r.assign(r, r + auxiliaries);
      maps_.combined.assign(maps_.aux[0]->size(), 0.0);
      for (int k = 0; k < auxiliaries; ++k)
        for (size_t m = 0; m < maps_.combined.size(); ++m) maps_.combined[m] += r[k] * (*maps_.aux[k])[m];
    }
    return maps_.fft.apply(maps_.combined, x, y, transpose);
  }
  PetscErrorCode output_fields(const Vec *h, Vec G) const {
    PetscFunctionBeginUser;
    PetscCall(maps_.fft.apply_sum(maps_.outputs, {h, h + outputs}, maps_.work));
    PetscCall(VecAXPY(G, 1.0, maps_.work));
    PetscFunctionReturn(0);
  }
  PetscErrorCode output_fields_transpose(Vec x, const Vec *hx) const {
    return maps_.fft.apply_many(maps_.outputs_t, x, {hx, hx + outputs});
  }
  bool maps_parameter(int k) const { return Df == FIELD_D && k == DIFF; }
  PetscErrorCode map_parameter(int, Vec f) const {
    if constexpr (spectral) return maps_.fft.dealias(f, f);
    return 0;
  }

  PetscErrorCode check_parameters(const ParameterBounds &b, MPI_Comm comm) const {
    PetscFunctionBeginUser;
    PetscCheck(Df == NONE || b.min[DIFF] >= 0, comm, PETSC_ERR_ARG_OUTOFRANGE, "Diffusivity must be non-negative, found D = %g%s",
               (double)b.min[DIFF], Df == FIELD_D ? " in its 2/3-rule truncation P D: smooth D or raise it away from 0" : "");
    PetscFunctionReturn(0);
  }

  PetscErrorCode spectrum(const ParameterBounds &b, Spectrum *s) const {
    std::vector<cplx> adv[2];
    std::vector<PetscReal> diff[2]; // per unit D
    PetscReal rho = 0;              // sum over directions of the largest diffusion symbol per unit D
    PetscFunctionBeginUser;
    for (int d = 0; d < Dim; ++d) {
      const PetscReal v = b.max[d];
      PetscReal ih = 1 / h_[d], dmax = 0;
      for (PetscInt k = 0; k < n_[d]; ++k) {
        const cplx e = std::polar<PetscReal>(1.0, 2 * PETSC_PI * k / n_[d]);
        cplx dx, grad = 0; // the symbols of h u_d and of the face gradient h B (spectral: of u_d, of the gradient)
        if constexpr (spectral) {
          const PetscInt ks = k < n_[d] / 2 ? k : k - n_[d];
          const PetscReal w = 2 * PETSC_PI * ks / length_[d];
          dx = 2 * ks == -n_[d] ? cplx(0) : cplx(0, w); // Nyquist: the odd part is 0
          if (Df == SCALAR_D || (Df == FIELD_D && 3 * std::abs(ks) < n_[d])) grad = w;
          ih = 1;
        } else {
          if (S == FD4) dx = (8.0 * (e - 1.0 / e) - (e * e - 1.0 / (e * e))) / 12.0;
          else if (S == UPWIND) dx = v >= 0 ? 1.0 - 1.0 / e : e - 1.0;
          else dx = 0.5 * (e - 1.0 / e);
          if (Df != NONE) grad = Df == FACES4 ? (1.0 / e - 27.0 + 27.0 * e - e * e) / 24.0 : e - 1.0;
        }
        adv[d].push_back(-v * ih * dx);
        diff[d].push_back(std::norm(grad) * ih * ih);
        dmax = std::max(dmax, diff[d].back());
      }
      rho += dmax;
    }
    const bool field = Df != NONE && field_;
    const PetscReal D = Df != NONE && !field ? b.max[DIFF] : 0.0;
    auto &ev = s->samples;
    ev.clear();
    for (PetscInt ky = 0; ky < (Dim == 2 ? n_[1] : 1); ++ky)
      for (PetscInt kx = 0; kx < n_[0]; ++kx) ev.push_back(adv[0][kx] - D * diff[0][kx] + (Dim == 2 ? adv[1][ky] - D * diff[1][ky] : 0.0));
    if (field) { // the boundary of W(advection) + [-Dmax rho, 0]; order 4's interpolation may overshoot max D
      const PetscReal Dmax = Df == FACES4 ? (9 * b.max[DIFF] - b.min[DIFF]) / 8 : b.max[DIFF], shift = Dmax * rho;
      size_t top = 0, bottom = 0;
      const size_t nadv = ev.size();
      for (size_t q = 0; q < nadv; ++q) {
        if (ev[q].imag() > ev[top].imag()) top = q;
        if (ev[q].imag() < ev[bottom].imag()) bottom = q;
        ev.push_back(ev[q] - shift);
      }
      for (int t = 1; t < 64; ++t) {
        ev.push_back(ev[top] - shift * t / 64.0);
        ev.push_back(ev[bottom] - shift * t / 64.0);
      }
    }
    s->imag_radius = s->real_radius = 0;
    for (const cplx &l : ev) {
      s->imag_radius = std::max(s->imag_radius, std::fabs(l.imag()));
      s->real_radius = std::max(s->real_radius, std::fabs(l.real()));
    }
    PetscFunctionReturn(0);
  }

private:
  // u and D at offset o along direction d.
  template <int d, class P> static auto u(const P &pt, int o) {
    if constexpr (d == 0) return pt.u(0, o);
    else return pt.u(0, 0, o);
  }
  template <int d, class P> static auto D(const P &pt, int o) {
    if constexpr (d == 0) return pt.param(DIFF, o);
    else return pt.param(DIFF, 0, o);
  }
  // h v u_d by the scheme, v the velocity along d.
  template <int d, class P, class T = typename P::Number> static T advective(const P &pt) {
    const T v = pt.param(d);
    if constexpr (S == UPWIND) return max(v, T(0.0)) * (u<d>(pt, 0) - u<d>(pt, -1)) + min(T(0.0), v) * (u<d>(pt, 1) - u<d>(pt, 0));
    else if constexpr (S == FD4) return v * ((u<d>(pt, -2) - u<d>(pt, 2) + 8.0 * (u<d>(pt, 1) - u<d>(pt, -1))) * (1.0 / 12));
    else return v * (0.5 * (u<d>(pt, 1) - u<d>(pt, -1)));
  }
  PetscReal profile(PetscReal x, PetscReal y) const {
    if (ic_ == SINUSOID) {
      PetscReal arg = 2 * PETSC_PI * mode_[0] * (x - x0_[0]) / length_[0] + phase_;
      if (Dim == 2) arg += 2 * PETSC_PI * mode_[1] * (y - x0_[1]) / length_[1];
      return std::sin(arg);
    }
    auto periodic = [](PetscReal d, PetscReal L) { return d - L * std::floor(d / L + 0.5); }; // in [-L/2, L/2)
    const PetscReal dx = periodic(x - center_[0], length_[0]), dy = Dim == 2 ? periodic(y - center_[1], length_[1]) : 0;
    if (ic_ == GAUSSIAN) return std::exp(-(dx * dx + dy * dy) / (width_ * width_));
    return std::fabs(dx) < 0.5 * width_ && std::fabs(dy) < 0.5 * width_ ? 1.0 : 0.0;
  }

  PetscErrorCode make_spectral_maps(const Grid &grid) {
    using SD = SpectralDifferentiator;
    PetscFunctionBeginUser;
    if constexpr (spectral) {
      PetscCall(maps_.fft.setup(grid));
      PetscCall(DMCreateGlobalVector(grid.dm(), maps_.work.out()));
      for (int d = 0; d < Dim; ++d) {
        maps_.derivative[d] = maps_.fft.symbol([d](const FourierMode &k) { return SD::derivative_symbol(k, d, 1); });
        maps_.dealiased[d] = maps_.fft.symbol([d](const FourierMode &k) { return k.kept ? SD::derivative_symbol(k, d, 1) : cplx(0); });
      }
      maps_.laplacian = maps_.fft.symbol([](const FourierMode &k) { return cplx(-(k.wx * k.wx + k.wy * k.wy)); });
      auto conj = [](SpectralDifferentiator::Symbol q) {
        for (auto &v : q) v = std::conj(v);
        return q;
      };
      for (int k = 0; k < auxiliaries; ++k) maps_.aux.push_back(&aux_symbol(k)), maps_.aux_t.push_back(conj(aux_symbol(k)));
      for (const auto &s : maps_.aux_t) maps_.aux_adjoint.push_back(&s);
      for (int d = 0; d < Dim; ++d) maps_.dealiased_t.push_back(conj(maps_.dealiased[d]));
      for (int m = 0; m < outputs; ++m) maps_.outputs.push_back(&maps_.dealiased[m]), maps_.outputs_t.push_back(&maps_.dealiased_t[m]);
    }
    PetscFunctionReturn(0);
  }
  const SpectralDifferentiator::Symbol &aux_symbol(int k) const {
    return k < Dim ? maps_.derivative[k] : Df == SCALAR_D ? maps_.laplacian : maps_.dealiased[k - Dim];
  }

  PetscInt ic_ = SINUSOID, mode_[2] = {1, 1}, n_[2] = {1, 1};
  PetscBool field_ = PETSC_FALSE; // D is a field
  PetscReal phase_ = 0, width_ = 0.1, center_[2] = {0, 0}, x0_[2] = {0, 0}, length_[2] = {1, 1}, h_[2] = {1, 1};
  // Finite differences hold none: the model is then trivially copyable, and the sweeps work on a copy
  // whose members the compiler knows no store changes.
  std::conditional_t<spectral, SpectralMaps, NoMaps> maps_;
};

// The shape is fixed at compile time: the model is made for the options given. Options that are not
// offered fall back to a default here, and setup reports them.
template <int Dim, int S> std::unique_ptr<Model> make_scheme(int diffusion) {
  if constexpr (S == SPECTRAL) {
    if (diffusion == FIELD_D) return std::make_unique<PointwiseModel<Advection<Dim, S, FIELD_D>>>();
    if (diffusion == SCALAR_D) return std::make_unique<PointwiseModel<Advection<Dim, S, SCALAR_D>>>();
  } else {
    if (diffusion == FACES4) return std::make_unique<PointwiseModel<Advection<Dim, S, FACES4>>>();
    if (diffusion == FACES2) return std::make_unique<PointwiseModel<Advection<Dim, S, FACES2>>>();
  }
  return std::make_unique<PointwiseModel<Advection<Dim, S, NONE>>>();
}
template <int Dim> std::unique_ptr<Model> make(const Choice &c) {
  const int diffusion = c.diffusion_term();
  if (c.scheme == FD4) return make_scheme<Dim, FD4>(diffusion);
  if (c.scheme == UPWIND) return make_scheme<Dim, UPWIND>(diffusion);
  if (c.scheme == SPECTRAL) return make_scheme<Dim, SPECTRAL>(diffusion);
  return make_scheme<Dim, FD2>(diffusion);
}

// The 2D instances are compiled in a unit of their own (advection_2d.cpp), so that a build spreads
// the instances over two cores.
#ifdef FLEXIPDE_ADVECTION_2D_UNIT
template std::unique_ptr<Model> make<2>(const Choice &);
#else
extern template std::unique_ptr<Model> make<2>(const Choice &);

const ModelRegistration registration("advection", [] {
  Choice c;
  if (!PetscPushErrorHandler(PetscReturnErrorHandler, nullptr)) {
    if (read_choice(c)) c = Choice();
    (void)PetscPopErrorHandler();
  }
  if (c.order != 2 && c.order != 4) c.order = 2;
  return c.dim == 2 ? make<2>(c) : make<1>(c);
});
#endif

} // namespace advection
} // namespace flexipde
