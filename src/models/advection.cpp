// Linear advection-diffusion of one scalar on a periodic grid, in 1D or 2D.
//
//   1D (default):        u_t + a u_x         = (D u_x)_x                on [x0, x1) periodic
//   2D (-advection_dim 2): u_t + a u_x + b u_y = (D u_x)_x + (D u_y)_y    on [x0, x1) x [y0, y1)
//   u(x, 0) = u0(x; A)
//
// The velocities a (-advection_a) and, in 2D only, b (-advection_b) are scalar parameters. A 1D
// scene has no b and no second grid direction. Diffusion is optional: -advection_diffusion
// (default on exactly when -advection_D, -advection_D_field or -advection_D_profile is given) adds
// the parameter D, one scalar (-advection_D) or a field D(x) (-advection_D_field 1). Without it
// the scene declares no D and assembles no diffusion term. A 2D scene defaults to a 64 x 64 grid,
// periodic in both directions.
//
// Space (h the grid spacing of the direction, all stencils periodic, applied per direction):
//   -advection_scheme fd2     (u_x)_i = (u_{i+1} - u_{i-1}) / 2h                          order 2
//   -advection_scheme fd4     (u_x)_i = (u_{i-2} - 8u_{i-1} + 8u_{i+1} - u_{i+2}) / 12h   order 4
//   -advection_scheme upwind  (u_x)_i = (u_i - u_{i-1}) / h for a >= 0, (u_{i+1} - u_i) / h
//                             for a < 0: order 1, monotone (no new extrema on a square pulse)
//   -advection_scheme spectral  Fourier differentiation with FFTW-MPI (include/flexipde/spectral.hpp),
//                             exponential accuracy for smooth u; N even in every direction
//   Finite-difference diffusion in conservative flux form, per direction G_i = (F_{i+1/2} - F_{i-1/2})/h
//   for -fd_order 2, F_f = D_f (u_x)_f at the faces f = i+1/2:
//     -fd_order 2: (u_x)_f = (u_{i+1} - u_i) / h,  D_f = (D_i + D_{i+1}) / 2
//     -fd_order 4: (u_x)_f = (u_{i-1} - 27u_i + 27u_{i+1} - u_{i+2}) / 24h,
//                  D_f = (-D_{i-1} + 9D_i + 9D_{i+1} - D_{i+2}) / 16,
//                  G_i = (F_{i-3/2} - 27F_{i-1/2} + 27F_{i+1/2} - F_{i+3/2}) / 24h
//   i.e. G_diff = -sum_d B_d^T diag(D_f) B_d u with B_d the face gradient of direction d: symmetric,
//   negative semi-definite while every D_f >= 0, conservative and of the stated order for a smooth
//   field D too. -fd_order defaults to 4 with fd4 and to 2 otherwise.
//   Spectral diffusion: a scalar D is the multiplier -D |kappa|^2; a field D is
//   sum_d E_d diag(P D) E_d u with E_d = P d/dx_d, P the 2/3-rule truncation: the product D u_x is
//   de-aliased (both factors truncated, the product truncated), and the operator stays symmetric
//   negative semi-definite while P D >= 0 (checked).
//
//   G(U; a, b, D) = A(a, b, D) U,   A = -a D_x - b D_y + G_diff       dG/dU = A (constant)
//   dG/da = -D_x u, dG/db = -D_y u                                   (one column each)
//   dG/dD = -sum_d B_d^T diag(B_d u) I_d (field; a scalar D sums the columns)
// Finite differences assemble A (AIJ); spectral A is a MatShell with MULT and MULT_TRANSPOSE (the
// transposed Fourier multiplier), so an implicit integrator solves with unpreconditioned GMRES
// (the Simulation's default for a shell Jacobian). dG/dp is a MatShell for every scheme. For
// upwind, dG/da is taken on the side of the current sign of a (one-sided at a = 0).
//
// Spectrum (for the explicit stability check): with no D or a scalar D, A is a sum of circulants
// per direction, normal, and its eigenvalues are the symbols lambda(theta_x) + lambda(theta_y),
// theta_k = 2 pi k / N: the model passes all of them and the Simulation checks |R(dt lambda)| <= 1
// for each. With a field D the eigenvalues lie in the field of values, inside W(advection) +
// [-Dmax rho, 0] (rho the largest |symbol|^2 of the face gradients); the model passes the boundary
// of that set (advection eigenvalues, the same shifted by -Dmax rho, and the two horizontal edges).
//
// Initial condition (-advection_ic, profile s, u0 = A s):
//   sinusoid  s = sin(2 pi m (x - x0) / Lx [+ 2 pi m_y (y - y0) / Ly] + phi)
//             -advection_ic_mode m, -advection_ic_mode_y m_y (2D, default 1), -advection_ic_phase phi
//   gaussian  s = exp(-|d|^2 / w^2)                  d the periodic distance to the centre
//   square    s = 1 where |d_x| < w/2 [and |d_y| < w/2], else 0      w = -advection_ic_width
//   centre -advection_ic_center [-advection_ic_center_y], default the middle of the domain.
// The amplitude A (-advection_ic_amplitude) is a plain value unless -advection_ic_amplitude_param 1
// declares it as the scalar parameter advection_ic_amplitude; then dU0/dA = s enters the gradient.
//
//   mpiexec -n 2 ./flexipde -model advection -grid_periodic 1 -grid_x1 6.283185307179586
//           -da_grid_x 64 -ts_dt 0.01 -ts_max_time 1 -task taylor -objective_type mean_square
//           -advection_ic_amplitude_param 1 -advection_D 0.05 -advection_D_field 1   (one line)
//   mpiexec -n 2 ./flexipde -model advection -grid_periodic 1 -task gradient -advection_scheme upwind
//           -advection_a 0.8 -true_advection_a 1 -ts_type cn -ts_dt 1e-3 -ts_max_time 0.5 -check_fd
//   mpiexec -n 2 ./flexipde -model advection -grid_periodic 1 -grid_x1 6.283185307179586 -da_grid_x 64
//           -advection_scheme spectral -advection_a 0.8 -true_advection_a 1 -ts_dt 0.01 -ts_max_time 1
//           -task gradient -check_fd
//   mpiexec -n 2 ./flexipde -model advection -advection_dim 2 -da_grid_x 32 -da_grid_y 32
//           -advection_a 0.8 -advection_b 0.5 -true_advection_b 0.6 -advection_D 0.01 -ts_dt 0.005
//           -ts_max_time 0.2 -task gradient -check_fd
#include "flexipde/differentiator.hpp"
#include "flexipde/halo.hpp"
#include "flexipde/sweep_support.hpp"
#include "flexipde/model.hpp"
#include "flexipde/spectral.hpp"
#include <petsc/private/petscimpl.h> // PetscObjectStateGet
#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <vector>

namespace flexipde {
namespace {

const char *const schemes[] = {"fd2", "fd4", "upwind", "spectral"};
enum Scheme : PetscInt { FD2 = 0, FD4 = 1, UPWIND = 2, SPECTRAL = 3 };
const char *const ic_names[] = {"sinusoid", "gaussian", "square"};
enum InitialCondition : PetscInt { SINUSOID = 0, GAUSSIAN = 1, SQUARE = 2 };
const char *const velocity_names[2] = {"advection_a", "advection_b"};

// Default diffusivity when diffusion is switched on without a value, and the 2D grid's default size.
constexpr PetscReal default_diffusion = 0.01;
constexpr PetscInt default_points_2d = 64;

using cplx = std::complex<PetscReal>;

// (dG/dp)^T x computed by the transpose of dG/dU (which reads the same x in the same sweep) for the
// dG/dp transpose that follows: an explicit RK adjoint stage applies J^T and then (dG/dp)^T to one
// unchanged Vec. Valid only for that Vec (id) in that state, at the same recorded stage (serial).
struct FusedProducts : ProductTag {
  PetscReal local[3] = {0, 0, 0}; // this rank's partial dot products (velocities, then a scalar D)
};

// The choices that fix the grid and the stencils. Read before the grid exists (its dimension and
// ghost width depend on them) without registering help, and again in setup with help.
struct StencilChoice {
  PetscInt dim = 1;
  PetscInt scheme = FD2;
  PetscBool diffusion = PETSC_FALSE;
  PetscInt diffusion_order = 2;
};

PetscErrorCode diffusion_requested(PetscBool *requested) {
  PetscBool a, b, c;
  PetscFunctionBeginUser;
  PetscCall(PetscOptionsHasName(nullptr, nullptr, "-advection_D", &a));
  PetscCall(PetscOptionsHasName(nullptr, nullptr, "-advection_D_field", &b));
  PetscCall(PetscOptionsHasName(nullptr, nullptr, "-advection_D_profile", &c));
  *requested = (a || b || c) ? PETSC_TRUE : PETSC_FALSE;
  PetscFunctionReturn(0);
}

PetscErrorCode read_stencil_choice(StencilChoice &s) {
  PetscFunctionBeginUser;
  PetscCall(PetscOptionsGetInt(nullptr, nullptr, "-advection_dim", &s.dim, nullptr));
  PetscCall(PetscOptionsGetEList(nullptr, nullptr, "-advection_scheme", schemes, 4, &s.scheme, nullptr));
  PetscCall(diffusion_requested(&s.diffusion));
  PetscCall(PetscOptionsGetBool(nullptr, nullptr, "-advection_diffusion", &s.diffusion, nullptr));
  s.diffusion_order = s.scheme == FD4 ? 4 : 2;
  PetscCall(PetscOptionsGetInt(nullptr, nullptr, "-fd_order", &s.diffusion_order, nullptr));
  PetscFunctionReturn(0);
}

// First-derivative weights at offsets -2..2 (times 1/h). Upwind takes the side the flow comes from.
std::array<PetscReal, 5> first_derivative_weights(PetscInt scheme, PetscReal a) {
  switch (scheme) {
  case FD4: return {1.0 / 12, -8.0 / 12, 0.0, 8.0 / 12, -1.0 / 12};
  case UPWIND: return a >= 0 ? std::array<PetscReal, 5>{0, -1, 1, 0, 0} : std::array<PetscReal, 5>{0, 0, -1, 1, 0};
  case SPECTRAL: return {0, 0, 0, 0, 0};
  default: return {0.0, -0.5, 0.0, 0.5, 0.0};
  }
}

// Face stencils of the diffusion: face f (= i + 1/2) reads cells f + offset + m, m < width.
struct FaceStencil {
  PetscInt offset, width;
  std::array<PetscReal, 4> grad;   // face gradient (times 1/h)
  std::array<PetscReal, 4> interp; // D at the face
};

FaceStencil face_stencil(PetscInt order) {
  if (order == 4) return {-1, 4, {1.0 / 24, -27.0 / 24, 27.0 / 24, -1.0 / 24}, {-1.0 / 16, 9.0 / 16, 9.0 / 16, -1.0 / 16}};
  return {0, 2, {-1.0, 1.0, 0, 0}, {0.5, 0.5, 0, 0}};
}

// One-dimensional face kernels (WD = the face stencil's width), on ghosted arrays: the faces the
// owned points [0, n) touch are k = 0 .. n + WD - 2, face k reading ghosted entries k .. k + WD - 1
// of a and b (the arrays passed start at the first of them). F_k = (sum_m pa[m] a) (sum_m pb[m] b).
template <int WD>
void face_products(PetscInt n, const PetscReal *__restrict pa, const PetscReal *__restrict pb,
                   const PetscScalar *__restrict a, const PetscScalar *__restrict b, PetscReal *__restrict F) {
  for (PetscInt k = 0; k < n + WD - 1; ++k) {
    PetscReal va = 0, vb = 0;
#pragma GCC unroll 4
    for (int m = 0; m < WD; ++m) {
      va += pa[m] * PetscRealPart(a[k + m]);
      vb += pb[m] * PetscRealPart(b[k + m]);
    }
    F[k] = va * vb;
  }
}
// A 1D field-D RK adjoint stage's face work in one pass over the faces and one over the points:
// y = a y - B^T diag(I D) B x / h^2 (Df = I D at the faces) and, unless g is null,
// g += -I^T (B u .* B x) / h^2 (a field D's gradient); x, u ghosted from the first face's first entry.
template <int WD, bool G>
void field_stage_faces(PetscInt n, const PetscReal *__restrict Df, const PetscReal *__restrict gr,
                       const PetscReal *__restrict ip, const PetscScalar *__restrict x, const PetscScalar *__restrict u,
                       PetscReal s, PetscReal a, PetscReal *__restrict F1, PetscReal *__restrict F2,
                       PetscScalar *__restrict y, PetscScalar *__restrict g) {
  for (PetscInt k = 0; k < n + WD - 1; ++k) {
    PetscReal bx = 0, bu = 0;
#pragma GCC unroll 4
    for (int m = 0; m < WD; ++m) {
      bx += gr[m] * PetscRealPart(x[k + m]);
      bu += gr[m] * PetscRealPart(u[k + m]);
    }
    F1[k] = Df[k] * bx;
    F2[k] = bu * bx;
  }
  for (PetscInt i = 0; i < n; ++i) {
    PetscReal v1 = 0, v2 = 0;
#pragma GCC unroll 4
    for (int q = 0; q < WD; ++q) {
      v1 -= gr[q] * F1[i + WD - 1 - q] * s;
      v2 -= ip[q] * F2[i + WD - 1 - q] * s;
    }
    y[i] = a * y[i] + v1;
    if (G) g[i] += v2;
  }
}
// y_i (+)= -sum_q w[q] F_{i + WD - 1 - q} s at the owned points (ADD: added to y).
template <int WD, bool ADD, class Y>
void gather_faces(PetscInt n, const PetscReal *__restrict w, PetscReal s, const PetscReal *__restrict F, Y *__restrict y) {
  for (PetscInt i = 0; i < n; ++i) {
    PetscReal v = 0;
#pragma GCC unroll 4
    for (int q = 0; q < WD; ++q) v -= w[q] * F[i + WD - 1 - q] * s;
    if (ADD) y[i] += v;
    else y[i] = v;
  }
}

// Two-dimensional face kernels, one direction d at a time (a0, b0: ghosted arrays at the first owned
// point; rows sy apart; xm x ym owned points, y row-major xm x ym): the faces along d around every
// owned point, each once, F = (sum_m pa[m] a) (sum_m pb[m] b), then y (+)= -sum_q w[q] F s.
template <int WD, bool ADD, class Y>
void faces_2d(PetscInt d, PetscInt xm, PetscInt ym, PetscInt sy, const PetscReal *pa, const PetscReal *pb,
              const PetscReal *w, const PetscScalar *a0, const PetscScalar *b0, PetscReal s, PetscReal *F, Y *y) {
  if (d == 0) { // along x: row by row, as in 1D
    for (PetscInt jl = 0; jl < ym; ++jl) {
      const PetscInt base = jl * sy - (WD - 1);
      face_products<WD>(xm, pa, pb, a0 + base, b0 + base, F);
      gather_faces<WD, ADD>(xm, w, s, F, y + jl * xm);
    }
    return;
  }
  for (PetscInt kf = 0; kf < ym + WD - 1; ++kf) { // along y: face rows, vectorised along x
    PetscReal *__restrict Fr = F + kf * xm;
    for (PetscInt i = 0; i < xm; ++i) {
      PetscReal va = 0, vb = 0;
#pragma GCC unroll 4
      for (int m = 0; m < WD; ++m) {
        const PetscInt g = (kf - (WD - 1) + m) * sy + i;
        va += pa[m] * PetscRealPart(a0[g]);
        vb += pb[m] * PetscRealPart(b0[g]);
      }
      Fr[i] = va * vb;
    }
  }
  for (PetscInt jl = 0; jl < ym; ++jl) {
    Y *__restrict yr = y + jl * xm;
    for (PetscInt i = 0; i < xm; ++i) {
      PetscReal v = 0;
#pragma GCC unroll 4
      for (int q = 0; q < WD; ++q) v -= w[q] * F[(jl + WD - 1 - q) * xm + i] * s;
      if (ADD) yr[i] += v;
      else yr[i] = v;
    }
  }
}

// A 2D stage's u for the face kernels, read in place: owned rows from U's array (xm apart), ghost rows
// and the ghosts at either end of a row from a Halo (null: one rank holding everything, periodic).
struct URows {
  const PetscScalar *u;
  PetscInt xm, ym;
  const Halo *h;
  const PetscScalar *row(PetscInt j) const {
    if (j >= 0 && j < ym) return u + j * xm;
    if (h) return h->ghost_row(j);
    return u + ((j % ym + ym) % ym) * xm;
  }
  // Row jl with its w ghosts on either side, into b (xm + 2 w entries, b[w] = (0, jl)).
  void ghosted_row(PetscInt jl, PetscInt w, PetscScalar *b) const {
    const PetscScalar *r = u + jl * xm;
    for (PetscInt k = 1; k <= w; ++k) {
      b[w - k] = h ? (*h)(-k, jl) : r[xm - k];
      b[w + xm - 1 + k] = h ? (*h)(xm - 1 + k, jl) : r[k - 1];
    }
    std::copy(r, r + xm, b + w);
  }
};

// One face row along y (x at its first row of WD, rows sy apart; u's WD rows ur): f1 = df .* B x,
// f2 = B u .* B x.
template <int WD, bool G>
void face_row_2d(PetscInt xm, PetscInt sy, const PetscReal *__restrict df, const PetscReal *__restrict gr,
                 const PetscScalar *__restrict x, const PetscScalar *const *ur, PetscReal *__restrict f1,
                 PetscReal *__restrict f2) {
  const PetscScalar *__restrict u0 = ur[0], *__restrict u1 = ur[1];
  const PetscScalar *__restrict u2 = WD == 4 ? ur[2] : ur[0], *__restrict u3 = WD == 4 ? ur[3] : ur[0];
  for (PetscInt i = 0; i < xm; ++i) {
    PetscReal bx = 0, bu = 0;
#pragma GCC unroll 4
    for (int m = 0; m < WD; ++m) bx += gr[m] * PetscRealPart(x[m * sy + i]);
    if (G) {
      bu += gr[0] * PetscRealPart(u0[i]);
      bu += gr[1] * PetscRealPart(u1[i]);
      if (WD == 4) {
        bu += gr[2] * PetscRealPart(u2[i]);
        bu += gr[3] * PetscRealPart(u3[i]);
      }
    }
    f1[i] = df[i] * bx;
    if (G) f2[i] = bu * bx;
  }
}

// A 2D field-D RK adjoint stage's face work (x0, u0 ghosted at the first owned point, rows sy apart):
// with (B x)_f computed once per face, y += -s_d B_d^T (Df_d .* B_d x) (Df = I D at the faces, cached:
// along x, row jl's faces at jl (xm + WD - 1) + k; along y, face row kf at kf xm + i) and, unless g is
// null, g += -s_d I_d^T (B_d u .* B_d x) (the field D's gradient), d = x, y.
// Both directions in one pass over the rows: for row jl, its x faces (as in 1D,
// row buffers F1, F2 of xm + WD - 1), then its y faces from a ring R1, R2 of the WD face rows below and
// above it (WD x xm each): each face row is formed once, as the rows reach it, and applied while in L1,
// instead of both directions' full face arrays being written and read back. The same arithmetic as the
// two passes: y += x part, then y += y part, term by term in the same order.
// First(jl) runs at the start of row jl, before its faces are added to y's row (the rest of the stage
// writing that row: with y and x's rows in L1 when the faces come).
template <int WD, bool G, class First>
void field_stage_faces_2d_rows(PetscInt xm, PetscInt ym, PetscInt sy, const PetscReal *__restrict Dfx,
                               const PetscReal *__restrict Dfy, const PetscReal *__restrict gr,
                               const PetscReal *__restrict ip, const PetscScalar *x0, const URows &U,
                               PetscReal sx, PetscReal syy, PetscReal *__restrict F1, PetscReal *__restrict F2,
                               PetscReal *__restrict R1, PetscReal *__restrict R2, PetscScalar *__restrict ub,
                               PetscScalar *__restrict y, PetscScalar *__restrict g, const First &first) {
  // face row kf (between ghosted rows kf - WD and kf - 1) into ring slot kf % WD
  auto face_row = [&](PetscInt kf) {
    const PetscScalar *ur[WD];
    for (int m = 0; m < WD; ++m) ur[m] = G ? U.row(kf - (WD - 1) + m) : nullptr;
    face_row_2d<WD, G>(xm, sy, Dfy + kf * xm, gr, x0 + (kf - (WD - 1)) * sy, ur, R1 + (kf % WD) * xm, R2 + (kf % WD) * xm);
  };
  for (PetscInt kf = 0; kf < WD - 1; ++kf) face_row(kf);
  for (PetscInt jl = 0; jl < ym; ++jl) {
    const PetscInt base = jl * sy - (WD - 1);
    PetscScalar *__restrict yr = y + jl * xm, *__restrict gq = G ? g + jl * xm : nullptr;
    first(jl);
    if (G) U.ghosted_row(jl, WD - 1, ub); // (without a gradient u is not used: x stands in)
    field_stage_faces<WD, G>(xm, Dfx + jl * (xm + WD - 1), gr, ip, x0 + base, G ? ub : x0 + base, sx, 1.0, F1, F2, yr,
                             gq);
    face_row(jl + WD - 1);
    // the ring slots of face rows jl + WD - 1 - q, q = 0 .. WD - 1 (WD is 2 or 4)
    const PetscReal *__restrict a0 = R1 + ((jl + WD - 1) % WD) * xm, *__restrict a1 = R1 + ((jl + WD - 2) % WD) * xm;
    const PetscReal *__restrict a2 = R1 + ((jl + 2 * WD - 3) % WD) * xm, *__restrict a3 = R1 + ((jl + 2 * WD - 4) % WD) * xm;
    const PetscReal *__restrict b0 = R2 + ((jl + WD - 1) % WD) * xm, *__restrict b1 = R2 + ((jl + WD - 2) % WD) * xm;
    const PetscReal *__restrict b2 = R2 + ((jl + 2 * WD - 3) % WD) * xm, *__restrict b3 = R2 + ((jl + 2 * WD - 4) % WD) * xm;
    for (PetscInt i = 0; i < xm; ++i) {
      PetscReal v1 = 0, v2 = 0;
      v1 -= gr[0] * a0[i] * syy;
      if (G) v2 -= ip[0] * b0[i] * syy;
      v1 -= gr[1] * a1[i] * syy;
      if (G) v2 -= ip[1] * b1[i] * syy;
      if (WD == 4) {
        v1 -= gr[2] * a2[i] * syy;
        if (G) v2 -= ip[2] * b2[i] * syy;
        v1 -= gr[3] * a3[i] * syy;
        if (G) v2 -= ip[3] * b3[i] * syy;
      }
      yr[i] += v1;
      if (G) gq[i] += v2;
    }
  }
}

// A 2D field-D RK adjoint stage with fd2 faces, everything of row jl in one loop over its points: the
// advection transpose with the velocities' terms (z0, z1 as sweep_sums_row writes them), the x faces on
// either side of the point, the y face above it (written to the ring slot the next row reads as its
// face below) and the y face below it (from the ring). The fd2 faces' weights are exact: B x = x_k -
// x_{k-1} (grad = (-1, 1)) and I D = (D_{k-1} + D_k) / 2 (interp = (1/2, 1/2)), so the generic sums of
// field_stage_faces_2d_rows reduce to
//   y += s (F1_r - F1_l) (F1 = I D .* B x),   g += -(s F2_r + s F2_l) / 2 (F2 = B u .* B x)
// per direction (s = 1/h^2), the same numbers as theirs (only the sign of a zero can differ: the
// products with -1, 1 and 1/2 are exact and -(a + b) = -a - b), with fewer operations. An x face is
// formed twice (as the right face of i and the left face of i + 1) instead of being stored and read
// back. l: x at the row's first owned point (ghosted, rows sy apart); ub: u's row with one ghost on
// either side (ub[0] = u(-1)); uu: u's row jl + 1; dfx: the row's x faces (xm + 1); dfy: the y faces
// above the row (face row jl + 1); lo1, lo2: the ring's face row below; up1, up2: the ring slot for the
// face row above. vx, vy: sweep_sums_row's taps, c0, c1 its coefficients.
template <int R>
__attribute__((optimize("tree-vectorize", "vect-cost-model=dynamic")))
void field_stage_row_fd2(PetscInt xm, PetscInt sy, const PetscScalar *__restrict l, const PetscReal *vx,
                         const PetscReal *vy, PetscReal c0, PetscReal c1, const PetscScalar *__restrict ub,
                         const PetscScalar *__restrict uu, const PetscReal *__restrict dfx,
                         const PetscReal *__restrict dfy, PetscReal sx, PetscReal syy, const PetscReal *__restrict lo1,
                         const PetscReal *__restrict lo2, PetscReal *__restrict up1, PetscReal *__restrict up2,
                         PetscReal *__restrict z0, PetscReal *__restrict z1, PetscScalar *__restrict y,
                         PetscScalar *__restrict g) {
  PetscReal tx[2 * R + 1], ty[2 * R + 1];
  for (int k = 0; k < 2 * R + 1; ++k) tx[k] = vx[k], ty[k] = vy[k];
  for (PetscInt i = 0; i < xm; ++i) {
    // sweep_sums_row<R, 2, false>
    PetscReal sxv = 0, syv = 0;
#pragma GCC unroll 8
    for (int k = -R; k <= R; ++k) sxv += tx[k + R] * PetscRealPart(l[i + k]);
#pragma GCC unroll 8
    for (int k = -R; k <= R; ++k) syv += ty[k + R] * PetscRealPart(l[i + k * sy]);
    z0[i] = sxv;
    z1[i] = syv;
    const PetscReal x0 = PetscRealPart(l[i]), u0 = PetscRealPart(ub[i + 1]);
    // the x faces i (left) and i + 1 (right)
    const PetscReal bxl = x0 - PetscRealPart(l[i - 1]), bxr = PetscRealPart(l[i + 1]) - x0;
    const PetscReal bul = u0 - PetscRealPart(ub[i]), bur = PetscRealPart(ub[i + 2]) - u0;
    const PetscReal f1l = dfx[i] * bxl, f2l = bul * bxl, f1r = dfx[i + 1] * bxr, f2r = bur * bxr;
    const PetscReal yx = (c0 * sxv + c1 * syv) + (f1r * sx - f1l * sx);
    const PetscReal gx = PetscRealPart(g[i]) + (f2r * sx + f2l * sx) * -0.5;
    // the y face above (rows jl, jl + 1), kept for the next row, and the one below
    const PetscReal bxu = PetscRealPart(l[i + sy]) - x0, buu = PetscRealPart(uu[i]) - u0;
    const PetscReal f1u = dfy[i] * bxu, f2u = buu * bxu;
    up1[i] = f1u;
    up2[i] = f2u;
    y[i] = yx + (f1u * syy - lo1[i] * syy);
    g[i] = gx + (f2u * syy + lo2[i] * syy) * -0.5;
  }
}

// The 1D field-D RK adjoint stage with fd2 faces in one loop over the points (field_stage_row_fd2's
// 1D counterpart): z = D^T x (times h, sweep_row's sum), y = a z + s (F1_r - F1_l) and
// g += -(s F2_r + s F2_l) / 2, the numbers of sweep_row + field_stage_faces<2, true> (up to the sign
// of a zero). l, ul: x and u at the first owned point, ghosted; df: the faces (n + 1); t: the taps.
template <int R>
__attribute__((optimize("tree-vectorize", "vect-cost-model=dynamic")))
void field_stage_fd2_1d(PetscInt n, const PetscScalar *__restrict l, const PetscScalar *__restrict ul, const PetscReal *t,
                        const PetscReal *__restrict df, PetscReal s, PetscReal a, PetscReal *__restrict z,
                        PetscScalar *__restrict y, PetscScalar *__restrict g) {
  PetscReal tx[2 * R + 1];
  for (int k = 0; k < 2 * R + 1; ++k) tx[k] = t[k];
  for (PetscInt i = 0; i < n; ++i) {
    PetscReal sw = 0;
#pragma GCC unroll 8
    for (int k = -R; k <= R; ++k) sw += tx[k + R] * PetscRealPart(l[i + k]);
    z[i] = sw;
    const PetscReal x0 = PetscRealPart(l[i]), u0 = PetscRealPart(ul[i]);
    const PetscReal bxl = x0 - PetscRealPart(l[i - 1]), bxr = PetscRealPart(l[i + 1]) - x0;
    const PetscReal bul = u0 - PetscRealPart(ul[i - 1]), bur = PetscRealPart(ul[i + 1]) - u0;
    const PetscReal f1l = df[i] * bxl, f2l = bul * bxl, f1r = df[i + 1] * bxr, f2r = bur * bxr;
    y[i] = a * sw + (f1r * s - f1l * s);
    g[i] = PetscRealPart(g[i]) + (f2r * s + f2l * s) * -0.5;
  }
}

class AdvectionModel final : public LinearModel {
public:
  const char *name() const override { return "advection"; }
  PetscInt dof() const override { return 1; }
  const char *component_name(PetscInt) const override { return "u"; }
  PetscInt stencil_width(MPI_Comm) const override {
    StencilChoice s;
    if (quiet_read(s)) return 1; // setup reports the bad option
    return half_width(s);
  }
  PetscInt dim() const override {
    StencilChoice s;
    if (quiet_read(s)) return 1;
    return s.dim == 2 ? 2 : 1; // setup refuses other values
  }
  void grid_defaults(GridOptions &g) const override {
    g.periodic = g.periodic_y = PETSC_TRUE; // the only boundary implemented
    if (dim() != 2) return;                  // 1D: the grid's own number of points
    g.n = g.ny = default_points_2d;
  }

  PetscErrorCode setup(const Grid &grid, DM state_dm, Parameters &params) override {
    StencilChoice s;
    SecondDerivative order_reader; // reads and checks -fd_order
    PetscFunctionBeginUser;
    grid_ = &grid;
    dm_ = state_dm;
    params_ = &params;
    dim_ = grid.dim();
    const PetscReal L = grid.x1() - grid.x0();
    center_[0] = 0.5 * (grid.x0() + grid.x1());
    center_[1] = 0.5 * (grid.y0() + grid.y1());
    width_ = 0.1 * L;
    PetscCall(read_stencil_choice(s));
    PetscInt dim_opt = s.dim;
    scheme_ = s.scheme;
    diffusion_ = s.diffusion;
    PetscOptionsBegin(grid.comm(), nullptr, "Advection-diffusion model u_t + a u_x (+ b u_y) = div(D grad u)", "Advection");
    PetscCall(PetscOptionsInt("-advection_dim", "Space dimension: 1, or 2 (velocity (a, b), grid -da_grid_x x -da_grid_y)",
                              "Advection", s.dim, &dim_opt, nullptr));
    PetscCall(PetscOptionsEList("-advection_scheme",
                                "First derivative of the advection: fd2, fd4 (centred), upwind, or spectral (FFTW)",
                                "Advection", schemes, 4, schemes[s.scheme], &scheme_, nullptr));
    PetscCall(PetscOptionsBool("-advection_diffusion",
                               "Add div(D grad u) with the parameter D (default: on when -advection_D* is given)",
                               "Advection", s.diffusion, &diffusion_, nullptr));
    PetscCall(PetscOptionsBool("-advection_D_field", "Diffusivity D is a field (one value per grid point), else one scalar",
                               "Advection", D_field_, &D_field_, nullptr));
    PetscCall(PetscOptionsEList("-advection_ic", "Initial profile", "Advection", ic_names, 3, ic_names[ic_], &ic_, nullptr));
    PetscCall(PetscOptionsBool("-advection_ic_amplitude_param",
                               "Declare the amplitude A of u0 = A s(x) as the parameter advection_ic_amplitude",
                               "Advection", amplitude_param_, &amplitude_param_, nullptr));
    if (!amplitude_param_)
      PetscCall(PetscOptionsReal("-advection_ic_amplitude", "Amplitude A of u0 = A s(x)", "Advection", amplitude_,
                                 &amplitude_, nullptr));
    PetscCall(PetscOptionsInt("-advection_ic_mode", "sinusoid: number m of periods in x", "Advection", mode_[0], &mode_[0],
                              nullptr));
    PetscCall(PetscOptionsReal("-advection_ic_phase", "sinusoid: phase phi", "Advection", phase_, &phase_, nullptr));
    PetscCall(PetscOptionsReal("-advection_ic_center", "gaussian, square: centre (x)", "Advection", center_[0], &center_[0],
                               nullptr));
    if (dim_ == 2) {
      PetscCall(PetscOptionsInt("-advection_ic_mode_y", "sinusoid: number of periods in y", "Advection", mode_[1],
                                &mode_[1], nullptr));
      PetscCall(PetscOptionsReal("-advection_ic_center_y", "gaussian, square: centre (y)", "Advection", center_[1],
                                 &center_[1], nullptr));
    }
    PetscCall(PetscOptionsReal("-advection_ic_width", "gaussian: width w of exp(-(d/w)^2); square: full width", "Advection",
                               width_, &width_, nullptr));
    PetscOptionsEnd();
    PetscCheck(dim_opt == 1 || dim_opt == 2, grid.comm(), PETSC_ERR_ARG_OUTOFRANGE,
               "-advection_dim %" PetscInt_FMT " is not offered: choose 1 or 2", dim_opt);
    PetscCheck(grid.periodic() && (dim_ == 1 || grid.periodic_y()), grid.comm(), PETSC_ERR_ARG_WRONG,
               "Model advection needs a periodic grid (-grid_periodic 1%s): inflow and outflow boundaries are not "
               "implemented",
               dim_ == 2 ? " -grid_periodic_y 1" : "");
    PetscCheck(width_ > 0, grid.comm(), PETSC_ERR_ARG_OUTOFRANGE, "-advection_ic_width must be positive, got %g",
               (double)width_);
    if (diffusion_ && scheme_ != SPECTRAL) {
      PetscCall(SecondDerivative::from_options(grid.comm(), nullptr, scheme_ == FD4 ? 4 : 2, order_reader));
      face_ = face_stencil(order_reader.order());
    }
    { // the grid was made for the choice read before setup; -help or a prefix must not change it
      StencilChoice now{dim_, scheme_, diffusion_, diffusion_ ? order_reader.order() : 2};
      PetscCheck(half_width(now) <= grid.stencil_width() && dim_opt == dim_, grid.comm(), PETSC_ERR_PLIB,
                 "Advection stencil half-width %" PetscInt_FMT " or dimension %" PetscInt_FMT
                 " differs from the grid's (%" PetscInt_FMT ", %" PetscInt_FMT ")",
                 half_width(now), dim_opt, grid.stencil_width(), dim_);
    }
    if (scheme_ == SPECTRAL) PetscCall(spectral_.setup(grid));
    lazy_ = scheme_ != SPECTRAL && !(diffusion_ && D_field_);

    for (PetscInt d = 0; d < dim_; ++d) vel_index_[d] = params.add(velocity_names[d], ParamKind::Scalar);
    if (diffusion_)
      D_index_ = params.add("advection_D", D_field_ ? ParamKind::Field : ParamKind::Scalar, 0.0, default_diffusion);
    if (amplitude_param_) A_index_ = params.add("advection_ic_amplitude", ParamKind::Scalar, PETSC_NINFINITY, amplitude_);

    h_[0] = grid.h();
    h_[1] = dim_ == 2 ? grid.hy() : 1.0;
    for (PetscInt d = 0; d < 2; ++d) dGdv_scale_[d] = scheme_ == SPECTRAL ? -1.0 : -1.0 / h_[d];
    PetscCall(DMDAGetGhostCorners(dm_, &gxs_, &gys_, nullptr, &gxm_, nullptr, nullptr));
    if (dim_ == 1) gys_ = 0;
    stride_[0] = 1;
    stride_[1] = gxm_;
    if (scheme_ == SPECTRAL) {
      for (auto *v : {&t1_, &t2_, &t3_}) PetscCall(DMCreateGlobalVector(grid.dm(), v->out()));
      shared_dx_ = dim_ == 1 && !diffusion_;
      if (shared_dx_) PetscCall(DMCreateGlobalVector(grid.dm(), dx_.out()));
      if (diffusion_ && D_field_)
        for (PetscInt d = 0; d < dim_; ++d) PetscCall(DMCreateGlobalVector(grid.dm(), w_[d].out()));
    } else {
      PetscCall(DMCreateLocalVector(dm_, U_local_.out()));
      PetscCall(DMCreateLocalVector(dm_, X_local_.out()));
      PetscCall(DMDAGetInfo(dm_, nullptr, nullptr, nullptr, nullptr, nullptr, nullptr, nullptr, nullptr, &radius_, nullptr,
                            nullptr, nullptr, nullptr));
      // One rank holding every point of each (periodic) direction fills the ghosts by wrapping its
      // own rows around; otherwise the Halo communicates them.
      wrap_ = grid.xm() == grid.n() && (dim_ == 1 || grid.ym() == grid.ny());
      if (!wrap_) PetscCall(halo_.setup(grid, dm_, 0, radius_));
      if (!wrap_) PetscCall(halo2_.setup(grid, dm_, 0, radius_));
      if (!wrap_ && dim_ == 1) PetscCall(packed_.setup_packed(grid, radius_, diffusion_ && D_field_ ? 2 : 1));
    }
    if (diffusion_) {
      PetscCall(DMCreateGlobalVector(grid.dm(), D_.out()));
      PetscCall(DMCreateLocalVector(grid.dm(), D_local_.out()));
      if (D_field_) {
        PetscCall(DMCreateGlobalVector(grid.dm(), dD_.out()));
        PetscCall(DMCreateLocalVector(grid.dm(), dD_local_.out()));
      }
    }
    PetscCall(create_operator(dm_));
    for (PetscInt d = 0; d < dim_; ++d) dGdv_[d].assign(grid.local_points(), 0.0);
    dGdD_.assign(grid.local_points(), 0.0);
    if (lazy_) scratch_.assign(grid.local_points(), 0.0);
    faces_.assign((grid.xm() + 4) * (dim_ == 2 ? grid.ym() + 4 : 1), 0.0);
    faces2_.assign(grid.xm() + 4, 0.0);
    stage_scratch_.assign(std::max(grid.local_points(), 3 * grid.xm()), 0.0);
    if (diffusion_ && D_field_) gD_.assign(grid.local_points(), 0.0);
    PetscFunctionReturn(0);
  }

  // Spectral: a MatShell (the operator is dense in physical space). Finite differences: AIJ.
  PetscErrorCode create_jacobian(Mat *J) override {
    PetscFunctionBeginUser;
    if (scheme_ != SPECTRAL) {
      PetscCall(LinearModel::create_jacobian(J));
      PetscFunctionReturn(0);
    }
    const PetscInt n = grid_->local_points();
    PetscCall(MatCreateShell(grid_->comm(), n, n, PETSC_DETERMINE, PETSC_DETERMINE, this, J));
    PetscCall(MatShellSetOperation(*J, MATOP_MULT, (void (*)(void))spectral_mult));
    PetscCall(MatShellSetOperation(*J, MATOP_MULT_TRANSPOSE, (void (*)(void))spectral_mult_transpose));
    PetscFunctionReturn(0);
  }

  // Finite differences: dG/dU for explicit RK as a MatShell. Mult is the assembled A (the forward's
  // own operator); MultTranspose is one stencil sweep over x with its ghosts (Halo, or wrapped on
  // one rank) instead of AIJ's scatter-add transpose. Spectral has no other form than its shell.
  PetscErrorCode create_jacobian_matrix_free(Mat *J) override {
    PetscFunctionBeginUser;
    *J = nullptr;
    if (scheme_ == SPECTRAL) PetscFunctionReturn(0);
    const PetscInt n = grid_->local_points();
    PetscCall(MatCreateShell(grid_->comm(), n, n, PETSC_DETERMINE, PETSC_DETERMINE, this, J));
    PetscCall(MatShellSetOperation(*J, MATOP_MULT, (void (*)(void))jmf_mult));
    PetscCall(MatShellSetOperation(*J, MATOP_MULT_TRANSPOSE, (void (*)(void))jmf_mult_transpose));
    PetscFunctionReturn(0);
  }

  PetscErrorCode create_jacobian_p(Mat *Jp) override {
    PetscFunctionBeginUser;
    PetscCall(MatCreateShell(grid_->comm(), grid_->local_points(), params_->local_size(), PETSC_DETERMINE, PETSC_DETERMINE,
                             this, Jp));
    PetscCall(MatShellSetOperation(*Jp, MATOP_MULT, (void (*)(void))jp_mult));
    PetscCall(MatShellSetOperation(*Jp, MATOP_MULT_TRANSPOSE, (void (*)(void))jp_mult_transpose));
    PetscFunctionReturn(0);
  }

  PetscErrorCode set_parameters(Vec p) override {
    PetscFunctionBeginUser;
    for (PetscInt d = 0; d < dim_; ++d) {
      PetscCall(params_->scalar(p, vel_index_[d], &vel_[d]));
      w1_[d] = first_derivative_weights(scheme_, vel_[d]);
    }
    if (diffusion_) {
      if (D_field_) PetscCall(params_->get_field(p, D_index_, D_));
      else {
        PetscCall(params_->scalar(p, D_index_, &D_scalar_));
        PetscCall(VecSet(D_, D_scalar_));
      }
      PetscReal Dmin;
      PetscCall(VecMin(D_, nullptr, &Dmin));
      PetscCheck(Dmin >= 0, grid_->comm(), PETSC_ERR_ARG_OUTOFRANGE, "Diffusivity must be non-negative, found D = %g",
                 (double)Dmin);
      if (scheme_ == SPECTRAL) PetscCall(spectral_diffusivity());
      else {
        PetscCall(DMGlobalToLocal(grid_->dm(), D_, INSERT_VALUES, D_local_));
        PetscCall(face_diffusivity_range());
        PetscCall(cache_face_diffusivity());
      }
    }
    if (scheme_ != SPECTRAL) set_taps();
    else make_spectral_symbols();
    stage_.invalidate(); // dG/dp and any fused product are taken at the new parameters
    PetscCall(assemble(A_));
    PetscFunctionReturn(0);
  }

  // Records what the dG/dp shell needs at this state. Finite differences without a field D, and
  // spectral 1D without diffusion: the state U itself (RecordedStage, no copy); the columns -D_d u
  // and -B^T B u are formed only if the shell's Mult or an unfused transpose needs them, else the
  // transposes take <u, D_d^T x> from the sweep of dG/dU^T (FD) or <u, D_x x> from D_x x
  // (spectral). Otherwise: the columns now, and for a field D the ghosted u (FD) or the de-aliased
  // E_d u (spectral).
  PetscErrorCode rhs_jacobian_p(PetscReal, Vec U, Mat Jp) override {
    PetscFunctionBeginUser;
    if (shared_dx_ || lazy_) PetscCall(stage_.record(U));
    else if (scheme_ == SPECTRAL) PetscCall(spectral_columns(U));
    else PetscCall(fd_columns(U));
    // Reassembly resets any scaling TS applied since (theta's adjoint scales by -1). It costs an
    // options lookup (-mat_view) per call, so only when Jp changed since we last assembled it.
    PetscObjectId id;
    PetscObjectState state;
    PetscCall(PetscObjectGetId((PetscObject)Jp, &id));
    PetscCall(PetscObjectStateGet((PetscObject)Jp, &state));
    if (id != jp_id_ || state != jp_state_) {
      PetscCall(MatAssemblyBegin(Jp, MAT_FINAL_ASSEMBLY));
      PetscCall(MatAssemblyEnd(Jp, MAT_FINAL_ASSEMBLY));
      jp_id_ = id;
      PetscCall(PetscObjectStateGet((PetscObject)Jp, &jp_state_));
    }
    PetscFunctionReturn(0);
  }

  PetscErrorCode spectrum(Spectrum *s) override {
    PetscFunctionBeginUser;
    // Per-direction symbols of advection and of the (scalar-coefficient) diffusion, per mode.
    std::vector<cplx> adv[2];
    std::vector<PetscReal> diff[2];
    PetscReal diff_max = 0; // sum over directions of the largest |diffusion symbol| per unit D
    for (PetscInt d = 0; d < dim_; ++d) {
      const PetscInt n = d == 0 ? grid_->n() : grid_->ny();
      const PetscReal L = d == 0 ? grid_->x1() - grid_->x0() : grid_->y1() - grid_->y0();
      adv[d].resize(n);
      diff[d].resize(n);
      PetscReal dmax = 0;
      for (PetscInt k = 0; k < n; ++k) {
        if (scheme_ == SPECTRAL) {
          const PetscInt ks = k < n / 2 ? k : k - n;
          const PetscReal w = 2 * PETSC_PI * ks / L;
          adv[d][k] = ks == -n / 2 ? cplx(0) : cplx(0, -vel_[d] * w); // Nyquist: odd part 0
          diff[d][k] = (!diffusion_ ? 0 : D_field_ ? (3 * std::abs(ks) < n ? w * w : 0) : w * w);
        } else {
          const PetscReal th = 2 * PETSC_PI * k / n;
          cplx a = 0, b = 0;
          for (PetscInt j = -2; j <= 2; ++j) a += w1_[d][j + 2] * std::polar<PetscReal>(1.0, j * th);
          adv[d][k] = -vel_[d] / h_[d] * a;
          if (diffusion_)
            for (PetscInt m = 0; m < face_.width; ++m) b += face_.grad[m] * std::polar<PetscReal>(1.0, (face_.offset + m) * th);
          diff[d][k] = std::norm(b) / (h_[d] * h_[d]);
        }
        dmax = std::max(dmax, diff[d][k]);
      }
      diff_max += dmax;
    }
    const PetscInt nx = grid_->n(), ny = dim_ == 2 ? grid_->ny() : 1;
    auto &ev = s->samples;
    ev.clear();
    ev.reserve((size_t)nx * ny);
    const bool field = diffusion_ && D_field_;
    const PetscReal D = diffusion_ && !field ? D_scalar_ : 0.0;
    for (PetscInt ky = 0; ky < ny; ++ky)
      for (PetscInt kx = 0; kx < nx; ++kx) {
        cplx l = adv[0][kx] - D * diff[0][kx];
        if (dim_ == 2) l += adv[1][ky] - D * diff[1][ky];
        ev.push_back(l);
      }
    if (field) { // boundary of W(advection) + [-shift, 0]
      const PetscReal shift = Dmax_ * diff_max;
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

  PetscErrorCode initial_condition(Vec p, Vec U0) override {
    PetscFunctionBeginUser;
    PetscReal A = amplitude_;
    if (amplitude_param_) PetscCall(params_->scalar(p, A_index_, &A));
    Array U(U0);
    PetscCall(U.error());
    PetscInt il = 0;
    for (PetscInt j = grid_->ys(); j < grid_->ys() + grid_->ym(); ++j)
      for (PetscInt i = grid_->xs(); i < grid_->xs() + grid_->xm(); ++i) U[il++] = A * profile(i, j);
    PetscFunctionReturn(0);
  }

  PetscErrorCode initial_condition_transpose(Vec, Vec lambda0, Vec grad) override {
    PetscFunctionBeginUser;
    if (!amplitude_param_) PetscFunctionReturn(0);
    PetscReal local = 0;
    {
      ConstArray L(lambda0);
      PetscCall(L.error());
      PetscInt il = 0;
      for (PetscInt j = grid_->ys(); j < grid_->ys() + grid_->ym(); ++j)
        for (PetscInt i = grid_->xs(); i < grid_->xs() + grid_->xm(); ++i) local += profile(i, j) * PetscRealPart(L[il++]);
    }
    PetscCall(params_->add_local_sum(grad, A_index_, local));
    PetscFunctionReturn(0);
  }

private:
  // The early reads (before the grid exists) stay silent on a bad option: setup reports it once.
  static PetscErrorCode quiet_read(StencilChoice &s) {
    if (PetscPushErrorHandler(PetscReturnErrorHandler, nullptr)) return 1;
    const PetscErrorCode err = read_stencil_choice(s);
    (void)PetscPopErrorHandler();
    return err;
  }
  static PetscInt half_width(const StencilChoice &s) {
    if (s.scheme == SPECTRAL) return 1; // no stencil; the DMDA wants some ghost width
    const PetscInt adv = s.scheme == FD4 ? 2 : 1;
    const PetscInt diff = s.diffusion ? (s.diffusion_order == 4 ? 3 : 1) : 0;
    return std::max(adv, diff);
  }

  PetscReal profile(PetscInt i, PetscInt j) const {
    const PetscReal x = grid_->x(i), Lx = grid_->x1() - grid_->x0();
    const PetscReal y = dim_ == 2 ? grid_->y(j) : 0.0, Ly = grid_->y1() - grid_->y0();
    if (ic_ == SINUSOID) {
      PetscReal arg = 2 * PETSC_PI * mode_[0] * (x - grid_->x0()) / Lx + phase_;
      if (dim_ == 2) arg += 2 * PETSC_PI * mode_[1] * (y - grid_->y0()) / Ly;
      return std::sin(arg);
    }
    auto periodic_distance = [](PetscReal d, PetscReal L) { return d - L * std::floor(d / L + 0.5); }; // [-L/2, L/2)
    const PetscReal dx = periodic_distance(x - center_[0], Lx), dy = dim_ == 2 ? periodic_distance(y - center_[1], Ly) : 0;
    if (ic_ == GAUSSIAN) return std::exp(-(dx * dx + dy * dy) / (width_ * width_));
    return std::fabs(dx) < 0.5 * width_ && std::fabs(dy) < 0.5 * width_ ? 1.0 : 0.0;
  }

  // Position of point (i, j) in a ghosted local array (x fastest).
  PetscInt ghost_index(PetscInt i, PetscInt j) const { return (j - gys_) * gxm_ + (i - gxs_); }
  // Face gradient (B_d u)_f without the 1/h, at the face after the cell with ghosted index gf.
  PetscReal face_gradient(const PetscScalar *u, PetscInt gf, PetscInt d) const {
    PetscReal g = 0;
    for (PetscInt m = 0; m < face_.width; ++m) g += face_.grad[m] * PetscRealPart(u[gf + (face_.offset + m) * stride_[d]]);
    return g;
  }
  PetscReal face_value(const PetscScalar *D, PetscInt gf, PetscInt d) const {
    PetscReal v = 0;
    for (PetscInt m = 0; m < face_.width; ++m) v += face_.interp[m] * PetscRealPart(D[gf + (face_.offset + m) * stride_[d]]);
    return v;
  }
  // y_k += -sum_d B_d^T diag(I_d c) B_d w at every owned point k (ghosted arrays c, w): the
  // variable-coefficient diffusion face by face, used with (c, w) = (D, x) for dG/dU^T and
  // (dD, u) for the field-D column of dG/dp.
  void add_face_diffusion(const PetscScalar *c, const PetscScalar *w, PetscScalar *y) const {
    face_sweeps(face_.interp.data(), face_.grad.data(), face_.grad.data(), c, w, false, y);
  }
  // Each face once per direction (faces_2d; a 1D grid is its one row): F = (sum_m pa[m] a)
  // (sum_m pb[m] b) at every face the owned points touch, then out (+)= -sum_q w[q] F / h_d^2, added
  // unless `assign` (the first direction then writes out). a, b ghosted (the face stencil's offset
  // cancels: see face_products).
  template <class Y>
  void face_sweeps(const PetscReal *pa, const PetscReal *pb, const PetscReal *w, const PetscScalar *a, const PetscScalar *b,
                   bool assign, Y *out) const {
    const Grid &g = *grid_;
    const PetscInt g0 = ghost_index(g.xs(), g.ys()), xm = g.xm(), ym = g.ym(), sy = stride_[1];
    for (PetscInt d = 0; d < dim_; ++d) {
      const PetscReal sd = 1.0 / (h_[d] * h_[d]);
      const bool add = !(assign && d == 0);
      if (face_.width == 2 && add) faces_2d<2, true>(d, xm, ym, sy, pa, pb, w, a + g0, b + g0, sd, faces_.data(), out);
      else if (face_.width == 2) faces_2d<2, false>(d, xm, ym, sy, pa, pb, w, a + g0, b + g0, sd, faces_.data(), out);
      else if (add) faces_2d<4, true>(d, xm, ym, sy, pa, pb, w, a + g0, b + g0, sd, faces_.data(), out);
      else faces_2d<4, false>(d, xm, ym, sy, pa, pb, w, a + g0, b + g0, sd, faces_.data(), out);
    }
  }

  // (D_d u) at ghosted index g, with the 1/h.
  PetscReal first_derivative(const PetscScalar *u, PetscInt g, PetscInt d) const {
    PetscReal s = 0;
    for (PetscInt k = -2; k <= 2; ++k) // zero weights may lie beyond the ghosts: skip them
      if (w1_[d][k + 2] != 0) s += w1_[d][k + 2] * PetscRealPart(u[g + k * stride_[d]]);
    return s / h_[d];
  }

  // Stencil taps per direction, offsets -3..3 at [k + 3], for the constant-coefficient sweeps
  // (finite differences): the velocity columns read w1_ (scaled by -1/h afterwards, as
  // first_derivative does), a scalar D's column -B^T B u / h^2, and A^T. With a field D, A^T's taps
  // hold its advection part only; the (symmetric) diffusion goes face by face.
  void set_taps() {
    for (PetscInt d = 0; d < 2; ++d) {
      for (PetscInt e = 0; e < 2; ++e) vel_taps_[d][e].fill(0.0), vel_taps_t_[d][e].fill(0.0);
      lap_taps_[d].fill(0.0);
      at_taps_[d].fill(0.0);
    }
    for (PetscInt d = 0; d < dim_; ++d) {
      for (PetscInt k = -2; k <= 2; ++k) {
        vel_taps_[d][d][k + 3] = w1_[d][k + 2];
        vel_taps_t_[d][d][-k + 3] = w1_[d][k + 2]; // D_d^T (times h)
        at_taps_[d][-k + 3] += -vel_[d] * w1_[d][k + 2] / h_[d]; // A_d[k] lands at offset -k of A^T
      }
      if (!diffusion_) continue;
      const PetscReal ih2 = 1.0 / (h_[d] * h_[d]);
      PetscReal Df = 0; // a scalar D at the faces, as face_value computes it
      for (PetscInt m = 0; m < face_.width; ++m) Df += face_.interp[m] * D_scalar_;
      for (PetscInt m = 0; m < face_.width; ++m)
        for (PetscInt q = 0; q < face_.width; ++q) {
          const PetscReal bb = face_.grad[m] * face_.grad[q];
          if (D_field_) continue;
          lap_taps_[d][q - m + 3] -= bb * ih2;
          at_taps_[d][m - q + 3] -= bb * Df * ih2; // symmetric: the same taps reflected
        }
    }
  }

  // Fills the owned points and the star ghosts (radius_ along each axis; no corners: every sweep
  // here is a star) of the ghosted local array L from the global X. Replaces DMGlobalToLocal, whose
  // scatter costs more than the sweeps themselves on small grids.
  PetscErrorCode fill_ghosted(Vec X, Vec L) {
    PetscFunctionBeginUser;
    if (!wrap_) PetscCall(halo_.begin(X));
    PetscCall(fill_interior(X, L));
    if (!wrap_) PetscCall(fill_halo(halo_, X, L));
    PetscFunctionReturn(0);
  }
  // Both at once: on several ranks the two halo exchanges are in flight together (one latency).
  PetscErrorCode fill_ghosted_pair(Vec X, Vec L, Vec X2, Vec L2) {
    PetscFunctionBeginUser;
    if (!wrap_) {
      PetscCall(halo_.begin(X));
      PetscCall(halo2_.begin(X2));
    }
    PetscCall(fill_interior(X, L));
    PetscCall(fill_interior(X2, L2));
    if (!wrap_) {
      PetscCall(fill_halo(halo_, X, L));
      PetscCall(fill_halo(halo2_, X2, L2));
    }
    PetscFunctionReturn(0);
  }
  // The owned rows of L from X, and, on one rank holding everything (wrap_), the periodic ghosts.
  PetscErrorCode fill_interior(Vec X, Vec L) {
    const PetscInt xm = grid_->xm(), ym = grid_->ym();
    PetscScalar *l;
    PetscFunctionBeginUser;
    PetscCall(VecGetArray(L, &l));
    {
      ConstArray x(X);
      PetscCall(x.error());
      for (PetscInt jl = 0; jl < ym; ++jl) std::copy(x.data() + jl * xm, x.data() + (jl + 1) * xm, row(l, jl));
    }
    wrap_ghosts(l);
    PetscCall(VecRestoreArray(L, &l));
    PetscFunctionReturn(0);
  }
  // Which owned points of a ghosted copy to form: all of them, the strips that neighbours read (within
  // radius_ of the block's edges: formed first, so that their exchange overlaps the rest), or the rest.
  enum class Part { All, Strips, Rest };
  // The same with X an RK adjoint stage's combination (m <= 3), formed row by row straight into L (and
  // copied into W, unless null, for a Halo's exchange): no separate pass forming it.
  PetscErrorCode fill_interior(const StageCombination &x, Vec L, Part part, Vec W = nullptr) {
    const PetscInt xm = grid_->xm(), ym = grid_->ym(), r = radius_, ry = dim_ == 2 ? radius_ : 0;
    const PetscScalar *a0, *a[3];
    PetscScalar *l, *w = nullptr;
    PetscFunctionBeginUser;
    PetscCheck(x.m <= 3, PETSC_COMM_SELF, PETSC_ERR_PLIB, "fill_interior: %" PetscInt_FMT " terms", x.m);
    PetscCall(VecGetArray(L, &l));
    PetscCall(VecGetArrayRead(x.x0, &a0));
    for (PetscInt j = 0; j < x.m; ++j) PetscCall(VecGetArrayRead(x.X[j], &a[j]));
    if (W) PetscCall(VecGetArrayWrite(W, &w));
    for (PetscInt jl = 0; jl < ym; ++jl) {
      PetscScalar *rw = row(l, jl);
      auto form = [&](PetscInt i0, PetscInt i1) { // points [i0, i1) of row jl
        if (i1 <= i0) return;
        const PetscScalar *aj[3];
        for (PetscInt j = 0; j < x.m; ++j) aj[j] = a[j] + jl * xm + i0;
        StageCombination::form_local(i1 - i0, x.c0, a0 + jl * xm + i0, x.m, x.c, aj, rw + i0);
        if (w) std::copy(rw + i0, rw + i1, w + jl * xm + i0);
      };
      const bool edge_row = jl < ry || jl >= ym - ry;
      if (part == Part::All || (part == Part::Strips && edge_row)) form(0, xm);
      else if (part == Part::Strips) {
        form(0, std::min(r, xm));
        form(std::max(r, xm - r), xm);
      } else if (!edge_row) form(std::min(r, xm), std::max(r, xm - r));
    }
    if (W) PetscCall(VecRestoreArrayWrite(W, &w));
    for (PetscInt j = 0; j < x.m; ++j) PetscCall(VecRestoreArrayRead(x.X[j], &a[j]));
    PetscCall(VecRestoreArrayRead(x.x0, &a0));
    if (part == Part::All) wrap_ghosts(l);
    PetscCall(VecRestoreArray(L, &l));
    PetscFunctionReturn(0);
  }
  // On one rank holding everything (wrap_), the periodic ghosts of the ghosted array l from its owned rows.
  void wrap_ghosts(PetscScalar *l) const {
    const PetscInt xm = grid_->xm(), ym = grid_->ym(), r = radius_, sy = stride_[1];
    if (wrap_) {
      for (PetscInt jl = 0; jl < ym; ++jl) {
        PetscScalar *rw = row(l, jl);
        for (PetscInt k = 1; k <= r; ++k) {
          rw[-k] = rw[xm - k];
          rw[xm - 1 + k] = rw[k - 1];
        }
      }
      if (dim_ == 2)
        for (PetscInt k = 1; k <= r; ++k) {
          std::copy(row(l, ym - k), row(l, ym - k) + xm, row(l, 0) - k * sy);
          std::copy(row(l, k - 1), row(l, k - 1) + xm, row(l, ym - 1) + k * sy);
        }
    }
  }
  // The ghosts of L from a Halo whose exchange of X was begun.
  PetscErrorCode fill_halo(Halo &h, Vec X, Vec L) {
    PetscScalar *l;
    PetscFunctionBeginUser;
    PetscCall(h.end(X));
    PetscCall(VecGetArray(L, &l));
    copy_ghosts(h, 0, l);
    PetscCall(VecRestoreArray(L, &l));
    PetscFunctionReturn(0);
  }
  // The ghosts of the ghosted array l from field f of a Halo whose exchange has finished.
  void copy_ghosts(const Halo &h, PetscInt f, PetscScalar *l) const {
    const PetscInt xm = grid_->xm(), ym = grid_->ym(), r = radius_, sy = stride_[1];
    for (PetscInt jl = 0; jl < ym; ++jl) {
      PetscScalar *rw = row(l, jl);
      for (PetscInt k = 1; k <= r; ++k) {
        rw[-k] = h(-k, jl, f);
        rw[xm - 1 + k] = h(xm - 1 + k, jl, f);
      }
    }
    if (dim_ == 2)
      for (PetscInt k = 1; k <= r; ++k)
        for (PetscInt il = 0; il < xm; ++il) {
          row(l, 0)[il - k * sy] = h(il, -k, f);
          row(l, ym - 1)[il + k * sy] = h(il, ym - 1 + k, f);
        }
  }
  // On several ranks, an RK adjoint stage's ghosted x from its combination and (with U) u's ghosted
  // copy, their ghosts in one exchange (packed_: one message per neighbour for both) that overlaps
  // forming the points no neighbour reads.
  PetscErrorCode fill_ghosted_packed(const StageCombination &x, Vec U) {
    const PetscScalar *xl, *u = nullptr;
    Halo::Strided f[2];
    PetscFunctionBeginUser;
    PetscCall(fill_interior(x, X_local_, Part::Strips));
    PetscCall(VecGetArrayRead(X_local_, &xl));
    f[0] = {row(xl, 0), 1, stride_[1]};
    if (U) {
      PetscCall(VecGetArrayRead(U, &u));
      f[1] = {u, 1, grid_->xm()};
    }
    PetscCall(packed_.begin(f));
    if (U) PetscCall(VecRestoreArrayRead(U, &u));
    PetscCall(VecRestoreArrayRead(X_local_, &xl));
    PetscCall(fill_interior(x, X_local_, Part::Rest));
    if (U) PetscCall(fill_interior(U, U_local_));
    PetscCall(packed_.end());
    for (PetscInt k = 0; k < (U ? 2 : 1); ++k) {
      PetscScalar *l;
      const Vec L = k == 0 ? X_local_ : U_local_;
      PetscCall(VecGetArray(L, &l));
      copy_ghosts(packed_, k, l);
      PetscCall(VecRestoreArray(L, &l));
    }
    PetscFunctionReturn(0);
  }
  // Owned row jl (j = ys + jl) of a ghosted local array.
  PetscScalar *row(PetscScalar *l, PetscInt jl) const { return l + ghost_index(grid_->xs(), grid_->ys() + jl); }
  const PetscScalar *row(const PetscScalar *l, PetscInt jl) const {
    return l + ghost_index(grid_->xs(), grid_->ys() + jl);
  }

  // out[il] = sum_d sum_{|k| <= R} t[d][k + 3] l[g + k stride_d] at every owned point (il the owned
  // index, g the ghosted one), summed in the order of first_derivative (x taps, then y, each from
  // -R up). The taps are copied to locals and the pointers are restrict so that the row loop needs
  // no reloads.
  // sum_i c_i x_i with four partial sums (latency, not bandwidth, bounds a single chain).
  static PetscReal dot4(const PetscReal *__restrict c, const PetscScalar *__restrict x, PetscInt n) {
    PetscReal s0 = 0, s1 = 0, s2 = 0, s3 = 0;
    PetscInt i = 0;
    for (; i + 3 < n; i += 4) {
      s0 += c[i] * PetscRealPart(x[i]);
      s1 += c[i + 1] * PetscRealPart(x[i + 1]);
      s2 += c[i + 2] * PetscRealPart(x[i + 2]);
      s3 += c[i + 3] * PetscRealPart(x[i + 3]);
    }
    for (; i < n; ++i) s0 += c[i] * PetscRealPart(x[i]);
    return (s0 + s1) + (s2 + s3);
  }

  // One row of sweep_rows (l, out at the row's first owned point).
  template <int R, int DIM>
  __attribute__((optimize("tree-vectorize", "vect-cost-model=dynamic"))) // across points; each sum keeps its order
  static void sweep_row(const PetscScalar *__restrict l, const std::array<PetscReal, 7> *t, PetscReal *__restrict out,
                        PetscInt xm, PetscInt sy) {
    PetscReal tx[2 * R + 1], ty[2 * R + 1];
    for (int k = -R; k <= R; ++k) {
      tx[k + R] = t[0][k + 3];
      ty[k + R] = DIM == 2 ? t[1][k + 3] : 0.0;
    }
    for (PetscInt i = 0; i < xm; ++i) {
      PetscReal s = 0;
#pragma GCC unroll 8
      for (int k = -R; k <= R; ++k) s += tx[k + R] * PetscRealPart(l[i + k]);
      if (DIM == 2) {
#pragma GCC unroll 8
        for (int k = -R; k <= R; ++k) s += ty[k + R] * PetscRealPart(l[i + k * sy]);
      }
      out[i] = s;
    }
  }
  template <int R, int DIM>
  static void sweep_rows(const PetscScalar *l, const std::array<PetscReal, 7> *t, PetscReal *out, PetscInt xm, PetscInt ym,
                         PetscInt sy) {
    for (PetscInt jl = 0; jl < ym; ++jl, l += sy, out += xm) sweep_row<R, DIM>(l, t, out, xm, sy);
  }
  // An RK adjoint stage's sweep with the scalars' sums (finite differences, no field D in the taps), one
  // row (l, u, out at its first owned point): z_d = D_d^T x (times h_d), z_L = L x (LAP),
  // y = sum_d c[d] z_d + c[2] z_L, and sums[m] += <z_m, u>, from one read of x; the row's z stays in L1
  // for its dot products (z: 3 rows of xm).
  template <int R, int DIM, bool LAP>
  __attribute__((optimize("tree-vectorize", "vect-cost-model=dynamic")))
  static void sweep_sums_row(const PetscScalar *__restrict l, const PetscReal *vxt, const PetscReal *vyt, const PetscReal *lxt,
                             const PetscReal *lyt, const PetscReal *c, const PetscScalar *__restrict u, PetscScalar *__restrict out,
                             PetscInt xm, PetscInt sy, PetscReal *__restrict z, PetscReal *sums) {
    PetscReal vx[2 * R + 1], vy[2 * R + 1], lx[2 * R + 1], ly[2 * R + 1];
    for (int k = -R; k <= R; ++k) {
      vx[k + R] = vxt[k + 3];
      vy[k + R] = DIM == 2 ? vyt[k + 3] : 0.0;
      lx[k + R] = LAP ? lxt[k + 3] : 0.0;
      ly[k + R] = LAP && DIM == 2 ? lyt[k + 3] : 0.0;
    }
    const PetscReal c0 = c[0], c1 = c[1], cl = c[2];
    PetscReal *__restrict z0 = z, *__restrict z1 = z + xm, *__restrict z2 = z + 2 * xm;
    for (PetscInt i = 0; i < xm; ++i) {
      PetscReal sx = 0, syv = 0, sl = 0;
#pragma GCC unroll 8
      for (int k = -R; k <= R; ++k) sx += vx[k + R] * PetscRealPart(l[i + k]);
      if (DIM == 2) {
#pragma GCC unroll 8
        for (int k = -R; k <= R; ++k) syv += vy[k + R] * PetscRealPart(l[i + k * sy]);
      }
      if (LAP) {
#pragma GCC unroll 8
        for (int k = -R; k <= R; ++k) sl += lx[k + R] * PetscRealPart(l[i + k]);
        if (DIM == 2) {
#pragma GCC unroll 8
          for (int k = -R; k <= R; ++k) sl += ly[k + R] * PetscRealPart(l[i + k * sy]);
        }
      }
      out[i] = c0 * sx + c1 * syv + cl * sl;
      z0[i] = sx;
      if (DIM == 2) z1[i] = syv;
      if (LAP) z2[i] = sl;
    }
    sums[0] += dot4(z0, u, xm);
    if (DIM == 2) sums[1] += dot4(z1, u, xm);
    if (LAP) sums[2] += dot4(z2, u, xm);
  }
  template <int R, int DIM, bool LAP>
  static void sweep_sums_rows(const PetscScalar *l, const PetscReal *vxt, const PetscReal *vyt, const PetscReal *lxt,
                              const PetscReal *lyt, const PetscReal *c, const PetscScalar *u, PetscScalar *out, PetscInt xm,
                              PetscInt ym, PetscInt sy, PetscReal *z, PetscReal *sums) {
    for (PetscInt jl = 0; jl < ym; ++jl, l += sy, out += xm, u += xm)
      sweep_sums_row<R, DIM, LAP>(l, vxt, vyt, lxt, lyt, c, u, out, xm, sy, z, sums);
  }
  // sweep_sums_row's coefficients and taps for this model: c = (-v_d / h_d, a scalar D's), the
  // Laplacian's part only with a scalar D (lap).
  struct SweepSumsTaps {
    bool lap;
    PetscReal c[3];
    const PetscReal *vx, *vy, *lx, *ly;
  };
  SweepSumsTaps sweep_sums_taps() const {
    const bool lap = diffusion_ && !D_field_;
    return {lap,
            {-vel_[0] / h_[0], dim_ == 2 ? -vel_[1] / h_[1] : 0.0, lap ? D_scalar_ : 0.0},
            vel_taps_t_[0][0].data(),
            vel_taps_t_[1][1].data(),
            lap_taps_[0].data(),
            lap_taps_[1].data()};
  }
  // y = A^T x without a field D's faces, and sums[d] = <D_d^T x, u> (times h_d), sums[2] = <L x, u>.
  void sweep_sums(const PetscScalar *l, const PetscScalar *u, PetscScalar *out, PetscReal *sums) {
    const PetscInt xm = grid_->xm(), ym = grid_->ym(), sy = stride_[1];
    const SweepSumsTaps t = sweep_sums_taps();
    const PetscScalar *l0 = row(l, 0);
    PetscReal *z = stage_scratch_.data();
    sums[0] = sums[1] = sums[2] = 0;
#define FLEXIPDE_SWEEP_SUMS(R, DIM)                                                                                    \
  (t.lap ? sweep_sums_rows<R, DIM, true>(l0, t.vx, t.vy, t.lx, t.ly, t.c, u, out, xm, ym, sy, z, sums)                 \
         : sweep_sums_rows<R, DIM, false>(l0, t.vx, t.vy, t.lx, t.ly, t.c, u, out, xm, ym, sy, z, sums))
    switch (10 * (int)dim_ + (int)radius_) {
    case 11: FLEXIPDE_SWEEP_SUMS(1, 1); break;
    case 12: FLEXIPDE_SWEEP_SUMS(2, 1); break;
    case 13: FLEXIPDE_SWEEP_SUMS(3, 1); break;
    case 21: FLEXIPDE_SWEEP_SUMS(1, 2); break;
    case 22: FLEXIPDE_SWEEP_SUMS(2, 2); break;
    default: FLEXIPDE_SWEEP_SUMS(3, 2); break;
    }
#undef FLEXIPDE_SWEEP_SUMS
  }
  void sweep(const PetscScalar *l, const std::array<PetscReal, 7> *t, PetscReal *out) const {
    const PetscInt xm = grid_->xm(), ym = grid_->ym(), sy = stride_[1];
    const PetscScalar *l0 = row(l, 0);
    switch (10 * (int)dim_ + (int)radius_) {
    case 11: sweep_rows<1, 1>(l0, t, out, xm, ym, sy); break;
    case 12: sweep_rows<2, 1>(l0, t, out, xm, ym, sy); break;
    case 13: sweep_rows<3, 1>(l0, t, out, xm, ym, sy); break;
    case 21: sweep_rows<1, 2>(l0, t, out, xm, ym, sy); break;
    case 22: sweep_rows<2, 2>(l0, t, out, xm, ym, sy); break;
    default: sweep_rows<3, 2>(l0, t, out, xm, ym, sy); break;
    }
  }

  // The matrix-free dG/dU (finite differences).
  static PetscErrorCode jmf_mult(Mat J, Vec x, Vec y) {
    AdvectionModel *m;
    PetscFunctionBeginUser;
    PetscCall(MatShellGetContext(J, &m));
    PetscCall(MatMult(m->A_, x, y));
    PetscFunctionReturn(0);
  }
  // y = A^T x, and with the recorded stage u (rhs_jacobian_p) also this
  // rank's share of (dG/dp)^T x from the same ghosted x: (dG/dv_d)^T x = -<u, D_d^T x> / h_d and a
  // scalar D's <u, B^T B x>-column, (-B^T B symmetric), kept in fused_ for jp_mult_transpose. 1D
  // without diffusion: A^T = -(a / h) D^T, so one sweep gives D^T x for both.
  static PetscErrorCode jmf_mult_transpose(Mat J, Vec x, Vec y) {
    AdvectionModel *m;
    const PetscScalar *xl, *D = nullptr;
    bool fuse = false;
    PetscFunctionBeginUser;
    PetscCall(MatShellGetContext(J, &m));
    if (m->lazy_) PetscCall(m->stage_.unchanged(&fuse));
    PetscCall(m->fill_ghosted(x, m->X_local_));
    PetscCall(VecGetArrayRead(m->X_local_, &xl));
    const bool field = m->diffusion_ && m->D_field_;
    if (field) PetscCall(VecGetArrayRead(m->D_local_, &D));
    {
      Array Y(y);
      PetscCall(Y.error());
      PetscScalar *ya = Y.data();
      const PetscInt n = m->grid_->local_points(), nd = m->dim_;
      const PetscScalar *u = nullptr;
      Vec U = nullptr;
      if (fuse) {
        PetscCall(m->stage_.get(&U));
        PetscCall(VecGetArrayRead(U, &u));
      }
      if (nd == 1 && !m->diffusion_) {
        m->sweep(xl, m->vel_taps_t_[0], ya); // D^T x (times h)
        if (fuse) m->fused_.local[0] = m->dGdv_scale_[0] * dot4(ya, u, n);
        const PetscReal s = m->vel_[0] * m->dGdv_scale_[0];
        for (PetscInt il = 0; il < n; ++il) ya[il] *= s;
      } else {
        m->sweep(xl, m->at_taps_, ya);
        if (field) m->add_face_diffusion(D, xl, ya); // symmetric: the forward's faces
        if (fuse) {
          PetscReal *z = m->scratch_.data();
          for (PetscInt d = 0; d < nd; ++d) {
            m->sweep(xl, m->vel_taps_t_[d], z);
            m->fused_.local[d] = m->dGdv_scale_[d] * dot4(z, u, n);
          }
          if (m->diffusion_) { // a scalar D (a field D is never lazy)
            m->sweep(xl, m->lap_taps_, z);
            m->fused_.local[nd] = dot4(z, u, n);
          }
        }
      }
      if (fuse) PetscCall(VecRestoreArrayRead(U, &u));
    }
    if (field) PetscCall(VecRestoreArrayRead(m->D_local_, &D));
    PetscCall(VecRestoreArrayRead(m->X_local_, &xl));
    if (fuse) PetscCall(m->fused_.store(x, m->stage_.serial()));
    PetscFunctionReturn(0);
  }

  // Largest face diffusivity (for the spectrum) and a check that none is negative: a negative
  // D_f makes the operator anti-diffusive, which only the 4-point interpolation can produce.
  PetscErrorCode face_diffusivity_range() {
    const PetscScalar *D;
    PetscReal mm[2] = {PETSC_MAX_REAL, 0}; // min, max
    PetscFunctionBeginUser;
    PetscCall(VecGetArrayRead(D_local_, &D));
    for (PetscInt j = grid_->ys(); j < grid_->ys() + grid_->ym(); ++j)
      for (PetscInt i = grid_->xs(); i < grid_->xs() + grid_->xm(); ++i)
        for (PetscInt d = 0; d < dim_; ++d) {
          const PetscReal v = face_value(D, ghost_index(i, j), d);
          mm[0] = std::min(mm[0], v);
          mm[1] = std::max(mm[1], v);
        }
    PetscCall(VecRestoreArrayRead(D_local_, &D));
    mm[0] = -mm[0];
    PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, mm, 2, MPIU_REAL, MPI_MAX, grid_->comm()));
    PetscCheck(-mm[0] >= 0, grid_->comm(), PETSC_ERR_ARG_OUTOFRANGE,
               "-fd_order 4 interpolates D to the cell faces with weights (-1, 9, 9, -1)/16, which gives a negative "
               "face diffusivity %g here: smooth the field D or use -fd_order 2",
               (double)-mm[0]);
    Dmax_ = mm[1];
    PetscFunctionReturn(0);
  }

  // Spectral field D: its 2/3-rule truncation P D multiplies the de-aliased gradient.
  PetscErrorCode spectral_diffusivity() {
    PetscReal lo;
    PetscFunctionBeginUser;
    if (!D_field_) {
      Dmax_ = D_scalar_;
      PetscFunctionReturn(0);
    }
    PetscCall(spectral_.dealias(D_, D_));
    PetscCall(VecMin(D_, nullptr, &lo));
    PetscCall(VecMax(D_, nullptr, &Dmax_));
    PetscCheck(lo >= 0, grid_->comm(), PETSC_ERR_ARG_OUTOFRANGE,
               "The 2/3-rule truncation of the field D (spectral diffusion) is negative somewhere (%g): smooth D or "
               "raise it away from 0",
               (double)lo);
    PetscFunctionReturn(0);
  }

  PetscErrorCode assemble(Mat A) override {
    PetscFunctionBeginUser;
    if (scheme_ == SPECTRAL) { // the shell reads the model's parameters; assembly resets TS's shift
      PetscCall(MatAssemblyBegin(A, MAT_FINAL_ASSEMBLY));
      PetscCall(MatAssemblyEnd(A, MAT_FINAL_ASSEMBLY));
      PetscFunctionReturn(0);
    }
    const PetscInt r = grid_->stencil_width(), w = 2 * r + 1;
    const PetscScalar *D = nullptr;
    std::vector<MatStencil> cols(dim_ * w);
    std::vector<PetscScalar> vals(dim_ * w), row(dim_ * w);
    std::vector<char> used(dim_ * w);
    PetscCall(MatZeroEntries(A));
    if (diffusion_) PetscCall(VecGetArrayRead(D_local_, &D));
    for (PetscInt j = grid_->ys(); j < grid_->ys() + grid_->ym(); ++j)
      for (PetscInt i = grid_->xs(); i < grid_->xs() + grid_->xm(); ++i) {
        // Row (i, j) by direction d and offset k in -r..r: entry d * w + k + r; the centre is kept in
        // direction 0 (distinct columns: the grid has at least 2r + 3 points per direction). The
        // diagonal is always stored so that an implicit TS's shift finds it.
        std::fill(row.begin(), row.end(), 0.0);
        std::fill(used.begin(), used.end(), 0);
        auto add = [&](PetscInt d, PetscInt k, PetscReal v) {
          const PetscInt q = (k == 0 ? 0 : d * w) + k + r;
          row[q] += v;
          used[q] = 1;
        };
        used[r] = 1;
        const PetscInt g = ghost_index(i, j);
        for (PetscInt d = 0; d < dim_; ++d) {
          for (PetscInt k = -2; k <= 2; ++k)
            if (w1_[d][k + 2] != 0) add(d, k, -vel_[d] * w1_[d][k + 2] / h_[d]);
          if (!diffusion_) continue;
          const PetscReal ih2 = 1.0 / (h_[d] * h_[d]);
          for (PetscInt m = 0; m < face_.width; ++m) { // -B^T diag(D_f) B: faces f whose gradient reads u_(i,j)
            const PetscInt gf = g - (face_.offset + m) * stride_[d];
            const PetscReal c = -face_.grad[m] * face_value(D, gf, d) * ih2;
            for (PetscInt q = 0; q < face_.width; ++q) add(d, q - m, c * face_.grad[q]);
          }
        }
        MatStencil rowst = {0, j, i, 0};
        PetscInt cnt = 0;
        for (PetscInt d = 0; d < dim_; ++d)
          for (PetscInt k = -r; k <= r; ++k) {
            const PetscInt q = d * w + k + r;
            if (!used[q]) continue;
            cols[cnt] = d == 0 ? MatStencil{0, j, i + k, 0} : MatStencil{0, j + k, i, 0};
            vals[cnt] = row[q];
            ++cnt;
          }
        PetscCall(MatSetValuesStencil(A, 1, &rowst, cnt, cols.data(), vals.data(), INSERT_VALUES));
      }
    if (diffusion_) PetscCall(VecRestoreArrayRead(D_local_, &D));
    PetscCall(MatAssemblyBegin(A, MAT_FINAL_ASSEMBLY));
    PetscCall(MatAssemblyEnd(A, MAT_FINAL_ASSEMBLY));
    PetscFunctionReturn(0);
  }

  // The constant-coefficient part of the spectral operator as one Fourier symbol, and the symbols of
  // the stage adjoint's derivatives (i kappa_d, then -|kappa|^2 with diffusion), made at set-up and
  // whenever the parameters change (set_parameters).
  void make_spectral_symbols() {
    const PetscReal a = vel_[0], b = dim_ == 2 ? vel_[1] : 0.0, D = diffusion_ && !D_field_ ? D_scalar_ : 0.0;
    symbol_ = spectral_.symbol([=](const FourierMode &k) { return cplx(-D * (k.wx * k.wx + k.wy * k.wy), -(a * k.wx + b * k.wy)); });
    symbol_t_ = symbol_;
    for (auto &v : symbol_t_) v = std::conj(v);
    if (!parts_.empty()) return;
    for (PetscInt d = 0; d < dim_; ++d)
      parts_.push_back(spectral_.symbol([d](const FourierMode &k) { return SpectralDifferentiator::derivative_symbol(k, d, 1); }));
    if (diffusion_ && !D_field_) parts_.push_back(spectral_.symbol([](const FourierMode &k) { return cplx(-(k.wx * k.wx + k.wy * k.wy)); }));
    if (parts_.size() == 2) packed_parts_ = spectral_.pack(parts_[0], parts_[1]); // the stage adjoint's pair
    if (diffusion_ && D_field_) {
      for (PetscInt d = 0; d < dim_; ++d)
        dealiased_[d] = spectral_.symbol([d](const FourierMode &k) {
          return k.kept ? SpectralDifferentiator::derivative_symbol(k, d, 1) : cplx(0);
        });
      if (dim_ == 2) { // E_x - i E_y: the divergence of a flux packed as f_x + i f_y (diffusion_sum)
        flux_div_ = dealiased_[0];
        for (size_t p = 0; p < flux_div_.size(); ++p) flux_div_[p] -= cplx(0, 1) * dealiased_[1][p];
      }
    }
  }

  // y = A x (or A^T x) for the spectral scheme. A field D adds sum_d E_d diag(P D) E_d x, E_d = P d/dx_d
  // (skew: the transpose has -E_d on both sides, the same product): x^ once, E_d x from one backward
  // transform (both directions in one in 2D), and (D E_d x)^ (both directions in one transform in 2D)
  // summed with the constant part's s x^ in the spectrum before the last backward transform: 4
  // transforms in 1D and 2D.
  PetscErrorCode spectral_apply(Vec x, Vec y, bool transpose) {
    PetscFunctionBeginUser;
    const SpectralDifferentiator::Symbol &s = transpose ? symbol_t_ : symbol_;
    if (!(diffusion_ && D_field_)) {
      PetscCall(spectral_.apply(s, x, y));
      PetscFunctionReturn(0);
    }
    Vec ex[2] = {t1_, t2_};
    PetscCall(spectral_.transform(x, xhat_));
    if (dim_ == 2) PetscCall(spectral_.backward_pair(dealiased_[0], xhat_, ex[0], dealiased_[1], xhat_, ex[1]));
    else PetscCall(spectral_.backward({{&dealiased_[0], &xhat_}}, ex[0]));
    PetscCall(diffusion_sum(s, xhat_, ex, y));
    PetscFunctionReturn(0);
  }
  // y = S x + sum_d E_d (D .* ex_d) (ex_d overwritten), with xhat the spectrum of x or of x + i alpha u
  // (the backward transform's real part is all that is kept). In 2D the fluxes go forward together as
  // f = f_x + i f_y, and Re F^-1 (E_x - i E_y) f^ = E_x f_x + E_y f_y (both E_d f_d real): one forward
  // transform for the two.
  PetscErrorCode diffusion_sum(const SpectralDifferentiator::Symbol &s, const SpectralDifferentiator::Spectrum &xhat, Vec *ex, Vec y) {
    PetscFunctionBeginUser;
    for (PetscInt d = 0; d < dim_; ++d) PetscCall(VecPointwiseMult(ex[d], ex[d], D_));
    PetscCall(spectral_.transform_pair(ex[0], dim_ == 2 ? ex[1] : nullptr, 1.0, what_));
    PetscCall(spectral_.backward({{&s, &xhat}, {dim_ == 2 ? &flux_div_ : &dealiased_[0], &what_}}, y));
    PetscFunctionReturn(0);
  }
  static PetscErrorCode spectral_mult(Mat A, Vec x, Vec y) {
    AdvectionModel *m;
    PetscFunctionBeginUser;
    PetscCall(MatShellGetContext(A, &m));
    PetscCall(m->spectral_apply(x, y, false));
    PetscFunctionReturn(0);
  }
  // Spectral 1D without diffusion: A^T x = a D_x x (A = -a D_x, D_x skew), and (dG/da)^T x =
  // <-D_x u, x> = <u, D_x x>. So the transpose keeps D_x x, tagged with x's id and state, and the
  // dG/dp transpose that an RK adjoint stage applies next to the same x reuses it: one transform
  // pair per adjoint stage instead of two.
  static PetscErrorCode spectral_mult_transpose(Mat A, Vec x, Vec y) {
    AdvectionModel *m;
    PetscFunctionBeginUser;
    PetscCall(MatShellGetContext(A, &m));
    if (!m->shared_dx_) {
      PetscCall(m->spectral_apply(x, y, true));
      PetscFunctionReturn(0);
    }
    PetscCall(m->derivative_of(x));
    const PetscReal a = m->vel_[0];
    ConstArray w(m->dx_);
    Array Y(y);
    PetscCall(w.error());
    PetscCall(Y.error());
    for (PetscInt il = 0; il < m->grid_->local_points(); ++il) Y[il] = a * w[il];
    PetscFunctionReturn(0);
  }
  // dx_ = D_x x unless it already holds it.
  PetscErrorCode derivative_of(Vec x) {
    PetscObjectId id;
    PetscObjectState state;
    PetscFunctionBeginUser;
    PetscCall(PetscObjectGetId((PetscObject)x, &id));
    PetscCall(PetscObjectStateGet((PetscObject)x, &state));
    if (id == dx_id_ && state == dx_state_) PetscFunctionReturn(0);
    PetscCall(spectral_.derivative(0, 1, x, dx_));
    dx_id_ = id;
    dx_state_ = state;
    PetscFunctionReturn(0);
  }

  // The columns at the recorded stage, unless they are already formed (lazy schemes only).
  PetscErrorCode recorded_columns() {
    Vec U = nullptr;
    PetscFunctionBeginUser;
    if (!(lazy_ || shared_dx_) || columns_serial_ == stage_.serial()) PetscFunctionReturn(0);
    PetscCall(stage_.get(&U));
    if (lazy_) PetscCall(fd_columns(U));
    else PetscCall(spectral_columns(U));
    columns_serial_ = stage_.serial();
    PetscFunctionReturn(0);
  }

  PetscErrorCode fd_columns(Vec U) {
    const PetscScalar *u;
    PetscFunctionBeginUser;
    PetscCall(fill_ghosted(U, U_local_));
    PetscCall(VecGetArrayRead(U_local_, &u));
    for (PetscInt d = 0; d < dim_; ++d) {
      PetscReal *col = dGdv_[d].data();
      const PetscReal h = h_[d];
      sweep(u, vel_taps_[d], col); // (D_d u) h_d; the consumers scale by dGdv_scale_[d] = -1/h_d
      dGdv_scale_[d] = -1.0 / h;
    }
    if (diffusion_ && !D_field_) {
      sweep(u, lap_taps_, dGdD_.data());
    }
    PetscCall(VecRestoreArrayRead(U_local_, &u));
    PetscFunctionReturn(0);
  }

  // The columns D_d U (and L U for a scalar D, or E_d U for a field D) from one forward transform of U
  // and one backward transform per two of them.
  PetscErrorCode spectral_columns(Vec U) {
    std::vector<const SpectralDifferentiator::Symbol *> ss;
    std::vector<Vec> out;
    Vec work[2] = {t1_, t2_};
    PetscFunctionBeginUser;
    for (PetscInt d = 0; d < dim_; ++d) {
      ss.push_back(&parts_[d]);
      out.push_back(work[d]);
      dGdv_scale_[d] = -1.0;
    }
    if (diffusion_ && D_field_)
      for (PetscInt d = 0; d < dim_; ++d) {
        ss.push_back(&dealiased_[d]);
        out.push_back(w_[d]);
      }
    else if (diffusion_) {
      ss.push_back(&parts_[dim_]);
      out.push_back(t3_);
    }
    PetscCall(spectral_.apply_many(ss, U, out));
    for (PetscInt d = 0; d < dim_ + (diffusion_ && !D_field_ ? 1 : 0); ++d) {
      ConstArray a(out[d]);
      PetscCall(a.error());
      std::vector<PetscReal> &col = d < dim_ ? dGdv_[d] : dGdD_;
      for (PetscInt il = 0; il < grid_->local_points(); ++il) col[il] = PetscRealPart(a[il]);
    }
    PetscFunctionReturn(0);
  }

  // y = dG/dp x   (x in parameter space, y in state space)
  static PetscErrorCode jp_mult(Mat Jp, Vec x, Vec y) {
    AdvectionModel *m;
    PetscFunctionBeginUser;
    PetscCall(MatShellGetContext(Jp, &m));
    PetscCall(m->recorded_columns());
    const Grid &g = *m->grid_;
    PetscReal dv[2] = {0, 0}, dD = 0;
    for (PetscInt d = 0; d < m->dim_; ++d) PetscCall(m->params_->scalar(x, m->vel_index_[d], &dv[d]));
    const bool field = m->diffusion_ && m->D_field_;
    if (m->diffusion_ && !field) PetscCall(m->params_->scalar(x, m->D_index_, &dD));
    {
      Array Y(y);
      PetscCall(Y.error());
      for (PetscInt il = 0; il < g.local_points(); ++il) {
        PetscReal v = m->dGdD_[il] * dD;
        for (PetscInt d = 0; d < m->dim_; ++d) v += m->dGdv_[d][il] * m->dGdv_scale_[d] * dv[d];
        Y[il] = v;
      }
    }
    if (!field) PetscFunctionReturn(0);
    PetscCall(m->params_->get_field(x, m->D_index_, m->dD_));
    if (m->scheme_ == SPECTRAL) { // sum_d E_d ((P dD) .* E_d u)
      PetscCall(m->spectral_.dealias(m->dD_, m->t3_));
      for (PetscInt d = 0; d < m->dim_; ++d) {
        PetscCall(VecPointwiseMult(m->t1_, m->t3_, m->w_[d]));
        PetscCall(m->spectral_.derivative(d, 1, m->t1_, m->t2_, true));
        PetscCall(VecAXPY(y, 1.0, m->t2_));
      }
      PetscFunctionReturn(0);
    }
    // -sum_d B_d^T (B_d u .* I_d dD)
    const PetscScalar *u, *ddl;
    PetscCall(DMGlobalToLocal(g.dm(), m->dD_, INSERT_VALUES, m->dD_local_));
    PetscCall(VecGetArrayRead(m->dD_local_, &ddl));
    PetscCall(VecGetArrayRead(m->U_local_, &u));
    {
      Array Y(y);
      PetscCall(Y.error());
      m->add_face_diffusion(ddl, u, Y.data());
    }
    PetscCall(VecRestoreArrayRead(m->dD_local_, &ddl));
    PetscCall(VecRestoreArrayRead(m->U_local_, &u));
    PetscFunctionReturn(0);
  }

  // y = (dG/dp)^T x   (x in state space, y in parameter space). The scalars' dot products share one
  // reduction to rank 0 (which holds every scalar) and one write of y.
  static PetscErrorCode jp_mult_transpose(Mat Jp, Vec x, Vec y) {
    AdvectionModel *m;
    PetscFunctionBeginUser;
    PetscCall(MatShellGetContext(Jp, &m));
    const Grid &g = *m->grid_;
    const PetscInt n = g.local_points(), nd = m->dim_;
    const bool field = m->diffusion_ && m->D_field_, scalar_D = m->diffusion_ && !field;
    PetscReal local[3] = {0, 0, 0}, total[3] = {0, 0, 0};
    bool hit = false;
    if (m->lazy_) PetscCall(m->fused_.matches(x, m->stage_.serial(), &hit));
    if (hit) std::copy(m->fused_.local, m->fused_.local + 3, local); // from the sweep of J^T x
    else if (m->shared_dx_) { // <u, D_x x>, D_x x usually left by the transpose of J just before
      Vec U = nullptr;
      PetscCall(m->stage_.get(&U));
      PetscCall(m->derivative_of(x));
      ConstArray u(U), w(m->dx_);
      PetscCall(u.error());
      PetscCall(w.error());
      local[0] = dot4(u.data(), w.data(), n);
    } else {
      PetscCall(m->recorded_columns());
      ConstArray X(x);
      PetscCall(X.error());
      const PetscScalar *xa = X.data();
      for (PetscInt d = 0; d < nd; ++d) local[d] = m->dGdv_scale_[d] * dot4(m->dGdv_[d].data(), xa, n);
      if (scalar_D) local[nd] = dot4(m->dGdD_.data(), xa, n);
    }
    const PetscInt nsum = nd + (scalar_D ? 1 : 0);
    PetscCallMPI(MPI_Reduce(local, total, (PetscMPIInt)nsum, MPIU_REAL, MPI_SUM, 0, g.comm()));
    {
      Array Y(y);
      PetscCall(Y.error());
      PetscInt ny;
      PetscCall(VecGetLocalSize(y, &ny));
      std::fill(Y.data(), Y.data() + ny, 0.0); // data(): ny may be 0 (no scalar on this rank)
      for (PetscInt q = 0; q < nsum; ++q) {
        const ParamInfo &pi = m->params_->info(q < nd ? m->vel_index_[q] : m->D_index_);
        if (pi.local_size) Y[pi.local_offset] = total[q];
      }
    }
    if (!field) PetscFunctionReturn(0);
    std::vector<PetscReal> &gD = m->gD_;
    std::fill(gD.begin(), gD.end(), 0.0);
    if (m->scheme_ == SPECTRAL) { // sum_d P (E_d u .* E_d^T x) = -P sum_d E_d u .* E_d x
      Vec ex[2] = {m->t1_, m->t2_};
      PetscCall(m->spectral_.apply_many(m->dim_ == 2 ? std::vector<const SpectralDifferentiator::Symbol *>{&m->dealiased_[0], &m->dealiased_[1]}
                                                     : std::vector<const SpectralDifferentiator::Symbol *>{&m->dealiased_[0]},
                                        x, std::vector<Vec>(ex, ex + m->dim_)));
      PetscCall(VecPointwiseMult(m->t3_, ex[0], m->w_[0]));
      if (m->dim_ == 2) {
        PetscCall(VecPointwiseMult(ex[1], ex[1], m->w_[1]));
        PetscCall(VecAXPY(m->t3_, 1.0, ex[1]));
      }
      PetscCall(VecScale(m->t3_, -1.0));
      if (!m->defer_truncation_) PetscCall(m->spectral_.dealias(m->t3_, m->t3_)); // else end_adjoint
      ConstArray a(m->t3_);
      PetscCall(a.error());
      for (PetscInt il = 0; il < g.local_points(); ++il) gD[il] = PetscRealPart(a[il]);
    } else { // finite differences: from the ghosted stage u (fd_columns) and x
      const PetscScalar *u, *xl;
      PetscCall(m->fill_ghosted(x, m->X_local_));
      PetscCall(VecGetArrayRead(m->U_local_, &u));
      PetscCall(VecGetArrayRead(m->X_local_, &xl));
      m->field_D_gradient(u, xl, gD.data());
      PetscCall(VecRestoreArrayRead(m->U_local_, &u));
      PetscCall(VecRestoreArrayRead(m->X_local_, &xl));
    }
    PetscCall(m->params_->add_pointwise(y, m->D_index_, gD));
    PetscFunctionReturn(0);
  }

  // g = (dG/dD)^T x for a field D (finite differences), from ghosted u and x: -sum_d I_d^T (B_d u .* B_d x)
  // / h_d^2 at every owned point, each face once.
  void field_D_gradient(const PetscScalar *u, const PetscScalar *xl, PetscReal *gD) const {
    face_sweeps(face_.grad.data(), face_.grad.data(), face_.interp.data(), u, xl, true, gD);
  }

  // y = sum_{j < M} c_j v_j, each sum from 0 in the order of j.
  template <int M>
  __attribute__((optimize("tree-vectorize", "vect-cost-model=dynamic")))
  static void combine_parts(PetscInt n, const PetscReal *c, const PetscScalar *const *v, PetscScalar *__restrict y) {
    PetscReal cc[M];
    const PetscScalar *__restrict w[M];
    for (int j = 0; j < M; ++j) cc[j] = c[j], w[j] = v[j];
    for (PetscInt il = 0; il < n; ++il) {
      PetscReal s = 0;
#pragma GCC unroll 3
      for (int j = 0; j < M; ++j) s += cc[j] * PetscRealPart(w[j][il]);
      y[il] = s;
    }
  }
  // The spectral stage (scalar coefficients): with D_d skew and the Laplacian L symmetric,
  // A^T x = sum_d a_d D_d x + D L x, and (dG/da_d)^T x = <-D_d u, x> = <u, D_d x>, (dG/dD)^T x = <u, L x>:
  // one forward transform of x and one backward transform per two derivatives (apply_pair, apply_many)
  // give the product and the parameters' sums together (the Jacobian path transforms u as well at every stage).
  PetscErrorCode spectral_stage_adjoint(PetscReal t, Vec U, Vec x, Vec y, Vec mu) {
    PetscReal local[3] = {0, 0, 0};
    const PetscInt n = grid_->local_points(), nd = dim_;
    PetscFunctionBeginUser;
    if (diffusion_ && D_field_) {
      PetscCall(spectral_field_stage_adjoint(t, U, x, y, mu));
      PetscFunctionReturn(0);
    }
    Vec work[3] = {t1_, t2_, t3_};
    const std::vector<Vec> out(work, work + parts_.size());
    if (out.size() == 2) PetscCall(spectral_.apply_pair(packed_parts_, x, out[0], out[1])); // one product per mode
    else { // one forward transform of x for all of them
      std::vector<const SpectralDifferentiator::Symbol *> ms;
      for (const auto &q : parts_) ms.push_back(&q);
      PetscCall(spectral_.apply_many(ms, x, out));
    }
    { // y = sum_j c_j out_j and the sums <u, out_j>, in one pass
      const PetscInt m = (PetscInt)out.size();
      PetscReal c[3];
      const PetscScalar *v[3], *u = nullptr;
      for (PetscInt j = 0; j < m; ++j) {
        c[j] = j < nd ? vel_[j] : D_scalar_;
        PetscCall(VecGetArrayRead(out[j], &v[j]));
      }
      if (mu) PetscCall(VecGetArrayRead(U, &u));
      {
        Array Y(y);
        PetscCall(Y.error());
        PetscScalar *ya = Y.data();
        switch (m) { // (the number of parts fixed at compile time, so that the loop vectorises)
        case 1: combine_parts<1>(n, c, v, ya); break;
        case 2: combine_parts<2>(n, c, v, ya); break;
        default: combine_parts<3>(n, c, v, ya); break;
        }
      }
      if (mu)
        for (PetscInt j = 0; j < m; ++j) local[j] = dot4(reinterpret_cast<const PetscReal *>(v[j]), u, n);
      if (mu) PetscCall(VecRestoreArrayRead(U, &u));
      for (PetscInt j = 0; j < m; ++j) PetscCall(VecRestoreArrayRead(out[j], &v[j]));
    }
    if (mu) {
      for (PetscInt d = 0; d < nd; ++d) PetscCall(params_->add_local_sum(mu, vel_index_[d], local[d]));
      if (diffusion_) PetscCall(params_->add_local_sum(mu, D_index_, local[nd]));
    }
    PetscFunctionReturn(0);
  }

  // The spectral stage with a field D: y = A^T x = S^T x + sum_d E_d (D .* E_d x) (spectral_apply),
  // (dG/da_d)^T x = <u, D_d x> (Parseval, no transform of its own), and (dG/dD)^T x = P g,
  // g = -sum_d E_d u .* E_d x, P applied once after the adjoint (end_adjoint), not at every stage.
  // x and u go forward together as z = x + i alpha u (transform_pair, alpha balancing their sizes):
  // E_d z's backward transform is E_d x + i alpha E_d u, z^ stands for x^ in the last backward sum, and
  // <u, D_d x> comes from |z^|^2 (pairing_packed). Transforms: z and D E_d x forward, E_d z and the sum
  // backward: 4 in 1D, 5 in 2D (the forward operator takes 4).
  PetscErrorCode spectral_field_stage_adjoint(PetscReal, Vec U, Vec x, Vec y, Vec mu) {
    const PetscInt n = grid_->local_points();
    Vec ex[2] = {t1_, t2_}, eu[2] = {w_[0], w_[1]};
    PetscReal alpha = 1;
    PetscFunctionBeginUser;
    if (!mu) { // y = A^T x alone
      PetscCall(spectral_apply(x, y, true));
      PetscFunctionReturn(0);
    }
    PetscCall(spectral_.balance(x, U, &alpha));
    PetscCall(spectral_.transform_pair(x, U, alpha, xhat_));
    for (PetscInt d = 0; d < dim_; ++d) PetscCall(spectral_.backward({{&dealiased_[d], &xhat_}}, ex[d], eu[d]));
    for (PetscInt d = 0; d < dim_; ++d) PetscCall(params_->add_local_sum(mu, vel_index_[d], spectral_.pairing_packed(parts_[d], xhat_, alpha)));
    std::fill(gD_.begin(), gD_.end(), 0.0);
    const PetscReal s = 1 / alpha;
    for (PetscInt d = 0; d < dim_; ++d) {
      ConstArray a(ex[d]), b(eu[d]);
      PetscCall(a.error());
      PetscCall(b.error());
      for (PetscInt il = 0; il < n; ++il) gD_[il] -= s * PetscRealPart(a[il]) * PetscRealPart(b[il]);
    }
    if (!defer_truncation_) { // (an adjoint outside the Simulation's: truncate here)
      PetscCall(VecPlaceArray(t3_, gD_.data()));
      PetscCall(spectral_.dealias(t3_, t3_));
      PetscCall(VecResetArray(t3_));
    }
    PetscCall(params_->add_pointwise(mu, D_index_, gD_));
    PetscCall(diffusion_sum(symbol_t_, xhat_, ex, y));
    PetscFunctionReturn(0);
  }

  // Spectral field D: between begin_adjoint and end_adjoint the transposes add their field sums g to
  // mu without the 2/3-rule truncation P (each would cost two transforms), and end_adjoint truncates
  // mu's D once: P is linear and a projection, so P applied to the sum equals the sum of the P g.
  void begin_adjoint() override { defer_truncation_ = scheme_ == SPECTRAL && diffusion_ && D_field_; }
  PetscErrorCode end_adjoint(Vec mu) override {
    PetscFunctionBeginUser;
    const bool deferred = defer_truncation_;
    defer_truncation_ = false;
    if (!deferred || !mu) PetscFunctionReturn(0);
    PetscCall(params_->get_field(mu, D_index_, t3_));
    PetscCall(spectral_.dealias(t3_, t3_));
    PetscCall(params_->set_field(mu, D_index_, t3_));
    PetscFunctionReturn(0);
  }

  // Field D: (I D)_f at the faces the owned points touch (1D: as face_products indexes them; 2D: as
  // field_stage_faces_2d_rows does), for stage_adjoint's diffusion transpose: D changes only with the
  // parameters.
  PetscErrorCode cache_face_diffusivity() {
    const PetscScalar *D;
    PetscFunctionBeginUser;
    const Grid &g = *grid_;
    const PetscInt WD = face_.width, xm = g.xm(), ym = g.ym(), sy = stride_[1];
    PetscCall(VecGetArrayRead(D_local_, &D));
    auto at = [&](PetscInt first, PetscInt step) { // I D at the face whose first ghosted entry is `first`
      PetscReal v = 0;
      for (PetscInt m = 0; m < WD; ++m) v += face_.interp[m] * PetscRealPart(D[first + m * step]);
      return v;
    };
    const PetscInt g0 = ghost_index(g.xs(), g.ys());
    if (dim_ == 1) {
      face_D_.resize(xm + WD - 1);
      for (PetscInt k = 0; k < xm + WD - 1; ++k) face_D_[k] = at(g0 - (WD - 1) + k, 1);
    } else { // along x: row jl's faces; along y: face rows (the layouts of field_stage_faces_2d_rows)
      face_D_.resize(ym * (xm + WD - 1));
      for (PetscInt jl = 0; jl < ym; ++jl)
        for (PetscInt k = 0; k < xm + WD - 1; ++k) face_D_[jl * (xm + WD - 1) + k] = at(g0 + jl * sy - (WD - 1) + k, 1);
      face_D_y_.resize((ym + WD - 1) * xm);
      for (PetscInt kf = 0; kf < ym + WD - 1; ++kf)
        for (PetscInt i = 0; i < xm; ++i) face_D_y_[kf * xm + i] = at(g0 + (kf - (WD - 1)) * sy + i, sy);
      const size_t need = (size_t)std::max((ym + WD - 1) * xm, xm + WD - 1); // faces_2d's y faces
      if (faces_.size() < need) faces_.resize(need);
      if (faces2_.size() < (size_t)(xm + WD - 1)) faces2_.resize(xm + WD - 1); // a row's x faces
    }
    PetscCall(VecRestoreArrayRead(D_local_, &D));
    PetscFunctionReturn(0);
  }
  // 2D field D: y += the diffusion transpose and, unless g is null, g += the field's gradient, from
  // ghosted x and the stage's u read in place (u: its owned array; ghosts from halo2_, exchanged
  // already, or wrapped on one rank), in one pass over the rows (field_stage_faces_2d_rows).
  // first(jl) writes row jl of y before its faces are added (fused_stage_2d).
  template <class First>
  void field_stage_2d(const PetscScalar *xl, const PetscScalar *u, PetscScalar *y, PetscScalar *g, const First &first) {
    const Grid &gr = *grid_;
    const PetscInt g0 = ghost_index(gr.xs(), gr.ys()), xm = gr.xm(), WD = face_.width;
    const PetscReal *grad = face_.grad.data(), *ip = face_.interp.data();
    const PetscReal sx = 1.0 / (h_[0] * h_[0]), sy = 1.0 / (h_[1] * h_[1]);
    const URows U{u, xm, gr.ym(), wrap_ ? nullptr : &halo2_};
    if (ring_.size() < (size_t)(2 * WD * xm)) ring_.resize(2 * WD * xm);
    if (urow_.size() < (size_t)(xm + 2 * WD)) urow_.resize(xm + 2 * WD);
    PetscReal *R1 = ring_.data(), *R2 = R1 + WD * xm;
#define FLEXIPDE_FS2(WD, G)                                                                                          \
  field_stage_faces_2d_rows<WD, G>(xm, gr.ym(), stride_[1], face_D_.data(), face_D_y_.data(), grad, ip, xl + g0, U, sx, \
                                   sy, faces_.data(), faces2_.data(), R1, R2, urow_.data(), y, g, first)
    if (WD == 2) FLEXIPDE_FS2(2, false); // (with a gradient: fused_stage_2d_fd2)
    else g ? FLEXIPDE_FS2(4, true) : FLEXIPDE_FS2(4, false);
#undef FLEXIPDE_FS2
  }

  // A 2D field-D stage in one pass over the rows: each row of y gets the sweep (A^T x without the field's
  // faces; with g, the scalars' sums as sweep_sums, into sums) and then its faces (field_stage_2d), so
  // y, x and u are read once per row instead of once by the sweep and again by the faces. The same
  // arithmetic in the same order as the two passes.
  template <int R>
  void fused_stage_2d(const PetscScalar *xl, const PetscScalar *u, PetscScalar *y, PetscScalar *g, PetscReal *sums) {
    const PetscInt xm = grid_->xm(), sy = stride_[1];
    const PetscScalar *l0 = row(xl, 0);
    if (!g) {
      const std::array<PetscReal, 7> *t = at_taps_;
      field_stage_2d(xl, nullptr, y, nullptr, [&](PetscInt jl) { sweep_row<R, 2>(l0 + jl * sy, t, y + jl * xm, xm, sy); });
      return;
    }
    const SweepSumsTaps t = sweep_sums_taps(); // (no Laplacian part: D is a field)
    PetscReal *z = stage_scratch_.data();
    sums[0] = sums[1] = sums[2] = 0;
    field_stage_2d(xl, u, y, g, [&](PetscInt jl) {
      sweep_sums_row<R, 2, false>(l0 + jl * sy, t.vx, t.vy, t.lx, t.ly, t.c, u + jl * xm, y + jl * xm, xm, sy, z, sums);
    });
  }
  // fused_stage_2d with fd2 faces and a gradient, one loop per row (field_stage_row_fd2).
  template <int R>
  void fused_stage_2d_fd2(const PetscScalar *xl, const PetscScalar *u, PetscScalar *y, PetscScalar *g, PetscReal *sums) {
    const Grid &gr = *grid_;
    const PetscInt xm = gr.xm(), ym = gr.ym(), sy = stride_[1];
    const PetscScalar *x0 = xl + ghost_index(gr.xs(), gr.ys());
    // (the fd2 faces: face_stencil(2), grad = (-1, 1), interp = (1/2, 1/2), written into field_stage_row_fd2)
    const PetscReal sx = 1.0 / (h_[0] * h_[0]), syy = 1.0 / (h_[1] * h_[1]);
    const URows U{u, xm, ym, wrap_ ? nullptr : &halo2_};
    if (ring_.size() < (size_t)(4 * xm)) ring_.resize(4 * xm);
    if (urow_.size() < (size_t)(xm + 4)) urow_.resize(xm + 4);
    PetscReal *R1 = ring_.data(), *R2 = R1 + 2 * xm, *z = stage_scratch_.data();
    PetscScalar *ub = urow_.data();
    const SweepSumsTaps t = sweep_sums_taps(); // (no Laplacian part: D is a field)
    sums[0] = sums[1] = sums[2] = 0;
    { // the face row below row 0 (rows -1 and 0) into ring slot 0
      const PetscScalar *ur[2] = {U.row(-1), U.row(0)};
      face_row_2d<2, true>(xm, sy, face_D_y_.data(), face_.grad.data(), x0 - sy, ur, R1, R2);
    }
    for (PetscInt jl = 0; jl < ym; ++jl) {
      const PetscInt lo = jl % 2, up = 1 - lo;
      U.ghosted_row(jl, 1, ub);
      field_stage_row_fd2<R>(xm, sy, x0 + jl * sy, t.vx + 3 - R, t.vy + 3 - R, t.c[0], t.c[1], ub, U.row(jl + 1),
                             face_D_.data() + jl * (xm + 1), face_D_y_.data() + (jl + 1) * xm, sx, syy, R1 + lo * xm,
                             R2 + lo * xm, R1 + up * xm, R2 + up * xm, z, z + xm, y + jl * xm, g + jl * xm);
      sums[0] += dot4(z, u + jl * xm, xm);
      sums[1] += dot4(z + xm, u + jl * xm, xm);
    }
  }
  void fused_stage_2d(const PetscScalar *xl, const PetscScalar *u, PetscScalar *y, PetscScalar *g, PetscReal *sums) {
    if (g && face_.width == 2) {
      switch (radius_) {
      case 1: fused_stage_2d_fd2<1>(xl, u, y, g, sums); return;
      case 2: fused_stage_2d_fd2<2>(xl, u, y, g, sums); return;
      default: fused_stage_2d_fd2<3>(xl, u, y, g, sums); return;
      }
    }
    switch (radius_) {
    case 1: fused_stage_2d<1>(xl, u, y, g, sums); break;
    case 2: fused_stage_2d<2>(xl, u, y, g, sums); break;
    default: fused_stage_2d<3>(xl, u, y, g, sums); break;
    }
  }

  // An explicit RK adjoint stage at state U (finite differences): y = A^T x and mu += (dG/dp)^T x in
  // one pass over the ghosted x: the velocities' -<u, D_d^T x> / h_d, a scalar D's <u, B^T B x>-column
  // (local sums, reduced once per adjoint by the Parameters), a field D's face products with u.
  bool has_stage_adjoint() const override { return true; }
  PetscErrorCode stage_adjoint(PetscReal t, Vec U, const PetscScalar *, Vec x, Vec y, Vec mu) override {
    if (scheme_ == SPECTRAL) return spectral_stage_adjoint(t, U, x, y, mu);
    PetscFunctionBeginUser;
    if (diffusion_ && D_field_ && dim_ == 1) PetscCall(fill_ghosted_pair(x, X_local_, U, U_local_)); // the faces read u's ghosts too
    else if (diffusion_ && D_field_ && !wrap_) { // 2D reads u in place: its ghosts only
      PetscCall(halo2_.begin(U));
      PetscCall(fill_ghosted(x, X_local_));
      PetscCall(halo2_.end(U));
    } else PetscCall(fill_ghosted(x, X_local_));
    PetscCall(fd_stage_adjoint(U, y, mu));
    PetscFunctionReturn(0);
  }
  // Finite differences copy x into the ghosted X_local_ anyway: the combination is formed there, in
  // the same pass (on several ranks also into its scratch Vec, whose halo is exchanged).
  PetscErrorCode stage_adjoint_combination(PetscReal t, Vec U, const PetscScalar *record, const StageCombination &x, Vec y,
                                           Vec mu) override {
    const bool field = diffusion_ && D_field_;
    PetscFunctionBeginUser;
    if (scheme_ == SPECTRAL || x.m > 3) {
      PetscCall(LinearModel::stage_adjoint_combination(t, U, record, x, y, mu));
      PetscFunctionReturn(0);
    }
    if (wrap_) {
      PetscCall(fill_interior(x, X_local_, Part::All));
      if (field && dim_ == 1) PetscCall(fill_interior(U, U_local_)); // (2D reads u in place)
    } else if (dim_ == 1) PetscCall(fill_ghosted_packed(x, field ? U : nullptr)); // x's and u's ghosts in one exchange
    else { // 2D: rows of ghosts, exchanged by two Halos in flight together (see packed_); u is read in place.
      // x's strips that the neighbours read are formed (and copied into the scratch Vec) first, the rest
      // while they travel.
      if (field) PetscCall(halo2_.begin(U));
      PetscCall(fill_interior(x, X_local_, Part::Strips, x.scratch));
      PetscCall(halo_.begin(x.scratch));
      PetscCall(fill_interior(x, X_local_, Part::Rest));
      PetscCall(fill_halo(halo_, x.scratch, X_local_));
      if (field) PetscCall(halo2_.end(U));
    }
    PetscCall(fd_stage_adjoint(U, y, mu));
    PetscFunctionReturn(0);
  }
  // The finite-difference stage from the ghosted X_local_ (and, with a field D: in 1D U_local_, in 2D U
  // with halo2_'s ghosts). A field D's diffusion transpose and gradient come from the face kernels
  // (1D: with the sweep; 2D: field_stage_2d), with the cached face D.
  PetscErrorCode fd_stage_adjoint(Vec U, Vec y, Vec mu) {
    const PetscScalar *xl, *u;
    PetscReal local[3] = {0, 0, 0};
    const bool field = diffusion_ && D_field_;
    const PetscInt n = grid_->local_points(), nd = dim_;
    PetscFunctionBeginUser;
    PetscCall(VecGetArrayRead(X_local_, &xl));
    PetscCall(VecGetArrayRead(U, &u));
    {
      Array Y(y);
      PetscCall(Y.error());
      PetscScalar *ya = Y.data();
      if (nd == 1 && field && mu && face_.width == 2) { // one loop (field_stage_fd2_1d)
        const PetscScalar *ul;
        PetscScalar *g;
        PetscReal *z = stage_scratch_.data();
        PetscCall(VecGetArrayRead(U_local_, &ul));
        PetscCall(VecGetArray(mu, &g));
        const PetscInt g0 = ghost_index(grid_->xs(), grid_->ys());
        const PetscReal s = vel_[0] * (-1.0 / h_[0]), ih2 = 1.0 / (h_[0] * h_[0]);
        PetscScalar *gD = g + params_->info(D_index_).local_offset;
        const PetscReal *t = vel_taps_t_[0][0].data() + 3;
        switch (radius_) {
        case 1: field_stage_fd2_1d<1>(n, xl + g0, ul + g0, t - 1, face_D_.data(), ih2, s, z, ya, gD); break;
        case 2: field_stage_fd2_1d<2>(n, xl + g0, ul + g0, t - 2, face_D_.data(), ih2, s, z, ya, gD); break;
        default: field_stage_fd2_1d<3>(n, xl + g0, ul + g0, t - 3, face_D_.data(), ih2, s, z, ya, gD); break;
        }
        local[0] = -1.0 / h_[0] * dot4(z, u, n);
        PetscCall(VecRestoreArray(mu, &g));
        PetscCall(VecRestoreArrayRead(U_local_, &ul));
      } else if (nd == 1 && (!diffusion_ || field)) { // A^T = -(a / h) D^T (+ the field's faces): one sweep for both
        sweep(xl, vel_taps_t_[0], ya);
        local[0] = -1.0 / h_[0] * dot4(ya, u, n);
        const PetscReal s = vel_[0] * (-1.0 / h_[0]);
        if (!field)
          for (PetscInt il = 0; il < n; ++il) ya[il] *= s;
        else { // the scaling, the faces: J^T's diffusion (cached face D) and, with mu, D's gradient
          const PetscScalar *ul;
          PetscScalar *g = nullptr;
          PetscCall(VecGetArrayRead(U_local_, &ul));
          if (mu) PetscCall(VecGetArray(mu, &g));
          PetscScalar *gD = g ? g + params_->info(D_index_).local_offset : nullptr;
          const PetscInt f0 = ghost_index(grid_->xs(), grid_->ys()) - (face_.width - 1);
          const PetscReal *Df = face_D_.data(), *gr = face_.grad.data(), *ip = face_.interp.data();
          const PetscReal ih2 = 1.0 / (h_[0] * h_[0]);
          PetscReal *F1 = faces_.data(), *F2 = faces2_.data();
          // (fd2 faces with a gradient: field_stage_fd2_1d above)
          if (face_.width == 2) field_stage_faces<2, false>(n, Df, gr, ip, xl + f0, ul + f0, ih2, s, F1, F2, ya, gD);
          else if (gD) field_stage_faces<4, true>(n, Df, gr, ip, xl + f0, ul + f0, ih2, s, F1, F2, ya, gD);
          else field_stage_faces<4, false>(n, Df, gr, ip, xl + f0, ul + f0, ih2, s, F1, F2, ya, gD);
          if (g) PetscCall(VecRestoreArray(mu, &g));
          PetscCall(VecRestoreArrayRead(U_local_, &ul));
        }
      } else if (mu) { // A^T x and the scalars' sums in one sweep
        PetscReal sums[3];
        if (field) { // (2D: a 1D field D took the first branch) with the faces: B x once per face
          PetscScalar *g;
          PetscCall(VecGetArray(mu, &g));
          fused_stage_2d(xl, u, ya, g + params_->info(D_index_).local_offset, sums);
          PetscCall(VecRestoreArray(mu, &g));
        } else sweep_sums(xl, u, ya, sums);
        for (PetscInt d = 0; d < nd; ++d) local[d] = -1.0 / h_[d] * sums[d];
        local[nd] = sums[2];
      } else if (field) fused_stage_2d(xl, nullptr, ya, nullptr, nullptr);
      else sweep(xl, at_taps_, ya);
    }
    PetscCall(VecRestoreArrayRead(U, &u));
    if (mu) {
      for (PetscInt d = 0; d < nd; ++d) PetscCall(params_->add_local_sum(mu, vel_index_[d], local[d]));
      if (diffusion_ && !field) PetscCall(params_->add_local_sum(mu, D_index_, local[nd]));
    }
    PetscCall(VecRestoreArrayRead(X_local_, &xl));
    PetscFunctionReturn(0);
  }

  const Grid *grid_ = nullptr;
  DM dm_ = nullptr;
  Parameters *params_ = nullptr;
  PetscInt dim_ = 1;
  PetscInt scheme_ = FD2, ic_ = SINUSOID, mode_[2] = {1, 1};
  PetscBool diffusion_ = PETSC_FALSE, D_field_ = PETSC_FALSE, amplitude_param_ = PETSC_FALSE;
  FaceStencil face_ = face_stencil(2);
  PetscInt vel_index_[2] = {-1, -1}, D_index_ = -1, A_index_ = -1;
  PetscReal vel_[2] = {0, 0}, h_[2] = {1, 1}, D_scalar_ = 0, Dmax_ = 0;
  std::array<PetscReal, 5> w1_[2] = {first_derivative_weights(FD2, 0), first_derivative_weights(FD2, 0)};
  PetscReal amplitude_ = 1.0, phase_ = 0, center_[2] = {0, 0}, width_ = 0;
  PetscInt gxs_ = 0, gys_ = 0, gxm_ = 1, stride_[2] = {1, 1};
  // D_: the diffusivity per grid point (spectral field: its 2/3 truncation P D).
  OwnedVec D_, D_local_, dD_, dD_local_, U_local_, X_local_;
  SpectralDifferentiator spectral_;
  OwnedVec t1_, t2_, t3_, w_[2]; // spectral work vectors; w_[d] = E_d u for a field D
  // Spectral 1D without diffusion: D_x of the Vec (id, state) last differentiated
  // (spectral_mult_transpose).
  bool shared_dx_ = false;
  OwnedVec dx_;
  // The stage recorded by rhs_jacobian_p (spectral 1D without diffusion, and lazy_: finite
  // differences without a field D); the record whose columns dGdv_, dGdD_ hold; J^T's fused dG/dp
  // products and its work array.
  bool lazy_ = false;
  RecordedStage stage_;
  unsigned long columns_serial_ = 0;
  FusedProducts fused_;
  std::vector<PetscReal> scratch_;
  std::vector<PetscReal> stage_scratch_;  // stage_adjoint's sweeps
  SpectralDifferentiator::Symbol symbol_; // spectral: the constant-coefficient operator's symbol
  std::vector<SpectralDifferentiator::Symbol> parts_; // spectral: i kappa_d (d < dim), then -|kappa|^2 (scalar D)
  SpectralDifferentiator::Symbol symbol_t_, dealiased_[2]; // conj(symbol_); a field D's E_d = P d/dx_d
  SpectralDifferentiator::Symbol packed_parts_;           // parts_[0] + i parts_[1] when there are two
  SpectralDifferentiator::Symbol flux_div_;               // field D, 2D: E_x - i E_y (diffusion_sum)
  SpectralDifferentiator::Spectrum xhat_, what_;            // spectra of x (or x + i alpha u) and of D E_x x [+ i D E_y x] (field D)
  bool defer_truncation_ = false; // spectral field D: P left to end_adjoint
  std::vector<PetscReal> face_D_, face_D_y_; // field D: I D at the faces (cache_face_diffusivity; y: 2D only)
  std::vector<PetscReal> faces2_;       // 1D: stage_adjoint's second face array
  mutable std::vector<PetscReal> faces_; // 1D: one value per face the owned points touch (face kernels)
  PetscObjectId dx_id_ = -1;
  PetscObjectState dx_state_ = -1;
  // dG/dv_d = dGdv_scale_[d] * dGdv_[d] (the scale kept apart: no division per point).
  std::vector<PetscReal> dGdv_[2], dGdD_, gD_; // gD_: a field D's gradient (jp_mult_transpose)
  // Finite differences: sweep taps (set_taps), ghost fill (fill_ghosted), and the last assembly of
  // the dG/dp shell (rhs_jacobian_p).
  std::array<PetscReal, 7> vel_taps_[2][2] = {}, vel_taps_t_[2][2] = {}, lap_taps_[2] = {}, at_taps_[2] = {};
  PetscReal dGdv_scale_[2] = {-1, -1};
  PetscInt radius_ = 1;
  bool wrap_ = false;
  Halo halo_, halo2_; // halo2_: a second exchange in flight with halo_'s (fill_ghosted_pair)
  // 1D on several ranks: the RK adjoint stage's x (and, with a field D, u) ghosts in one exchange, one
  // message per neighbour instead of two. Not in 2D: there the ghosts are rows, and at 128^2 the merged
  // message (4 KB) crosses Open MPI's eager limit where the two separate ones do not; the rendezvous
  // then costs more than the message saves.
  Halo packed_;
  std::vector<PetscReal> ring_;      // field_stage_2d's rings of y face rows
  std::vector<PetscScalar> urow_;    // ... and its row of u with ghosts
  PetscObjectId jp_id_ = -1;
  PetscObjectState jp_state_ = -1;
};

} // namespace

FLEXIPDE_REGISTER_MODEL("advection", AdvectionModel);

} // namespace flexipde
