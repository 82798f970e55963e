// Vlasov-Poisson for electrons on a neutralising ion background, 1D in x and 1D in velocity v.
//
//   f_t + v f_x - E f_v = 0,     E_x = 1 - rho,   rho(x) = int f dv,   int E dx = 0
//
// Sign convention: electrons of charge -1 and mass 1 (time in 1/omega_p, length in Debye lengths),
// so the force on them is -E; the ions are a uniform background of density 1. f lives on the
// phase-space grid (x, v): x periodic on [0, L), v in [-v_max, v_max] (the grid's y direction, not
// periodic, end points included) with f = 0 beyond it.
//
// Space (h = L / N_x, hv = 2 v_max / (N_v - 1)):
//   x: centred fourth order, periodic: (D_x f)_i = (f_{i-2} - 8f_{i-1} + 8f_{i+1} - f_{i+2}) / 12h
//   v: the same stencil in conservative flux form, (D_v f)_j = (F_{j+1/2} - F_{j-1/2}) / hv with the
//      face values F_{j+1/2} = (-f_{j-1} + 7f_j + 7f_{j+1} - f_{j+2}) / 12 between grid points
//      (f = 0 beyond the ends) and no flux through the two outer faces. Inside it is the centred
//      stencil above; next to the ends it keeps sum_j (D_v f)_j = 0, so the mass h hv sum f is
//      conserved to round-off (x periodic, x-sums of D_x vanish too).
//   rho_i = hv sum_j f_ij, and E = K (1 - rho) with K the spectral zero-mean antiderivative:
//      (K s)^_m = s^_m / (i kappa_m) for 0 < |m| < N_x/2, and 0 for the mean (and Nyquist) mode.
//      K is a real antisymmetric circulant with K 1 = 0, so E = -K rho. rho is summed over the v
//      rows each rank owns and MPI_Allreduce'd (a length-N_x array); every rank then applies K
//      to the whole of it with a serial real FFT (FFTW, O(N_x log N_x), negligible next to the
//      phase-space stencils) and keeps the x it owns.
//
//   G(f) = -v D_x f + E(f) D_v f
//   dG/dU d = -v D_x d + E D_v d + dE D_v f,   dE = -hv K S d  (S: sum over v)
//   (dG/dU)^T y = v D_x y + E D_v^T y + hv K w,   w_i = sum_j y_ij (D_v f)_ij   (K^T = -K, D_x^T = -D_x)
//   computed as w_i = sum_j f_ij (D_v^T y)_ij in the same sweep as the rest (no D_v f at all: the
//   adjoint's rhs_jacobian only copies f and sums its density, one pass without ghost exchange).
// dG/dU is a MatShell with MultTranspose (no matrix is stored); the model has no parameter in G, so
// dG/dp = 0. Integrators: -ts_type rk, and cn/theta/beuler (the Simulation solves their linear
// systems with GMRES on the shell).
//
// Initial condition f0 = (1 + alpha cos(k x)) F(v), k = 2 pi m / L (-vlasov_mode m):
//   -vlasov_ic landau      F = M(v; vt)                                 (defaults k 0.5, alpha 0.01)
//   -vlasov_ic two_stream  F = [M(v - v0; vt) + M(v + v0; vt sqrt(r))] / 2  (k 0.2, alpha 1e-3, v0 2.4)
// with M(u; s) = exp(-u^2 / 2s^2) / (sqrt(2 pi) s) and r the temperature ratio T_2 / T_1 of the
// beams. alpha, vt (and v0, r for two_stream) are the scalar parameters vlasov_alpha, vlasov_vt,
// vlasov_v0, vlasov_temperature_ratio (options of those names); dU0/dp^T lambda enters the gradient,
// and the gradient with respect to f0 itself is dJ/dU0 (Simulation::gradient's grad_u0).
// -vlasov_k sets the default domain length 2 pi / k, -vlasov_vmax the default velocity bounds;
// -da_grid_x, -da_grid_y, -grid_x1, -grid_y0, -grid_y1 override them.
//
// Functionals (Model::functional, for -objective_type functional / functional_integral and for
// diagnostics): field_energy 0.5 h sum_i E_i^2, mass h hv sum f, momentum h hv sum v f,
// kinetic_energy 0.5 h hv sum v^2 f, energy (kinetic + field), l2 sqrt(h hv sum f^2).
//
// Optional dissipation (-vlasov_dissipation c, default 0): G -= c [ |v| / 12h  d_x^4 f + E_cfl / 12hv
// Q f ] with fourth differences in x (periodic) and v (Q = (B^T B)^2, no flux through the bounds):
// linear, symmetric, negative semi-definite, mass-conserving. c = 1 makes the x advection the
// third-order upwind-biased scheme; it damps the grid-scale oscillations of filamentation.
//
// Explicit stability: the spectrum of dG/dU is bounded by i [-R, R] with R = 1.372 (v_max / h +
// E_max / hv) (1.372 = max of the fourth-order symbol); E_max is the larger of max|E| at t = 0
// and -vlasov_E_cfl (the field a nonlinear run is expected to reach). With dissipation the check
// uses sampled sums of the x and v symbols instead (Spectrum::samples).
//
//   mpiexec --allow-run-as-root --oversubscribe -n 2 ./flexipde -model vlasov -task forward
//           -da_grid_x 64 -da_grid_y 128 -ts_dt 0.05 -ts_max_time 10        (one line)
//   mpiexec --allow-run-as-root --oversubscribe -n 2 ./flexipde -model vlasov -vlasov_ic two_stream
//           -task taylor -da_grid_x 32 -da_grid_y 64 -ts_dt 0.1 -ts_max_time 5
//           -objective_type functional -objective_functional field_energy
#include "flexipde/halo.hpp"
#include "flexipde/model.hpp"
#include <algorithm>
#include <fftw3.h>
#include <cmath>
#include <cstring>
#include <vector>

namespace flexipde {
namespace {

const char *const ic_names[] = {"landau", "two_stream"};
enum InitialCondition : PetscInt { LANDAU = 0, TWO_STREAM = 1 };

// Defaults of the two set-ups (named, options override them).
struct IcDefaults {
  PetscReal k, alpha, vt, v0, ratio, vmax;
};
constexpr IcDefaults landau_defaults{0.5, 0.01, 1.0, 0.0, 1.0, 6.0};
constexpr IcDefaults two_stream_defaults{0.2, 1e-3, 1.0, 2.4, 1.0, 8.0};
constexpr PetscInt default_nx = 64, default_nv = 128;
constexpr PetscReal default_E_cfl = 1.0;

// Face interpolation weights (f_{j-1}, f_j, f_{j+1}, f_{j+2}) of the v flux.
constexpr PetscReal face_w[4] = {-1.0 / 12, 7.0 / 12, 7.0 / 12, -1.0 / 12};

PetscInt read_ic() {
  PetscInt ic = LANDAU;
  (void)PetscOptionsGetEList(nullptr, nullptr, "-vlasov_ic", ic_names, 2, &ic, nullptr);
  return ic;
}

PetscReal maxwellian(PetscReal u, PetscReal s) { return std::exp(-0.5 * u * u / (s * s)) / (std::sqrt(2 * PETSC_PI) * s); }

// One row of the transpose sweep (VlasovModel::j_mult_transpose) over the n owned x of row j:
//   y = cx (r_{i-2} - 8 r_{i-1} + 8 r_{i+1} - r_{i+2}) + E dvt,   w += f dvt,
// with dvt = (D_v^T x)_ij from the rows m2, m1, r, p1, p2 = x_{j-2..j+2} (ghosted: r[-2], r[n+1]
// are read). Free functions with restrict parameters, because GCC vectorises these loops and not
// the same loops over restrict locals inside the member function (which stay scalar). The arithmetic
// is unchanged, element by element.
// Rows away from the bounds, where D_v^T = -D_v: dvt = cv (m2 - 8 m1 + 8 p1 - p2), cv = -1/12hv.
void transpose_row_interior(PetscInt n, PetscReal cx, PetscReal cv, const PetscScalar *__restrict r,
                            const PetscScalar *__restrict m2, const PetscScalar *__restrict m1,
                            const PetscScalar *__restrict p1, const PetscScalar *__restrict p2,
                            const PetscReal *__restrict E, const PetscScalar *__restrict f, PetscScalar *__restrict y,
                            PetscReal *__restrict w) {
  for (PetscInt il = 0; il < n; ++il) {
    const PetscScalar dvt = cv * (m2[il] - 8.0 * m1[il] + 8.0 * p1[il] - p2[il]);
    y[il] = cx * (r[il - 2] - 8.0 * r[il - 1] + 8.0 * r[il + 1] - r[il + 2]) + E[il] * dvt;
    w[il] += PetscRealPart(f[il] * dvt);
  }
}
// The two rows next to each bound: dvt with the row's own weights c[0..4] (of x_{j-2..j+2}).
void transpose_row_bound(PetscInt n, PetscReal cx, const PetscReal c[5], const PetscScalar *__restrict r,
                         const PetscScalar *__restrict m2, const PetscScalar *__restrict m1,
                         const PetscScalar *__restrict p1, const PetscScalar *__restrict p2,
                         const PetscReal *__restrict E, const PetscScalar *__restrict f, PetscScalar *__restrict y,
                         PetscReal *__restrict w) {
  const PetscReal c0 = c[0], c1 = c[1], c2 = c[2], c3 = c[3], c4 = c[4];
  for (PetscInt il = 0; il < n; ++il) {
    const PetscScalar dvt = c0 * m2[il] + c1 * m1[il] + c2 * r[il] + c3 * p1[il] + c4 * p2[il];
    y[il] = cx * (r[il - 2] - 8.0 * r[il - 1] + 8.0 * r[il + 1] - r[il + 2]) + E[il] * dvt;
    w[il] += PetscRealPart(f[il] * dvt);
  }
}

// One row of G (VlasovModel::rhs) over n points: g = cx (r_{i-2} - 8 r_{i-1} + 8 r_{i+1} - r_{i+2}) + E dv
// with dv = (D_v f)_ij from the rows m2, m1, r, p1, p2 = f_{j-2..j+2} (r[-2], r[n+1] are read), the
// arithmetic of advection_row element by element (so G is the same bitwise), as free functions with
// restrict parameters so that GCC vectorises them (see transpose_row_interior).
// Rows 1 .. N_v - 2, where D_v is the centred stencil (with f = 0 beyond the bounds): cv = 1/12hv.
void advection_row_interior(PetscInt n, PetscReal cx, PetscReal cv, const PetscScalar *__restrict r,
                            const PetscScalar *__restrict m2, const PetscScalar *__restrict m1,
                            const PetscScalar *__restrict p1, const PetscScalar *__restrict p2,
                            const PetscReal *__restrict E, PetscScalar *__restrict g) {
  for (PetscInt il = 0; il < n; ++il)
    g[il] = cx * (r[il - 2] - 8.0 * r[il - 1] + 8.0 * r[il + 1] - r[il + 2]) +
            E[il] * cv * (m2[il] - 8.0 * m1[il] + 8.0 * p1[il] - p2[il]);
}
// The rows on the bounds (0 and N_v - 1): D_v with the row's weights c[0..4] (dv_row, of f_{j-2..j+2}).
void advection_row_bound(PetscInt n, PetscReal cx, const PetscReal c[5], const PetscScalar *__restrict r,
                         const PetscScalar *__restrict m2, const PetscScalar *__restrict m1,
                         const PetscScalar *__restrict p1, const PetscScalar *__restrict p2,
                         const PetscReal *__restrict E, PetscScalar *__restrict g) {
  const PetscReal c0 = c[0], c1 = c[1], c2 = c[2], c3 = c[3], c4 = c[4];
  for (PetscInt il = 0; il < n; ++il)
    g[il] = cx * (r[il - 2] - 8.0 * r[il - 1] + 8.0 * r[il + 1] - r[il + 2]) +
            E[il] * (c0 * m2[il] + c1 * m1[il] + c2 * r[il] + c3 * p1[il] + c4 * p2[il]);
}

class VlasovModel final : public Model {
public:
  const char *name() const override { return "vlasov"; }
  PetscInt dof() const override { return 1; }
  const char *component_name(PetscInt) const override { return "f"; }
  PetscInt stencil_width(MPI_Comm) const override { return 2; }
  PetscInt dim() const override { return 2; }
  void grid_defaults(GridOptions &g) const override {
    const IcDefaults &d = read_ic() == TWO_STREAM ? two_stream_defaults : landau_defaults;
    PetscReal k = d.k, vmax = d.vmax;
    (void)PetscOptionsGetReal(nullptr, nullptr, "-vlasov_k", &k, nullptr);
    (void)PetscOptionsGetReal(nullptr, nullptr, "-vlasov_vmax", &vmax, nullptr);
    g.periodic = PETSC_TRUE;
    g.periodic_y = PETSC_FALSE;
    g.n = default_nx;
    g.ny = default_nv;
    g.x0 = 0;
    g.x1 = k > 0 ? 2 * PETSC_PI / k : 1.0; // setup reports a bad k
    g.y0 = -vmax;
    g.y1 = vmax;
  }
  std::string functional_names() const override {
    return "field_energy, mass, momentum, kinetic_energy, energy, l2";
  }

  PetscErrorCode setup(const Grid &grid, DM state_dm, Parameters &params) override {
    PetscFunctionBeginUser;
    grid_ = &grid;
    dm_ = state_dm;
    params_ = &params;
    ic_ = read_ic();
    const IcDefaults &d = ic_ == TWO_STREAM ? two_stream_defaults : landau_defaults;
    PetscReal k = d.k, vmax = d.vmax;
    PetscOptionsBegin(grid.comm(), nullptr, "Vlasov-Poisson model f_t + v f_x - E f_v = 0, E_x = 1 - int f dv",
                      "Vlasov");
    PetscCall(PetscOptionsEList("-vlasov_ic", "Initial distribution: landau (one Maxwellian) or two_stream (two beams)",
                                "Vlasov", ic_names, 2, ic_names[ic_], &ic_, nullptr));
    PetscCall(PetscOptionsReal("-vlasov_k", "Perturbation wavenumber: sets the default domain length 2 pi / k",
                               "Vlasov", k, &k, nullptr));
    PetscCall(PetscOptionsReal("-vlasov_vmax", "Velocity bound: sets the default -grid_y0 -vmax, -grid_y1 vmax",
                               "Vlasov", vmax, &vmax, nullptr));
    PetscCall(PetscOptionsInt("-vlasov_mode", "Number m of perturbation periods in the domain (k = 2 pi m / L)",
                              "Vlasov", mode_, &mode_, nullptr));
    PetscCall(PetscOptionsReal("-vlasov_dissipation",
                               "Strength c of the fourth-difference dissipation (0: none; 1: third-order upwind-biased "
                               "in x)",
                               "Vlasov", c_diss_, &c_diss_, nullptr));
    PetscCall(PetscOptionsReal("-vlasov_E_cfl",
                               "Largest |E| the explicit stability check assumes (with max|E| at t = 0)", "Vlasov",
                               E_cfl_, &E_cfl_, nullptr));
    PetscOptionsEnd();
    PetscCheck(grid.dim() == 2, grid.comm(), PETSC_ERR_ARG_WRONG, "Model vlasov needs a 2D phase-space grid");
    PetscCheck(k > 0, grid.comm(), PETSC_ERR_ARG_OUTOFRANGE, "-vlasov_k must be positive, got %g", (double)k);
    PetscCheck(vmax > 0, grid.comm(), PETSC_ERR_ARG_OUTOFRANGE, "-vlasov_vmax must be positive, got %g", (double)vmax);
    PetscCheck(c_diss_ >= 0, grid.comm(), PETSC_ERR_ARG_OUTOFRANGE, "-vlasov_dissipation must be non-negative, got %g",
               (double)c_diss_);
    PetscCheck(mode_ >= 1, grid.comm(), PETSC_ERR_ARG_OUTOFRANGE, "-vlasov_mode must be at least 1, got %" PetscInt_FMT,
               mode_);
    PetscCheck(grid.periodic() && !grid.periodic_y(), grid.comm(), PETSC_ERR_ARG_WRONG,
               "Model vlasov needs x periodic (-grid_periodic 1) and v not periodic (-grid_periodic_y 0)");
    PetscCheck(grid.stencil_width() >= 2, grid.comm(), PETSC_ERR_PLIB, "Vlasov stencils need a ghost width of 2");

    nx_ = grid.n();
    nv_ = grid.ny();
    h_ = grid.h();
    hv_ = grid.hy();
    k_ = 2 * PETSC_PI * mode_ / (grid.x1() - grid.x0());
    alpha_index_ = params.add("vlasov_alpha", ParamKind::Scalar, PETSC_NINFINITY, d.alpha);
    vt_index_ = params.add("vlasov_vt", ParamKind::Scalar, 0.0, d.vt);
    if (ic_ == TWO_STREAM) {
      v0_index_ = params.add("vlasov_v0", ParamKind::Scalar, PETSC_NINFINITY, d.v0);
      ratio_index_ = params.add("vlasov_temperature_ratio", ParamKind::Scalar, 0.0, d.ratio);
    }

    // The zero-mean antiderivative K by a serial real FFT of length N_x on every rank: the
    // multiplier 1 / (i kappa_m) for 0 < m < N_x / 2, 0 for the mean and the Nyquist mode.
    fft_.setup(nx_, grid.x1() - grid.x0());
    rho_.assign(nx_, 0.0);
    Efull_.assign(nx_, 0.0);
    w_.assign(nx_, 0.0);
    E_.assign(grid.xm(), 0.0);
    Elin_.assign(grid.xm(), 0.0);
    Estage_.assign(grid.xm(), 0.0);
    dE_.assign(grid.xm(), 0.0);
    PetscCall(DMCreateGlobalVector(dm_, f_lin_.out()));
    PetscCall(DMCreateLocalVector(dm_, U_local_.out()));
    PetscCall(DMCreateLocalVector(dm_, X_local_.out()));
    PetscCall(halo_.setup(grid, dm_, 0, 2));
    PetscCallMPI(MPI_Comm_size(grid.comm(), &nranks_));
    ghost_rows_.assign(5 * grid.xm() + 4, 0.0);
    zero_row_.assign(grid.xm(), 0.0);
    PetscCall(VecSet(U_local_, 0.0));
    PetscCall(VecSet(X_local_, 0.0));
    PetscFunctionReturn(0);
  }

  PetscErrorCode create_jacobian(Mat *J) override {
    const PetscInt n = grid_->local_points();
    PetscFunctionBeginUser;
    PetscCall(MatCreateShell(grid_->comm(), n, n, PETSC_DETERMINE, PETSC_DETERMINE, this, J));
    PetscCall(MatShellSetOperation(*J, MATOP_MULT, (void (*)(void))j_mult));
    PetscCall(MatShellSetOperation(*J, MATOP_MULT_TRANSPOSE, (void (*)(void))j_mult_transpose));
    PetscCall(MatSetUp(*J));
    PetscFunctionReturn(0);
  }

  // G does not depend on the parameters (they enter U0 only): dG/dp is a zero shell.
  PetscErrorCode create_jacobian_p(Mat *Jp) override {
    PetscFunctionBeginUser;
    PetscCall(MatCreateShell(grid_->comm(), grid_->local_points(), params_->local_size(), PETSC_DETERMINE,
                             PETSC_DETERMINE, this, Jp));
    PetscCall(MatShellSetOperation(*Jp, MATOP_MULT, (void (*)(void))zero_mult));
    PetscCall(MatShellSetOperation(*Jp, MATOP_MULT_TRANSPOSE, (void (*)(void))zero_mult));
    PetscFunctionReturn(0);
  }
  PetscErrorCode rhs_jacobian_p(PetscReal, Vec, Mat) override { return 0; }

  PetscErrorCode set_parameters(Vec p) override {
    PetscFunctionBeginUser;
    PetscCall(params_->scalar(p, alpha_index_, &alpha_));
    PetscCall(params_->scalar(p, vt_index_, &vt_));
    PetscCheck(vt_ > 0, grid_->comm(), PETSC_ERR_ARG_OUTOFRANGE, "vlasov_vt (thermal spread) must be positive, got %g",
               (double)vt_);
    if (ic_ == TWO_STREAM) {
      PetscCall(params_->scalar(p, v0_index_, &v0_));
      PetscCall(params_->scalar(p, ratio_index_, &ratio_));
      PetscCheck(ratio_ > 0, grid_->comm(), PETSC_ERR_ARG_OUTOFRANGE,
                 "vlasov_temperature_ratio must be positive, got %g", (double)ratio_);
    }
    PetscFunctionReturn(0);
  }

  // G(U) = -v D_x f + E D_v f (- the dissipation), with U read in place like the transpose reads x:
  // owned rows from U's array, the two rows beyond each end of the owned block and the two x ghosts
  // of each row from the Halo, no ghosted copy of U (DMGlobalToLocal gathers every point through an
  // index list). The exchange is begun first and
  // overlaps the density sum and its reduction, then the sweep of the rows that need no ghost row
  // (with x split over ranks, the part of each row that needs no x ghost). G is the same bitwise as
  // advection_row (+ dissipation_row) on a ghosted copy gives.
  PetscErrorCode rhs(PetscReal, Vec U, Vec G) override {
    const Grid &g = *grid_;
    const Halo &h = halo_;
    const PetscScalar *u;
    PetscScalar *go;
    PetscFunctionBeginUser;
    const PetscInt xm = g.xm(), ys = g.ys(), ym = g.ym(), nv = nv_;
    // x whole on this rank: each row's x ghosts are its own periodic ends; on one rank nothing is
    // exchanged (the rows beyond the velocity bounds are zero).
    const bool x_whole = xm == nx_, exchange = !x_whole || nranks_ > 1;
    if (exchange) PetscCall(halo_.begin(U));
    PetscCall(VecGetArrayRead(U, &u));
    sum_density(u);
    PetscCall(field_from_row_sums(E_));
    PetscCall(VecGetArray(G, &go));
    PetscScalar *below = ghost_rows_.data(), *above = below + 2 * xm, *pad = above + 2 * xm;
    const PetscScalar *zero = zero_row_.data();
    auto row = [&](PetscInt jl) -> const PetscScalar * {
      const PetscInt j = ys + jl;
      if (j < 0 || j >= nv) return zero; // beyond the velocity bounds
      return jl < 0 ? below + (jl + 2) * xm : jl >= ym ? above + (jl - ym) * xm : u + jl * xm;
    };
    // x ghosts of row jl: o = -2, -1 (left) and xm, xm + 1 (right)
    auto xghost = [&](PetscInt o, PetscInt jl) {
      const PetscScalar *r = u + jl * xm;
      if (!x_whole) return h(o, jl);
      return o < 0 ? r[xm + o] : r[o - xm];
    };
    auto padded = [&](PetscInt jl) { // row jl with its two x ghosts on either side, readable on [-2, xm + 2)
      pad[0] = xghost(-2, jl);
      pad[1] = xghost(-1, jl);
      std::memcpy(pad + 2, u + jl * xm, sizeof(PetscScalar) * xm);
      pad[xm + 2] = xghost(xm, jl);
      pad[xm + 3] = xghost(xm + 1, jl);
      return (const PetscScalar *)pad + 2;
    };
    const PetscReal *E = E_.data();
    const PetscReal cv = 1.0 / (12 * hv_);
    // Advection on the points [i0, i0 + n) of row jl, reading row jl through r (r[0] is point i0).
    auto advect = [&](PetscInt jl, PetscInt i0, PetscInt n, const PetscScalar *r) {
      const PetscInt j = ys + jl;
      const PetscReal cx = -g.y(j) / (12 * h_);
      const PetscScalar *m2 = row(jl - 2) + i0, *m1 = row(jl - 1) + i0, *p1 = row(jl + 1) + i0, *p2 = row(jl + 2) + i0;
      if (j >= 1 && j <= nv - 2) advection_row_interior(n, cx, cv, r, m2, m1, p1, p2, E + i0, go + jl * xm + i0);
      else {
        PetscReal c[5];
        dv_row(j, c);
        advection_row_bound(n, cx, c, r, m2, m1, p1, p2, E + i0, go + jl * xm + i0);
      }
    };
    // The points of row jl that read no x ghost.
    auto middle = [&](PetscInt jl) {
      if (xm >= 4) advect(jl, 2, xm - 4, u + jl * xm + 2);
    };
    // The rest of row jl: its two points next to each end in x (from short padded copies), then the
    // dissipation of the whole row.
    auto finish = [&](PetscInt jl) {
      const PetscScalar *r = u + jl * xm;
      if (xm >= 4) {
        const PetscScalar left[6] = {xghost(-2, jl), xghost(-1, jl), r[0], r[1], r[2], r[3]};
        const PetscScalar right[6] = {r[xm - 4], r[xm - 3], r[xm - 2], r[xm - 1], xghost(xm, jl), xghost(xm + 1, jl)};
        advect(jl, 0, 2, left + 2);
        advect(jl, xm - 2, 2, right + 2);
      } else advect(jl, 0, xm, padded(jl));
      if (c_diss_ > 0) {
        const PetscScalar *rows[5] = {row(jl - 2), row(jl - 1), padded(jl), row(jl + 1), row(jl + 2)};
        dissipation_in_rows(rows, ys + jl, go + jl * xm);
      }
    };
    // Rows [lo, hi) need no ghost row (rows beyond the velocity bounds are zero, not exchanged).
    const PetscInt lo = std::min<PetscInt>(ym, ys > 0 ? 2 : 0);
    const PetscInt hi = std::max(lo, ys + ym < nv ? ym - 2 : ym);
    if (!exchange)
      for (PetscInt jl = 0; jl < ym; ++jl) {
        middle(jl);
        finish(jl);
      }
    else {
      for (PetscInt jl = lo; jl < hi; ++jl) { // while the ghosts arrive
        middle(jl);
        if (x_whole) finish(jl);
      }
      PetscCall(halo_.end(U));
      for (PetscInt k = 0; k < 2; ++k)
        for (PetscInt il = 0; il < xm; ++il) {
          below[k * xm + il] = h(il, k - 2);
          above[k * xm + il] = h(il, ym + k);
        }
      for (PetscInt jl = 0; jl < ym; ++jl) {
        const bool early = jl >= lo && jl < hi;
        if (!early) middle(jl);
        if (!early || !x_whole) finish(jl);
      }
    }
    PetscCall(VecRestoreArray(G, &go));
    PetscCall(VecRestoreArrayRead(U, &u));
    PetscFunctionReturn(0);
  }

  // Records what dG/dU needs of the linearisation state f: a copy of f at the owned points and
  // E(f), in one pass over f (the copy and the density together) and no ghost exchange. D_v f,
  // which only dG/dU itself needs, is made from the copy on the first MatMult (j_mult); the
  // transpose reads f directly (w = S (f o D_v^T x), see j_mult_transpose). (An explicit RK
  // adjoint stage does without the copy: stage_adjoint.)
  PetscErrorCode rhs_jacobian(PetscReal, Vec U, Mat J) override {
    const Grid &g = *grid_;
    const PetscScalar *u;
    PetscScalar *c;
    PetscFunctionBeginUser;
    PetscCall(VecGetArrayRead(U, &u));
    PetscCall(VecGetArrayWrite(f_lin_, &c));
    std::fill(rho_.begin(), rho_.end(), 0.0);
    PetscReal *rho = rho_.data() + g.xs();
    const PetscInt xm = g.xm();
    for (PetscInt jl = 0; jl < g.ym(); ++jl) {
      const PetscScalar *ur = u + jl * xm;
      PetscScalar *cr = c + jl * xm;
      for (PetscInt il = 0; il < xm; ++il) {
        cr[il] = ur[il];
        rho[il] += PetscRealPart(ur[il]);
      }
    }
    PetscCall(VecRestoreArrayWrite(f_lin_, &c));
    PetscCall(VecRestoreArrayRead(U, &u));
    // The density is reduced here, so that the transpose's one sweep knows E. (Deferring it to the
    // transpose's own reduction of w saves a synchronisation but needs a second pass over x and y,
    // which costs more.)
    PetscCall(field_from_row_sums(Elin_));
    dvf_valid_ = false;
    PetscCall(MatAssemblyBegin(J, MAT_FINAL_ASSEMBLY)); // resets any shift/scale a TS applied
    PetscCall(MatAssemblyEnd(J, MAT_FINAL_ASSEMBLY));
    PetscFunctionReturn(0);
  }

  PetscErrorCode spectrum(Spectrum *s) override {
    PetscReal symbol = 0; // max over theta of the fourth-order first-derivative symbol
    for (PetscInt q = 0; q <= 1000; ++q) {
      const PetscReal th = PETSC_PI * q / 1000;
      symbol = std::max(symbol, (8 * std::sin(th) - std::sin(2 * th)) / 6);
    }
    const PetscReal vmax = std::max(std::fabs(grid_->y0()), std::fabs(grid_->y1()));
    const PetscReal Emax = std::max(E0_max_, E_cfl_);
    s->imag_radius = symbol * (vmax / h_ + Emax / hv_);
    s->real_radius = 0;
    s->samples.clear();
    if (c_diss_ > 0) { // symbols of the x and v operators at the extreme coefficients, summed over both angles
      const int m = 48;
      for (int a = 0; a <= m; ++a)
        for (int b = 0; b <= m; ++b) {
          const PetscReal tx = PETSC_PI * a / m, tv = PETSC_PI * b / m;
          const PetscReal sx = (8 * std::sin(tx) - std::sin(2 * tx)) / 6, sv = (8 * std::sin(tv) - std::sin(2 * tv)) / 6;
          const PetscReal qx = std::pow(2 - 2 * std::cos(tx), 2), qv = std::pow(2 - 2 * std::cos(tv), 2);
          const PetscReal re = -c_diss_ * (vmax / (12 * h_) * qx + Emax / (12 * hv_) * qv);
          const PetscReal im = vmax / h_ * sx + Emax / hv_ * sv;
          s->samples.emplace_back(re, im);
          s->samples.emplace_back(re, -im);
        }
    }
    return 0;
  }

  PetscErrorCode initial_condition(Vec p, Vec U0) override {
    PetscScalar **f;
    PetscFunctionBeginUser;
    const Grid &g = *grid_;
    PetscCall(DMDAVecGetArray(dm_, U0, &f));
    for (PetscInt j = g.ys(); j < g.ys() + g.ym(); ++j) {
      const PetscReal F = velocity_profile(g.y(j));
      for (PetscInt i = g.xs(); i < g.xs() + g.xm(); ++i) f[j][i] = (1 + alpha_ * std::cos(k_ * g.x(i))) * F;
    }
    PetscCall(DMDAVecRestoreArray(dm_, U0, &f));
    PetscCall(functional("field_energy", U0, nullptr, nullptr)); // sets E_ from U0
    PetscReal emax = 0;
    for (PetscReal e : E_) emax = std::max(emax, std::fabs(e));
    PetscCallMPI(MPI_Allreduce(&emax, &E0_max_, 1, MPIU_REAL, MPI_MAX, g.comm()));
    PetscFunctionReturn(0);
  }

  // grad += sum_ij lambda_ij d f0_ij / dp.
  PetscErrorCode initial_condition_transpose(Vec, Vec lambda0, Vec grad) override {
    const PetscScalar **l;
    PetscReal s[4] = {0, 0, 0, 0}; // alpha, vt, v0, ratio
    PetscFunctionBeginUser;
    const Grid &g = *grid_;
    PetscCall(DMDAVecGetArrayRead(dm_, lambda0, &l));
    for (PetscInt j = g.ys(); j < g.ys() + g.ym(); ++j) {
      PetscReal lc = 0, ls = 0; // sum_i lambda cos(k x), sum_i lambda (1 + alpha cos(k x))
      for (PetscInt i = g.xs(); i < g.xs() + g.xm(); ++i) {
        const PetscReal c = std::cos(k_ * g.x(i)), lv = PetscRealPart(l[j][i]);
        lc += lv * c;
        ls += lv * (1 + alpha_ * c);
      }
      PetscReal dF[3];
      const PetscReal F = velocity_profile(g.y(j), dF);
      s[0] += lc * F;
      for (int q = 0; q < 3; ++q) s[q + 1] += ls * dF[q];
    }
    PetscCall(DMDAVecRestoreArrayRead(dm_, lambda0, &l));
    PetscCall(params_->add_local_sum(grad, alpha_index_, s[0]));
    PetscCall(params_->add_local_sum(grad, vt_index_, s[1]));
    if (ic_ == TWO_STREAM) {
      PetscCall(params_->add_local_sum(grad, v0_index_, s[2]));
      PetscCall(params_->add_local_sum(grad, ratio_index_, s[3]));
    }
    PetscFunctionReturn(0);
  }

  PetscErrorCode functional(const char *fname, Vec U, PetscReal *value, Vec dFdU) override {
    enum { FIELD, MASS, MOMENTUM, KINETIC, ENERGY, L2, NONE } which = NONE;
    const char *names[] = {"field_energy", "mass", "momentum", "kinetic_energy", "energy", "l2"};
    for (int q = 0; q < 6; ++q)
      if (!std::strcmp(fname, names[q])) which = static_cast<decltype(which)>(q);
    PetscFunctionBeginUser;
    PetscCheck(which != NONE, grid_->comm(), PETSC_ERR_ARG_WRONG,
               "Model vlasov has no functional '%s': choose one of %s", fname, functional_names().c_str());
    const Grid &g = *grid_;
    const PetscReal cell = h_ * hv_;
    PetscReal W = 0, local[2] = {0, 0}; // field energy; sum of the phase-space moment, sum f^2
    std::vector<PetscReal> KE;           // K E at the owned x (for dW/df)
    const bool needs_field = which == FIELD || which == ENERGY;
    if (needs_field) {
      const PetscScalar *u;
      PetscCall(VecGetArrayRead(U, &u));
      sum_density(u);
      PetscCall(VecRestoreArrayRead(U, &u));
      PetscCall(field_from_row_sums(E_));
      // W = 0.5 h sum_i E_i^2 over all x (every rank holds the whole E after field_from_row_sums()).
      for (PetscReal e : ks_) W += 0.5 * h_ * e * e;
      if (dFdU) { // dW/df_ij = h hv (K E)_i
        Efull_ = ks_;
        KE.resize(g.xm());
        apply_K(Efull_, KE);
      }
    }
    if (which == FIELD) {
      if (value) *value = W;
      if (dFdU) {
        PetscScalar **d;
        PetscCall(DMDAVecGetArray(dm_, dFdU, &d));
        for (PetscInt j = g.ys(); j < g.ys() + g.ym(); ++j)
          for (PetscInt i = g.xs(); i < g.xs() + g.xm(); ++i) d[j][i] = cell * KE[i - g.xs()];
        PetscCall(DMDAVecRestoreArray(dm_, dFdU, &d));
      }
      PetscFunctionReturn(0);
    }
    // Moments: F = cell sum_ij m(v_j) f_ij (mass, momentum, kinetic energy), or the L2 norm.
    auto moment = [&](PetscReal v) { return which == MASS ? 1.0 : which == MOMENTUM ? v : 0.5 * v * v; };
    {
      const PetscScalar **f;
      PetscCall(DMDAVecGetArrayRead(dm_, U, &f));
      for (PetscInt j = g.ys(); j < g.ys() + g.ym(); ++j) {
        const PetscReal mv = moment(g.y(j));
        for (PetscInt i = g.xs(); i < g.xs() + g.xm(); ++i) {
          const PetscReal fv = PetscRealPart(f[j][i]);
          local[0] += cell * mv * fv;
          local[1] += cell * fv * fv;
        }
      }
      PetscCall(DMDAVecRestoreArrayRead(dm_, U, &f));
    }
    PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, local, 2, MPIU_REAL, MPI_SUM, g.comm()));
    const PetscReal l2 = std::sqrt(local[1]);
    if (value) *value = which == L2 ? l2 : which == ENERGY ? local[0] + W : local[0];
    if (dFdU) {
      PetscScalar **d;
      const PetscScalar **f = nullptr;
      if (which == L2) PetscCall(DMDAVecGetArrayRead(dm_, U, &f));
      PetscCall(DMDAVecGetArray(dm_, dFdU, &d));
      for (PetscInt j = g.ys(); j < g.ys() + g.ym(); ++j) {
        const PetscReal mv = moment(g.y(j));
        for (PetscInt i = g.xs(); i < g.xs() + g.xm(); ++i) {
          if (which == L2) d[j][i] = l2 > 0 ? cell * PetscRealPart(f[j][i]) / l2 : 0.0;
          else d[j][i] = cell * mv + (which == ENERGY ? cell * KE[i - g.xs()] : 0.0);
        }
      }
      PetscCall(DMDAVecRestoreArray(dm_, dFdU, &d));
      if (f) PetscCall(DMDAVecRestoreArrayRead(dm_, U, &f));
    }
    PetscFunctionReturn(0);
  }

private:
  // Ghosted copy of U with f = 0 beyond the velocity bounds (ghost rows the scatter does not fill).
  // Only dG/dU x (j_mult, make_dvf) still uses it; rhs and the transpose read their input in place.
  PetscErrorCode to_local(Vec U, Vec Ul) {
    PetscScalar **a;
    PetscInt gxs, gys, gxm, gym;
    PetscFunctionBeginUser;
    PetscCall(DMGlobalToLocal(dm_, U, INSERT_VALUES, Ul));
    const Grid &g = *grid_;
    if (g.ys() > 0 && g.ys() + g.ym() < nv_) PetscFunctionReturn(0);
    PetscCall(DMDAGetGhostCorners(dm_, &gxs, &gys, nullptr, &gxm, &gym, nullptr));
    PetscCall(DMDAVecGetArray(dm_, Ul, &a));
    for (PetscInt j = gys; j < gys + gym; ++j)
      if (j < 0 || j >= nv_)
        for (PetscInt i = gxs; i < gxs + gxm; ++i) a[j][i] = 0;
    PetscCall(DMDAVecRestoreArray(dm_, Ul, &a));
    PetscFunctionReturn(0);
  }

  // G on row j: -v_j D_x f + E D_v f (E at the owned x), times sign, plus add (when given) at
  // the owned x.
  void advection_row(const PetscScalar *const *f, PetscInt j, const PetscReal *E, PetscScalar *g, PetscReal sign = 1,
                     const PetscReal *add = nullptr) const {
    const Grid &gr = *grid_;
    const PetscInt xs = gr.xs(), xe = gr.xs() + gr.xm();
    const PetscReal cx = -sign * gr.y(j) / (12 * h_), cv = sign / (12 * hv_);
    const PetscScalar *r = f[j];
    if (j >= 1 && j <= nv_ - 2) {
      const PetscScalar *m2 = f[j - 2], *m1 = f[j - 1], *p1 = f[j + 1], *p2 = f[j + 2];
      for (PetscInt i = xs; i < xe; ++i)
        g[i] = cx * (r[i - 2] - 8.0 * r[i - 1] + 8.0 * r[i + 1] - r[i + 2]) +
               E[i - xs] * cv * (m2[i] - 8.0 * m1[i] + 8.0 * p1[i] - p2[i]);
    } else {
      PetscReal c[5];
      dv_row(j, c);
      const PetscScalar *m2 = f[j - 2], *m1 = f[j - 1], *p1 = f[j + 1], *p2 = f[j + 2];
      for (PetscInt i = xs; i < xe; ++i)
        g[i] = cx * (r[i - 2] - 8.0 * r[i - 1] + 8.0 * r[i + 1] - r[i + 2]) +
               sign * E[i - xs] * (c[0] * m2[i] + c[1] * m1[i] + c[2] * r[i] + c[3] * p1[i] + c[4] * p2[i]);
    }
    if (add)
      for (PetscInt i = xs; i < xe; ++i) g[i] += add[i - xs];
  }

  // F(v) and, when dF is given, (dF/dvt, dF/dv0, dF/dratio).
  PetscReal velocity_profile(PetscReal v, PetscReal *dF = nullptr) const {
    // dM/ds = M (u^2 / s^3 - 1 / s), dM/du = -M u / s^2
    auto dMds = [](PetscReal u, PetscReal s) { return maxwellian(u, s) * (u * u / (s * s * s) - 1 / s); };
    if (ic_ == LANDAU) {
      if (dF) {
        dF[0] = dMds(v, vt_);
        dF[1] = dF[2] = 0;
      }
      return maxwellian(v, vt_);
    }
    const PetscReal s1 = vt_, s2 = vt_ * std::sqrt(ratio_), u1 = v - v0_, u2 = v + v0_;
    const PetscReal M1 = maxwellian(u1, s1), M2 = maxwellian(u2, s2);
    if (dF) {
      dF[0] = 0.5 * (dMds(u1, s1) + dMds(u2, s2) * std::sqrt(ratio_));
      dF[1] = 0.5 * (M1 * u1 / (s1 * s1) - M2 * u2 / (s2 * s2));
      dF[2] = 0.5 * dMds(u2, s2) * vt_ / (2 * std::sqrt(ratio_));
    }
    return 0.5 * (M1 + M2);
  }

  // g -= c [ |v_j| / 12h  d_x^4 f + E_cfl / 12hv  Q f ] on row j. d_x^4 = (1, -4, 6, -4, 1) is
  // periodic; Q = (B^T B)^2 with B^T B the second difference without flux through the velocity
  // bounds, i.e. the same stencil inside and (2, -3, 1), (-3, 6, -4, 1) on the two rows next to
  // each bound. Both are symmetric positive semi-definite with zero column sums: the term only
  // dissipates, keeps the mass, and is its own transpose.
  // rows[o] is row j + o - 2 from its first owned x (il = 0), rows[2] readable on [-2, xm + 2); g is
  // row j of the output from its first owned x.
  void dissipation_in_rows(const PetscScalar *const rows[5], PetscInt j, PetscScalar *g) const {
    const Grid &gr = *grid_;
    const PetscInt xm = gr.xm();
    const PetscReal cx = c_diss_ * std::fabs(gr.y(j)) / (12 * h_), cv = c_diss_ * E_cfl_ / (12 * hv_);
    PetscReal w[5] = {1, -4, 6, -4, 1};
    if (j == 0) w[0] = w[1] = 0, w[2] = 2, w[3] = -3;
    else if (j == 1) w[0] = 0, w[1] = -3;
    else if (j == nv_ - 2) w[4] = 0, w[3] = -3;
    else if (j == nv_ - 1) w[4] = w[3] = 0, w[2] = 2, w[1] = -3;
    const PetscScalar *r = rows[2];
    for (PetscInt i = 0; i < xm; ++i) {
      PetscScalar q = 0;
      for (int o = 0; o < 5; ++o)
        if (w[o] != 0) q += w[o] * rows[o][i];
      g[i] -= cx * (r[i - 2] - 4.0 * r[i - 1] + 6.0 * r[i] - 4.0 * r[i + 1] + r[i + 2]) + cv * q;
    }
  }
  // The same on a ghosted 2D array f and output row g (global x indices).
  void dissipation_row(const PetscScalar *const *f, PetscInt j, PetscScalar *g) const {
    const PetscInt xs = grid_->xs();
    const PetscScalar *rows[5] = {f[j - 2] + xs, f[j - 1] + xs, f[j] + xs, f[j + 1] + xs, f[j + 2] + xs};
    dissipation_in_rows(rows, j, g + xs);
  }

  // Face value F_{j+1/2} (zero for the outer faces j = -1 and j = N_v - 1).
  PetscReal face(const PetscScalar *const *f, PetscInt i, PetscInt j) const {
    if (j < 0 || j > nv_ - 2) return 0;
    return PetscRealPart(face_w[0] * f[j - 1][i] + face_w[1] * f[j][i] + face_w[2] * f[j + 1][i] + face_w[3] * f[j + 2][i]);
  }
  PetscReal dv(const PetscScalar *const *f, PetscInt i, PetscInt j) const {
    if (j >= 1 && j <= nv_ - 2)
      return PetscRealPart(f[j - 2][i] - 8.0 * f[j - 1][i] + 8.0 * f[j + 1][i] - f[j + 2][i]) / (12 * hv_);
    return (face(f, i, j) - face(f, i, j - 1)) / hv_;
  }
  // Row j of D_v as weights c[o] of f_{j+o}, o = -2..2 (c[0] for o = -2): (F_{j+1/2} - F_{j-1/2}) / hv
  // with no flux through the outer faces. Used on the rows next to the bounds.
  void dv_row(PetscInt j, PetscReal c[5]) const {
    for (int o = 0; o < 5; ++o) c[o] = 0;
    for (PetscInt q = j - 1; q <= j; ++q) { // face q + 1/2 reads f_{q-1+m}
      if (q < 0 || q > nv_ - 2) continue;
      const PetscReal sgn = q == j ? 1.0 : -1.0;
      for (PetscInt m = 0; m < 4; ++m) c[q - 1 + m - j + 2] += sgn * face_w[m] / hv_;
    }
  }
  // Row j of D_v^T in the same form: each face q + 1/2 that reads f_j (with weight w) contributes
  // w (z_q - z_{q+1}) / hv. Rows beyond the bounds get weight 0 (and read as 0 in the ghosted arrays).
  void dv_transpose_row(PetscInt j, PetscReal c[5]) const {
    for (int o = 0; o < 5; ++o) c[o] = 0;
    for (PetscInt m = 0; m < 4; ++m) {
      const PetscInt q = j + 1 - m; // face q + 1/2 reads f_{q-1+m} = f_j
      if (q < 0 || q > nv_ - 2) continue;
      c[q - j + 2] += face_w[m] / hv_;
      c[q + 1 - j + 2] -= face_w[m] / hv_;
    }
  }

  // E at the owned x from the density of f (collective): E = -K rho. ks_ is left holding E at
  // every x.
  PetscErrorCode field(const PetscScalar *const *f, std::vector<PetscReal> &E) {
    const Grid &g = *grid_;
    PetscFunctionBeginUser;
    std::fill(rho_.begin(), rho_.end(), 0.0);
    for (PetscInt j = g.ys(); j < g.ys() + g.ym(); ++j)
      for (PetscInt i = g.xs(); i < g.xs() + g.xm(); ++i) rho_[i] += PetscRealPart(f[j][i]);
    PetscCall(field_from_row_sums(E));
    PetscFunctionReturn(0);
  }
  // rho_ = this rank's sums over v of f (without hv) from the owned points u of a global Vec's array,
  // row by row (the order of field()'s sums).
  void sum_density(const PetscScalar *u) {
    const Grid &g = *grid_;
    std::fill(rho_.begin(), rho_.end(), 0.0);
    PetscReal *__restrict rho = rho_.data() + g.xs();
    const PetscInt xm = g.xm();
    for (PetscInt jl = 0; jl < g.ym(); ++jl) {
      const PetscScalar *__restrict ur = u + jl * xm;
      for (PetscInt il = 0; il < xm; ++il) rho[il] += PetscRealPart(ur[il]);
    }
  }
  // E = -K rho at the owned x from rho_ holding this rank's sums over v of f (without hv):
  // completes rho over the ranks (collective).
  PetscErrorCode field_from_row_sums(std::vector<PetscReal> &E) {
    PetscFunctionBeginUser;
    PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, rho_.data(), (PetscMPIInt)nx_, MPIU_REAL, MPI_SUM, grid_->comm()));
    field_from_sums(E);
    PetscFunctionReturn(0);
  }
  // The same with rho_ already summed over the ranks.
  void field_from_sums(std::vector<PetscReal> &E) {
    for (PetscReal &r : rho_) r *= -hv_;
    apply_K(rho_, E);
  }
  // out_il = (K s)_i for the owned i = xs + il; K s over all x is left in ks_.
  void apply_K(const std::vector<PetscReal> &s, std::vector<PetscReal> &out) {
    const Grid &g = *grid_;
    fft_.antiderivative(s.data(), ks_);
    for (PetscInt il = 0; il < g.xm(); ++il) out[il] = ks_[g.xs() + il];
  }

  static PetscErrorCode zero_mult(Mat, Vec, Vec y) { return VecSet(y, 0.0); }

  // D_v f at the owned points of the linearisation state, from the copy rhs_jacobian made (once
  // per linearisation: only dG/dU x needs it, the transpose does not).
  PetscErrorCode make_dvf() {
    const PetscScalar **f;
    const Grid &g = *grid_;
    PetscFunctionBeginUser;
    if (dvf_valid_) PetscFunctionReturn(0);
    dvf_.resize(g.local_points());
    PetscCall(to_local(f_lin_, U_local_));
    PetscCall(DMDAVecGetArrayRead(dm_, U_local_, &f));
    for (PetscInt j = g.ys(); j < g.ys() + g.ym(); ++j) {
      PetscReal *row = &dvf_[(j - g.ys()) * g.xm()];
      for (PetscInt i = g.xs(); i < g.xs() + g.xm(); ++i) row[i - g.xs()] = dv(f, i, j);
    }
    PetscCall(DMDAVecRestoreArrayRead(dm_, U_local_, &f));
    dvf_valid_ = true;
    PetscFunctionReturn(0);
  }

  // y = dG/dU x = -v D_x x + E D_v x + dE D_v f,  dE = -K rho(x)
  static PetscErrorCode j_mult(Mat J, Vec x, Vec y) {
    VlasovModel *m;
    const PetscScalar **xa;
    PetscScalar **ya;
    PetscFunctionBeginUser;
    PetscCall(MatShellGetContext(J, &m));
    const Grid &g = *m->grid_;
    PetscCall(m->make_dvf());
    PetscCall(m->to_local(x, m->X_local_));
    PetscCall(DMDAVecGetArrayRead(m->dm_, m->X_local_, &xa));
    PetscCall(m->field(xa, m->dE_));
    PetscCall(DMDAVecGetArray(m->dm_, y, &ya));
    for (PetscInt j = g.ys(); j < g.ys() + g.ym(); ++j) {
      m->advection_row(xa, j, m->Elin_.data(), ya[j]);
      if (m->c_diss_ > 0) m->dissipation_row(xa, j, ya[j]);
      const PetscReal *dvf = &m->dvf_[(j - g.ys()) * g.xm()];
      for (PetscInt il = 0; il < g.xm(); ++il) ya[j][g.xs() + il] += m->dE_[il] * dvf[il];
    }
    PetscCall(DMDAVecRestoreArray(m->dm_, y, &ya));
    PetscCall(DMDAVecRestoreArrayRead(m->dm_, m->X_local_, &xa));
    PetscFunctionReturn(0);
  }

  // y = (dG/dU)^T x = v D_x x + E D_v^T x + hv K w,  w_i = sum_j x_ij (D_v f)_ij = sum_j f_ij (D_v^T x)_ij.
  // The second form of w needs only the owned f (no ghosts of the linearisation state, no stored
  // D_v f) and D_v^T x, which the sweep for y computes anyway: one sweep makes v D_x x + E D_v^T x
  // and w together, and after the reduction of w a streaming pass adds hv K w.
  // On more than one rank, w is reduced over the ranks before the K pass (rhs_jacobian reduced the
  // density): with the exchange of x's ghosts (overlapped with the sweep), three synchronisations per
  // adjoint stage.
  // x is read in place: its owned rows from its array, the two rows beyond each end of the owned
  // block and the two x ghosts of each row from the Halo, so no ghosted copy of x is made
  // (DMGlobalToLocal gathers every point through an index list).
  static PetscErrorCode j_mult_transpose(Mat J, Vec x, Vec y) {
    VlasovModel *m;
    PetscFunctionBeginUser;
    PetscCall(MatShellGetContext(J, &m));
    PetscCall(m->transpose(m->f_lin_, m->Elin_.data(), x, y));
    PetscFunctionReturn(0);
  }

  // An explicit RK adjoint stage at the stored stage U: y = (dG/dU)(U)^T x as j_mult_transpose, read
  // from U in place (rhs_jacobian would copy it), with E(U) as G's evaluation at the stage recorded it
  // (stage records: the owned x of E, the same numbers bitwise) or else from one pass over U; no dG/dp (mu).
  PetscErrorCode stage_adjoint(PetscReal, Vec U, const PetscScalar *record, Vec x, Vec y, Vec) override {
    const PetscScalar *u;
    PetscFunctionBeginUser;
    if (record) {
      PetscCall(transpose(U, record, x, y));
      PetscFunctionReturn(0);
    }
    PetscCall(VecGetArrayRead(U, &u));
    sum_density(u);
    PetscCall(VecRestoreArrayRead(U, &u));
    PetscCall(field_from_row_sums(Estage_));
    PetscCall(transpose(U, Estage_.data(), x, y));
    PetscFunctionReturn(0);
  }
  bool has_stage_adjoint() const override { return true; }
  PetscInt stage_record_size() const override { return grid_->xm(); }
  PetscErrorCode rhs_record(PetscReal t, Vec U, Vec G, PetscScalar *record) override {
    PetscFunctionBeginUser;
    PetscCall(rhs(t, U, G));
    std::copy(E_.begin(), E_.begin() + grid_->xm(), record);
    PetscFunctionReturn(0);
  }

  // y = (dG/dU)(f)^T x at the state f with field E = E(f) (see j_mult_transpose).
  PetscErrorCode transpose(Vec f, const PetscReal *E, Vec x, Vec y) {
    VlasovModel *m = this;
    const PetscScalar *xo, *fl;
    PetscScalar *yo;
    PetscFunctionBeginUser;
    const Grid &g = *m->grid_;
    const Halo &h = m->halo_;
    const PetscInt xm = g.xm(), ys = g.ys(), ym = g.ym(), nv = m->nv_, nx = m->nx_;
    // x whole on this rank (1 rank, or a split in v only): each row's x ghosts are its own periodic
    // ends, and the rows away from the ends of the owned block are swept while the ghost rows arrive.
    // On one rank with x whole there is nothing to exchange (the rows beyond the bounds are zero).
    const bool x_whole = xm == nx, exchange = !x_whole || m->nranks_ > 1;
    if (exchange) PetscCall(m->halo_.begin(x));
    PetscCall(VecGetArrayRead(x, &xo));
    PetscScalar *below = m->ghost_rows_.data(), *above = below + 2 * xm, *pad = above + 2 * xm;
    auto row = [&](PetscInt jl) { return jl < 0 ? below + (jl + 2) * xm : jl >= ym ? above + (jl - ym) * xm : xo + jl * xm; };
    auto padded = [&](PetscInt jl) { // row jl with its two x ghosts on either side
      const PetscScalar *xr = xo + jl * xm;
      pad[0] = x_whole ? xr[xm - 2] : h(-2, jl);
      pad[1] = x_whole ? xr[xm - 1] : h(-1, jl);
      std::memcpy(pad + 2, xr, sizeof(PetscScalar) * xm);
      pad[xm + 2] = x_whole ? xr[0] : h(xm, jl);
      pad[xm + 3] = x_whole ? xr[1] : h(xm + 1, jl);
      return (const PetscScalar *)pad + 2;
    };
    PetscCall(VecGetArrayRead(f, &fl));
    PetscCall(VecGetArray(y, &yo));
    std::fill(m->w_.begin(), m->w_.end(), 0.0);
    PetscReal *w = m->w_.data() + g.xs();
    const PetscReal cv = -1.0 / (12 * m->hv_);
    auto sweep_row = [&](PetscInt jl) {
      const PetscInt j = ys + jl;
      const PetscScalar *rows[5] = {row(jl - 2), row(jl - 1), padded(jl), row(jl + 1), row(jl + 2)};
      const PetscScalar *fr = fl + jl * xm;
      PetscScalar *yr = yo + jl * xm;
      const PetscReal cx = g.y(j) / (12 * m->h_);
      PetscReal d[5];
      if (j < 2 || j > nv - 3) m->dv_transpose_row(j, d); // the two rows next to each bound: D_v^T row by row
      if (j >= 2 && j <= nv - 3) // D_v^T = -D_v, D_x^T = -D_x
        transpose_row_interior(xm, cx, cv, rows[2], rows[0], rows[1], rows[3], rows[4], E, fr, yr, w);
      else transpose_row_bound(xm, cx, d, rows[2], rows[0], rows[1], rows[3], rows[4], E, fr, yr, w);
      if (m->c_diss_ > 0) m->dissipation_in_rows(rows, j, yr); // symmetric
    };
    const PetscInt early_end = exchange && x_whole ? std::max<PetscInt>(2, ym - 2) : 2;
    for (PetscInt jl = 2; jl < early_end; ++jl) sweep_row(jl); // the rows that need no ghost row
    if (exchange) PetscCall(m->halo_.end(x));
    for (PetscInt k = 0; k < 2; ++k) // zero beyond the velocity bounds
      for (PetscInt il = 0; il < xm; ++il) {
        below[k * xm + il] = h(il, k - 2);
        above[k * xm + il] = h(il, ym + k);
      }
    if (early_end > 2) { // the rows next to the ends of the owned block
      for (PetscInt jl = 0; jl < std::min<PetscInt>(2, ym); ++jl) sweep_row(jl);
      for (PetscInt jl = early_end; jl < ym; ++jl) sweep_row(jl);
    } else
      for (PetscInt jl = 0; jl < ym; ++jl) sweep_row(jl); // in order
    PetscCall(VecRestoreArrayRead(f, &fl));
    if (m->nranks_ > 1) PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, m->w_.data(), (PetscMPIInt)nx, MPIU_REAL, MPI_SUM, g.comm()));
    m->apply_K(m->w_, m->dE_);
    const PetscReal hv = m->hv_;
    for (PetscInt il = 0; il < xm; ++il) m->dE_[il] *= hv; // hv K w
    const PetscReal *__restrict c = m->dE_.data();
    for (PetscInt jl = 0; jl < ym; ++jl) {
      PetscScalar *__restrict yr = yo + jl * xm;
      for (PetscInt il = 0; il < xm; ++il) yr[il] += c[il]; // + hv K w
    }
    PetscCall(VecRestoreArrayRead(x, &xo));
    PetscCall(VecRestoreArray(y, &yo));
    PetscFunctionReturn(0);
  }

  const Grid *grid_ = nullptr;
  DM dm_ = nullptr;
  Parameters *params_ = nullptr;
  PetscInt ic_ = LANDAU, mode_ = 1, nx_ = 0, nv_ = 0;
  PetscReal h_ = 1, hv_ = 1, k_ = 0.5, E_cfl_ = default_E_cfl, E0_max_ = 0, c_diss_ = 0;
  PetscReal alpha_ = 0, vt_ = 1, v0_ = 0, ratio_ = 1;
  PetscInt alpha_index_ = -1, vt_index_ = -1, v0_index_ = -1, ratio_index_ = -1;
  // Serial real FFT of length N_x for the zero-mean antiderivative K (the same on every rank).
  struct Antiderivative {
    PetscInt n = 0;
    double *in = nullptr;
    fftw_complex *out = nullptr;
    fftw_plan forward = nullptr, backward = nullptr;
    std::vector<PetscReal> inv_kappa; // 1/kappa_m for the kept modes, 0 for the others
    void setup(PetscInt n_, PetscReal L) {
      release();
      n = n_;
      in = fftw_alloc_real(n);
      out = fftw_alloc_complex(n / 2 + 1);
      forward = fftw_plan_dft_r2c_1d((int)n, in, out, FFTW_ESTIMATE);
      backward = fftw_plan_dft_c2r_1d((int)n, out, in, FFTW_ESTIMATE);
      inv_kappa.assign(n / 2 + 1, 0.0);
      for (PetscInt m = 1; 2 * m < n; ++m) inv_kappa[m] = L / (2 * PETSC_PI * m);
    }
    // r = K s over all N_x points: (K s)^_m = s^_m / (i kappa_m).
    void antiderivative(const PetscReal *s, std::vector<PetscReal> &r) {
      for (PetscInt l = 0; l < n; ++l) in[l] = s[l];
      fftw_execute(forward);
      for (PetscInt m = 0; m <= n / 2; ++m) { // (a + ib) / (i kappa) = (b - ia) / kappa, and 1/n
        const double a = out[m][0], b = out[m][1], c = inv_kappa[m] / n;
        out[m][0] = b * c;
        out[m][1] = -a * c;
      }
      fftw_execute(backward);
      r.resize(n);
      for (PetscInt l = 0; l < n; ++l) r[l] = in[l];
    }
    void release() {
      if (forward) fftw_destroy_plan(forward);
      if (backward) fftw_destroy_plan(backward);
      if (in) fftw_free(in);
      if (out) fftw_free(out);
      forward = backward = nullptr;
      in = nullptr;
      out = nullptr;
    }
    ~Antiderivative() { release(); }
  };
  Antiderivative fft_;
  std::vector<PetscReal> rho_, w_, ks_, Efull_; // length-N_x work arrays
  std::vector<PetscReal> E_, Elin_, dE_; // at the owned x: E(U) of rhs, E at the linearisation state, work
  std::vector<PetscReal> Estage_;        // at the owned x: E at stage_adjoint's stage
  std::vector<PetscReal> dvf_;           // D_v f at the owned points of the linearisation state (j_mult only)
  bool dvf_valid_ = false;               // dvf_ belongs to the current linearisation state
  OwnedVec U_local_, X_local_;
  Halo halo_;                          // ghosts of U for rhs, of x for the transpose (j_mult_transpose)
  PetscMPIInt nranks_ = 1;
  std::vector<PetscScalar> ghost_rows_; // rhs's and the transpose's rows beyond the owned block (2 + 2) and a padded row
  std::vector<PetscScalar> zero_row_;   // rhs: a row beyond the velocity bounds
  OwnedVec f_lin_; // the linearisation state f (owned points), copied by rhs_jacobian
};

} // namespace

FLEXIPDE_REGISTER_MODEL("vlasov", VlasovModel);

} // namespace flexipde
