// Linear advection-diffusion of one scalar on a periodic grid, in 1D or 2D:
//
//   1D (default):          u_t + a u_x         = (D u_x)_x                on [x0, x1) periodic
//   2D (-advection_dim 2): u_t + a u_x + b u_y = (D u_x)_x + (D u_y)_y    on [x0, x1) x [y0, y1)
//   u(x, 0) = A s(x)
//
// The velocities a (-advection_a) and, in 2D, b (-advection_b) are scalar parameters. Diffusion is
// optional: -advection_diffusion (default on exactly when -advection_D, -advection_D_field or
// -advection_D_profile is given) adds the parameter D, a scalar or a field (-advection_D_field 1).
//
// Space, per direction d with spacing h (every stencil periodic):
//   fd2       (u_x)_i = (u_{i+1} - u_{i-1}) / 2h                                    order 2
//   fd4       (u_x)_i = (u_{i-2} - 8u_{i-1} + 8u_{i+1} - u_{i+2}) / 12h             order 4
//   upwind    (u_x)_i = (u_i - u_{i-1}) / h for a >= 0, (u_{i+1} - u_i) / h for a < 0: order 1,
//             monotone; dG/da is taken on the side of the current sign (one-sided at a = 0)
//   spectral  u_x = F^-1 i kappa F u (FFTW-MPI, include/flexipde/spectral.hpp); N even
//   Diffusion, finite differences: the flux form G_i = -(B^T diag(D_f) B u)_i, with the face gradient
//   B and face diffusivity D_f at f = i + 1/2:
//     -fd_order 2: (Bu)_f = (u_{i+1} - u_i) / h,  D_f = (D_i + D_{i+1}) / 2
//     -fd_order 4: (Bu)_f = (u_{i-1} - 27u_i + 27u_{i+1} - u_{i+2}) / 24h,
//                  D_f = (-D_{i-1} + 9D_i + 9D_{i+1} - D_{i+2}) / 16
//   symmetric, negative semi-definite while D_f >= 0, conservative, of the stated order for a smooth
//   field D. -fd_order defaults to 4 with fd4, else 2.
//   Diffusion, spectral: a scalar D multiplies the Laplacian F^-1 (-|kappa|^2) F u; a field D gives
//   sum_d E_d (D .* E_d u), E_d = P d/dx_d with P the 2/3-rule truncation: the gradient is truncated
//   and so is the flux, symmetric negative semi-definite for D >= 0 and conservative.
//
// The layer (include/flexipde/pointwise.hpp) takes G at one point (rhs below) and derives dG/dU,
// dG/da, dG/db, dG/dD, their transposes and the adjoint sweeps. The spectral scheme enters through its
// non-local maps: auxiliary fields a_d = d/dx_d u (and the Laplacian, or E_d u for a field D) read at
// points, and for a field D the outputs h_d = D E_d u that G receives through E_d.
//
// Spectrum (the explicit stability check): with no D or a scalar D the operator is a sum of circulants,
// normal, and its eigenvalues are the symbols per mode lambda(theta_x) + lambda(theta_y): all of them
// are passed. With a field D they lie in the field of values, inside W(advection) + [-Dmax rho, 0]
// (rho the largest |symbol|^2 of the face gradients, Dmax bounding every D_f): its boundary is passed.
//
// Initial condition (-advection_ic, u0 = A s):
//   sinusoid  s = sin(2 pi m (x - x0) / Lx [+ 2 pi m_y (y - y0) / Ly] + phi)
//   gaussian  s = exp(-|d|^2 / w^2)                       d the periodic distance to the centre
//   square    s = 1 where |d_x| < w/2 [and |d_y| < w/2], else 0
// A (-advection_ic_amplitude) is a parameter with dU0/dA = s when -advection_ic_amplitude_param 1.
//
//   mpiexec -n 2 ./flexipde -model advection -grid_periodic 1 -grid_x1 6.283185307179586 -da_grid_x 64
//           -ts_dt 0.01 -ts_max_time 1 -task taylor -objective_type mean_square
//           -advection_ic_amplitude_param 1 -advection_D 0.05 -advection_D_field 1           (one line)
//   mpiexec -n 2 ./flexipde -model advection -grid_periodic 1 -task gradient -advection_scheme upwind
//           -advection_a 0.8 -true_advection_a 1 -ts_type cn -ts_dt 1e-3 -ts_max_time 0.5 -check_fd
//   mpiexec -n 2 ./flexipde -model advection -grid_periodic 1 -grid_x1 6.283185307179586 -da_grid_x 64
//           -advection_scheme spectral -advection_a 0.8 -true_advection_a 1 -ts_dt 0.01 -ts_max_time 1
//           -task gradient -check_fd
//   mpiexec -n 2 ./flexipde -model advection -advection_dim 2 -da_grid_x 32 -da_grid_y 32
//           -advection_a 0.8 -advection_b 0.5 -true_advection_b 0.6 -advection_D 0.01 -ts_dt 0.005
//           -ts_max_time 0.2 -task gradient -check_fd
#include "flexipde/differentiator.hpp"
#include "flexipde/pointwise.hpp"
#include "flexipde/spectral.hpp"
#include <algorithm>
#include <complex>

namespace flexipde {
namespace {

const char *const schemes[] = {"fd2", "fd4", "upwind", "spectral"};
enum Scheme : PetscInt { FD2, FD4, UPWIND, SPECTRAL };
const char *const ic_names[] = {"sinusoid", "gaussian", "square"};
enum InitialCondition : PetscInt { SINUSOID, GAUSSIAN, SQUARE };
constexpr PetscReal default_diffusion = 0.01; // D when diffusion is on without a value
constexpr PetscInt default_points_2d = 64;
using cplx = std::complex<PetscReal>;

// What fixes the grid and the equations' shape, read before the grid exists (no -help there).
struct Choice {
  PetscInt dim = 1, scheme = FD2, order = 2;
  PetscBool diffusion = PETSC_FALSE, field = PETSC_FALSE;
  // Stencil radius (the layer's ghost width is twice it) and the spectral scheme's non-local fields.
  int radius() const {
    if (scheme == SPECTRAL) return 0;
    return std::max(scheme == FD4 ? 2 : 1, diffusion ? (order == 4 ? 3 : 1) : 0);
  }
  int auxiliaries() const { return scheme != SPECTRAL ? 0 : !diffusion ? dim : field ? 2 * dim : dim + 1; }
  int outputs() const { return scheme == SPECTRAL && diffusion && field ? dim : 0; }
};
PetscErrorCode read_choice(Choice &c) {
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

// The equations for one shape: Dim, stencil radius R (0: spectral), K auxiliary fields, H outputs.
template <int Dim, int R, int K = 0, int H = 0>
class Advection {
  static constexpr bool spectral = R == 0;
  static constexpr bool laplacian = spectral && H == 0 && K == Dim + 1; // scalar D (1D field D also has K = 2)
  enum Parameter { A_VEL = 0, B_VEL = 1, DIFF = Dim, AMP = Dim + 1 };

public:
  static constexpr int dim = Dim, components = 1, radius = R, parameters = Dim + 2;
  static constexpr int auxiliaries = K, outputs = H;
  static constexpr bool linear = true;

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
    }
    // The model was made for the choice read before the grid existed; -help must not change it.
    PetscCheck(c.dim == Dim && c.radius() == R && c.auxiliaries() == K && c.outputs() == H, grid.comm(), PETSC_ERR_PLIB,
               "advection: the options changed between the model's creation and its setup");
    scheme_ = c.scheme, order_ = c.order, diffusion_ = c.diffusion, field_ = c.field;
    for (int d = 0; d < Dim; ++d) {
      n_[d] = d == 0 ? grid.n() : grid.ny(), length_[d] = d == 0 ? Lx : Ly, x0_[d] = d == 0 ? grid.x0() : grid.y0();
      h_[d] = length_[d] / n_[d];
    }
    if constexpr (spectral) PetscCall(make_spectral_maps(grid));

    decl.parameter(A_VEL, "advection_a", false, PETSC_NINFINITY, 1.0);
    if (Dim == 2) decl.parameter(B_VEL, "advection_b", false, PETSC_NINFINITY, 1.0);
    if (diffusion_) decl.parameter(DIFF, "advection_D", field_, 0.0, default_diffusion);
    else decl.fixed(DIFF, 0.0);
    if (amplitude_param) decl.parameter(AMP, "advection_ic_amplitude", false, PETSC_NINFINITY, amplitude);
    else decl.fixed(AMP, amplitude);
    PetscFunctionReturn(0);
  }

  // G at one point: -sum_d v_d (u_d) + diffusion.
  template <class P> void rhs(const P &pt, typename P::Number *g) const {
    using T = typename P::Number;
    if constexpr (spectral) {
      T G = -pt.param(A_VEL) * pt.aux(0);
      if constexpr (Dim == 2) G -= pt.param(B_VEL) * pt.aux(1);
      if constexpr (laplacian) G += pt.param(DIFF) * pt.aux(Dim); // D times the Laplacian
      g[0] = G;
      for (int d = 0; d < H; ++d) g[1 + d] = pt.param(DIFF) * pt.aux(Dim + d); // the flux D E_d u
    } else {
      const T a = pt.param(A_VEL);
      T G = -a * slope<0>(pt, a) * pt.inv_h(0);
      if constexpr (Dim == 2) {
        const T b = pt.param(B_VEL);
        G -= b * slope<1>(pt, b) * pt.inv_h(1);
      }
      if (diffusion_) {
        G += diffusion<0>(pt) * (pt.inv_h(0) * pt.inv_h(0));
        if constexpr (Dim == 2) G += diffusion<1>(pt) * (pt.inv_h(1) * pt.inv_h(1));
      }
      g[0] = G;
    }
  }

  template <class P> void initial(const P &pt, typename P::Number *u) const {
    u[0] = pt.param(AMP) * profile(pt.x(0), Dim == 2 ? pt.x(1) : 0.0);
  }

  // The spectral maps: a_k = L_k U and its transpose; G += E_m h_m and its transpose.
  PetscErrorCode auxiliary(int k, Vec U, Vec a) const { return spectral_.apply(aux_symbol(k), U, a); }
  PetscErrorCode auxiliary_transpose(int k, Vec z, Vec y) const {
    PetscFunctionBeginUser;
    PetscCall(spectral_.apply(aux_symbol(k), z, work_, true));
    PetscCall(VecAXPY(y, 1.0, work_));
    PetscFunctionReturn(0);
  }
  PetscErrorCode output(int m, Vec h, Vec G) const {
    PetscFunctionBeginUser;
    PetscCall(spectral_.apply(dealiased_[m], h, work_));
    PetscCall(VecAXPY(G, 1.0, work_));
    PetscFunctionReturn(0);
  }
  PetscErrorCode output_transpose(int m, Vec x, Vec hx) const { return spectral_.apply(dealiased_[m], x, hx, true); }

  PetscErrorCode check_parameters(const ParameterBounds &b, MPI_Comm comm) const {
    PetscFunctionBeginUser;
    PetscCheck(!diffusion_ || b.min[DIFF] >= 0, comm, PETSC_ERR_ARG_OUTOFRANGE, "Diffusivity must be non-negative, found D = %g",
               (double)b.min[DIFF]);
    PetscFunctionReturn(0);
  }

  PetscErrorCode spectrum(const ParameterBounds &b, Spectrum *s) const {
    std::vector<cplx> adv[2];
    std::vector<PetscReal> diff[2]; // per unit D
    PetscReal rho = 0;              // sum over directions of the largest diffusion symbol per unit D
    PetscFunctionBeginUser;
    for (int d = 0; d < Dim; ++d) {
      const PetscReal v = b.max[d];
      PetscReal ih = 1 / h_[d];
      PetscReal dmax = 0;
      for (PetscInt k = 0; k < n_[d]; ++k) {
        const PetscReal th = 2 * PETSC_PI * k / n_[d];
        const cplx e = std::polar<PetscReal>(1.0, th);
        cplx dx;    // the symbol of u_d times h (spectral: of u_d)
        cplx grad = 0; // the face gradient's symbol times h
        if (scheme_ == SPECTRAL) {
          const PetscInt ks = k < n_[d] / 2 ? k : k - n_[d];
          const PetscReal w = 2 * PETSC_PI * ks / length_[d];
          dx = 2 * ks == -n_[d] ? cplx(0) : cplx(0, w); // Nyquist: the odd part is 0
          if (diffusion_ && (!field_ || 3 * std::abs(ks) < n_[d])) grad = w;
          ih = 1;
        } else {
          if (scheme_ == FD4) dx = (8.0 * (e - 1.0 / e) - (e * e - 1.0 / (e * e))) / 12.0;
          else if (scheme_ == UPWIND) dx = v >= 0 ? 1.0 - 1.0 / e : e - 1.0;
          else dx = 0.5 * (e - 1.0 / e);
          if (diffusion_) grad = order_ == 4 ? (1.0 / e - 27.0 + 27.0 * e - e * e) / 24.0 : e - 1.0;
        }
        adv[d].push_back(-v * ih * dx);
        diff[d].push_back(std::norm(grad) * ih * ih);
        dmax = std::max(dmax, diff[d].back());
      }
      rho += dmax;
    }
    const bool field = diffusion_ && field_;
    const PetscReal D = diffusion_ && !field ? b.max[DIFF] : 0.0;
    auto &ev = s->samples;
    ev.clear();
    for (PetscInt ky = 0; ky < (Dim == 2 ? n_[1] : 1); ++ky)
      for (PetscInt kx = 0; kx < n_[0]; ++kx) {
        cplx l = adv[0][kx] - D * diff[0][kx];
        if (Dim == 2) l += adv[1][ky] - D * diff[1][ky];
        ev.push_back(l);
      }
    if (field) { // the boundary of W(advection) + [-Dmax rho, 0]; order 4's interpolation may overshoot max D
      const PetscReal Dmax = scheme_ != SPECTRAL && order_ == 4 ? (9 * b.max[DIFF] - b.min[DIFF]) / 8 : b.max[DIFF];
      const PetscReal shift = Dmax * rho;
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
  // h u_d by the scheme; v the velocity along d (upwinding takes the side the flow comes from).
  template <int d, class P, class T = typename P::Number> T slope(const P &pt, const T &v) const {
    if constexpr (R >= 2)
      if (scheme_ == FD4) return (u<d>(pt, -2) - u<d>(pt, 2) + 8.0 * (u<d>(pt, 1) - u<d>(pt, -1))) * (1.0 / 12);
    if (scheme_ == UPWIND) return value_of(v) >= 0 ? u<d>(pt, 0) - u<d>(pt, -1) : u<d>(pt, 1) - u<d>(pt, 0);
    return 0.5 * (u<d>(pt, 1) - u<d>(pt, -1));
  }
  // h^2 (D u_d)_d in flux form: -B^T diag(D_f) B u (a scalar D is a constant field to the layer).
  template <int d, class P, class T = typename P::Number> T diffusion(const P &pt) const {
    if constexpr (R >= 3)
      if (order_ == 4)
        return (flux<d, -2>(pt) - flux<d, 1>(pt) + 27.0 * (flux<d, 0>(pt) - flux<d, -1>(pt))) * (1.0 / 24);
    const T Dp = 0.5 * (D<d>(pt, 0) + D<d>(pt, 1)), Dm = 0.5 * (D<d>(pt, -1) + D<d>(pt, 0));
    return Dp * (u<d>(pt, 1) - u<d>(pt, 0)) - Dm * (u<d>(pt, 0) - u<d>(pt, -1));
  }
  // Order 4: h D_f (Bu)_f at the face f = i + k + 1/2.
  template <int d, int k, class P, class T = typename P::Number> T flux(const P &pt) const {
    const T grad = (u<d>(pt, k - 1) - u<d>(pt, k + 2) + 27.0 * (u<d>(pt, k + 1) - u<d>(pt, k))) * (1.0 / 24);
    const T Df = (9.0 * (D<d>(pt, k) + D<d>(pt, k + 1)) - D<d>(pt, k - 1) - D<d>(pt, k + 2)) * (1.0 / 16);
    return Df * grad;
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
    PetscCall(spectral_.setup(grid));
    PetscCall(DMCreateGlobalVector(grid.dm(), work_.out()));
    for (int d = 0; d < Dim; ++d) {
      derivative_[d] = spectral_.symbol([d](const FourierMode &k) { return SD::derivative_symbol(k, d, 1); });
      dealiased_[d] = spectral_.symbol([d](const FourierMode &k) { return k.kept ? SD::derivative_symbol(k, d, 1) : cplx(0); });
    }
    laplacian_ = spectral_.symbol([](const FourierMode &k) { return cplx(-(k.wx * k.wx + k.wy * k.wy)); });
    PetscFunctionReturn(0);
  }
  // L_k: d/dx_k (k < Dim), then the Laplacian (scalar D) or E_{k - Dim} (field D).
  const SpectralDifferentiator::Symbol &aux_symbol(int k) const {
    return k < Dim ? derivative_[k] : laplacian ? laplacian_ : dealiased_[k - Dim];
  }

  PetscInt scheme_ = FD2, order_ = 2, ic_ = SINUSOID, mode_[2] = {1, 1}, n_[2] = {1, 1};
  PetscBool diffusion_ = PETSC_FALSE, field_ = PETSC_FALSE;
  PetscReal phase_ = 0, width_ = 0.1, center_[2] = {0, 0}, x0_[2] = {0, 0}, length_[2] = {1, 1}, h_[2] = {1, 1};
  SpectralDifferentiator spectral_;
  SpectralDifferentiator::Symbol derivative_[2], dealiased_[2], laplacian_;
  OwnedVec work_;
};

// The shape is fixed at compile time (dimension, radius, non-local fields): the model is made for
// the options given. Bad options fall back to the default here and setup reports them.
template <int Dim> std::unique_ptr<Model> make(const Choice &c) {
  auto m = [](auto *p) { return std::unique_ptr<Model>(p); };
  if (c.scheme == SPECTRAL) {
    if (!c.diffusion) return m(new PointwiseModel<Advection<Dim, 0, Dim>>());
    if (!c.field) return m(new PointwiseModel<Advection<Dim, 0, Dim + 1>>());
    return m(new PointwiseModel<Advection<Dim, 0, 2 * Dim, Dim>>());
  }
  if (c.radius() == 3) return m(new PointwiseModel<Advection<Dim, 3>>());
  if (c.radius() == 2) return m(new PointwiseModel<Advection<Dim, 2>>());
  return m(new PointwiseModel<Advection<Dim, 1>>());
}

const ModelRegistration registration("advection", [] {
  Choice c;
  if (!PetscPushErrorHandler(PetscReturnErrorHandler, nullptr)) {
    if (read_choice(c)) c = Choice();
    (void)PetscPopErrorHandler();
  }
  if (c.order != 2 && c.order != 4) c.order = 2;
  return c.dim == 2 ? make<2>(c) : make<1>(c);
});

} // namespace
} // namespace flexipde
