// Linear advection-diffusion of one scalar on a periodic grid.
//
//   u_t + a u_x = (D u_x)_x   on [x0, x1) periodic,   u(x, 0) = u0(x; A)
//
// The velocity a is a scalar parameter (-advection_a). Diffusion is optional: -advection_diffusion
// (default on exactly when -advection_D, -advection_D_field or -advection_D_profile is given) adds
// the parameter D, one scalar (-advection_D) or a field D(x) (-advection_D_field 1). Without it
// the scene declares no D and assembles no diffusion stencil.
//
// Space (h the grid spacing, all stencils periodic):
//   -advection_scheme fd2     (u_x)_i = (u_{i+1} - u_{i-1}) / 2h                          order 2
//   -advection_scheme fd4     (u_x)_i = (u_{i-2} - 8u_{i-1} + 8u_{i+1} - u_{i+2}) / 12h   order 4
//   -advection_scheme upwind  (u_x)_i = (u_i - u_{i-1}) / h for a >= 0, (u_{i+1} - u_i) / h
//                             for a < 0: order 1, monotone (no new extrema on a square pulse)
//   Diffusion in conservative flux form, G_i = (F_{i+1/2} - F_{i-1/2}) / h for -fd_order 2,
//   F_f = D_f (u_x)_f at the faces f = i+1/2:
//     -fd_order 2: (u_x)_f = (u_{i+1} - u_i) / h,  D_f = (D_i + D_{i+1}) / 2
//     -fd_order 4: (u_x)_f = (u_{i-1} - 27u_i + 27u_{i+1} - u_{i+2}) / 24h,
//                  D_f = (-D_{i-1} + 9D_i + 9D_{i+1} - D_{i+2}) / 16,
//                  G_i = (F_{i-3/2} - 27F_{i-1/2} + 27F_{i+1/2} - F_{i+3/2}) / 24h
//   i.e. G_diff = -B^T diag(D_f) B u with B the face gradient: symmetric, negative semi-definite
//   while every D_f >= 0, conservative (sum_i G_i = 0) and of the stated order for a smooth
//   field D too. -fd_order defaults to 4 with fd4 and to 2 otherwise. A scalar D uses the same
//   operator with D_f = D (for -fd_order 4 its stencil is 7 points wide, not the usual 5).
//
//   G(U; a, D) = A(a, D) U,   A = -a D1 - B^T diag(I D) B         dG/dU = A (assembled, constant)
//   dG/da = -D1 u                                                 (one column)
//   dG/dD = -B^T diag(B u) I       (field; a scalar D sums the columns: -B^T B u)
// The transposes are pointwise products of face gradients, (dG/dD)^T l = -I^T (Bu .* Bl), so dG/dp
// is a MatShell and a gradient with respect to a field costs no more than one for a scalar.
// For upwind, dG/da is taken on the side of the current sign of a (one-sided at a = 0).
//
// Spectrum (for the explicit stability check): the eigenvalues of A are lambda(theta_k),
// theta_k = 2 pi k / N, from the stencils' symbols: centred advection is imaginary
// (|Im| <= |a| 1/h for fd2, 1.372 |a|/h for fd4), diffusion real (>= -D 4/h^2 for order 2,
// -D (56/24)^2/h^2 for order 4), upwind a circle touching both axes. The Simulation checks the two
// axes separately, which is exact when the spectrum lies on one axis but not when it lies off
// both; then both radii are reported as max_k |Re lambda_k| + |Im lambda_k|, the diamond spanned
// by the axis limits lying inside the stability region of the RK methods (checked for rk 3, 4,
// 3bs and 5dp in tests/test_advection.cpp). A field D bounds the diffusion part by max D_f times the scalar
// symbol (field of values), so its bound is a rectangle.
//
// Initial condition (-advection_ic, profile s(x), u0 = A s(x)):
//   sinusoid  s = sin(2 pi m (x - x0) / L + phi)     -advection_ic_mode m, -advection_ic_phase phi
//   gaussian  s = exp(-(d / w)^2)                    d the periodic distance to -advection_ic_center,
//   square    s = 1 where |d| < w / 2, else 0        w = -advection_ic_width
// The amplitude A (-advection_ic_amplitude) is a plain value unless -advection_ic_amplitude_param 1
// declares it as the scalar parameter advection_ic_amplitude; then dU0/dA = s enters the gradient.
//
//   mpiexec -n 2 ./flexipde -model advection -grid_periodic 1 -grid_x1 6.283185307179586
//           -da_grid_x 64 -ts_dt 0.01 -ts_max_time 1 -task taylor -objective_type mean_square
//           -advection_ic_amplitude_param 1 -advection_D 0.05 -advection_D_field 1   (one line)
//   mpiexec -n 2 ./flexipde -model advection -grid_periodic 1 -task gradient -advection_scheme upwind
//           -advection_a 0.8 -true_advection_a 1 -ts_type cn -ts_dt 1e-3 -ts_max_time 0.5 -check_fd
#include "flexipde/differentiator.hpp"
#include "flexipde/model.hpp"
#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <vector>

namespace flexipde {
namespace {

const char *const schemes[] = {"fd2", "fd4", "upwind"};
enum Scheme : PetscInt { FD2 = 0, FD4 = 1, UPWIND = 2 };
const char *const ic_names[] = {"sinusoid", "gaussian", "square"};
enum InitialCondition : PetscInt { SINUSOID = 0, GAUSSIAN = 1, SQUARE = 2 };

// Default diffusivity when diffusion is switched on without a value.
constexpr PetscReal default_diffusion = 0.01;

// The choices that fix the stencils. Read before the grid exists (its ghost width depends on
// them) without registering help, and again in setup with help, from the same defaults.
struct StencilChoice {
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
  PetscCall(PetscOptionsGetEList(nullptr, nullptr, "-advection_scheme", schemes, 3, &s.scheme, nullptr));
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

class AdvectionModel final : public LinearModel {
public:
  const char *name() const override { return "advection"; }
  PetscInt dof() const override { return 1; }
  const char *component_name(PetscInt) const override { return "u"; }
  PetscInt stencil_width(MPI_Comm) const override {
    StencilChoice s;
    if (read_stencil_choice(s)) return 1; // setup reports the bad option
    return half_width(s);
  }

  PetscErrorCode setup(const Grid &grid, DM state_dm, Parameters &params) override {
    StencilChoice s;
    SecondDerivative order_reader; // reads and checks -fd_order
    PetscFunctionBeginUser;
    grid_ = &grid;
    dm_ = state_dm;
    params_ = &params;
    const PetscReal L = grid.x1() - grid.x0();
    center_ = 0.5 * (grid.x0() + grid.x1());
    width_ = 0.1 * L;
    PetscCall(read_stencil_choice(s));
    scheme_ = s.scheme;
    diffusion_ = s.diffusion;
    PetscOptionsBegin(grid.comm(), nullptr, "Advection-diffusion model u_t + a u_x = (D u_x)_x", "Advection");
    PetscCall(PetscOptionsEList("-advection_scheme", "First derivative of the advection: fd2, fd4 (centred) or upwind",
                                "Advection", schemes, 3, schemes[s.scheme], &scheme_, nullptr));
    PetscCall(PetscOptionsBool("-advection_diffusion",
                               "Add (D u_x)_x with the parameter D (default: on when -advection_D* is given)", "Advection",
                               s.diffusion, &diffusion_, nullptr));
    PetscCall(PetscOptionsBool("-advection_D_field", "Diffusivity D is a field (one value per grid point), else one scalar",
                               "Advection", D_field_, &D_field_, nullptr));
    PetscCall(PetscOptionsEList("-advection_ic", "Initial profile", "Advection", ic_names, 3, ic_names[ic_], &ic_, nullptr));
    PetscCall(PetscOptionsBool("-advection_ic_amplitude_param",
                               "Declare the amplitude A of u0 = A s(x) as the parameter advection_ic_amplitude",
                               "Advection", amplitude_param_, &amplitude_param_, nullptr));
    if (!amplitude_param_)
      PetscCall(PetscOptionsReal("-advection_ic_amplitude", "Amplitude A of u0 = A s(x)", "Advection", amplitude_,
                                 &amplitude_, nullptr));
    PetscCall(PetscOptionsInt("-advection_ic_mode", "sinusoid: number m of periods in the domain", "Advection", mode_,
                              &mode_, nullptr));
    PetscCall(PetscOptionsReal("-advection_ic_phase", "sinusoid: phase phi", "Advection", phase_, &phase_, nullptr));
    PetscCall(PetscOptionsReal("-advection_ic_center", "gaussian, square: centre", "Advection", center_, &center_, nullptr));
    PetscCall(PetscOptionsReal("-advection_ic_width", "gaussian: width w of exp(-(d/w)^2); square: full width", "Advection",
                               width_, &width_, nullptr));
    PetscOptionsEnd();
    PetscCheck(grid.periodic(), grid.comm(), PETSC_ERR_ARG_WRONG,
               "Model advection needs a periodic grid (-grid_periodic 1): inflow and outflow boundaries are not "
               "implemented");
    PetscCheck(width_ > 0, grid.comm(), PETSC_ERR_ARG_OUTOFRANGE, "-advection_ic_width must be positive, got %g",
               (double)width_);
    if (diffusion_) {
      PetscCall(SecondDerivative::from_options(grid.comm(), nullptr, scheme_ == FD4 ? 4 : 2, order_reader));
      face_ = face_stencil(order_reader.order());
    }
    { // the grid was made for the choice read before setup; -help or a prefix must not change it
      StencilChoice now{scheme_, diffusion_, diffusion_ ? order_reader.order() : 2};
      PetscCheck(half_width(now) <= grid.stencil_width(), grid.comm(), PETSC_ERR_PLIB,
                 "Advection stencil half-width %" PetscInt_FMT " exceeds the grid's ghost width %" PetscInt_FMT,
                 half_width(now), grid.stencil_width());
    }

    a_index_ = params.add("advection_a", ParamKind::Scalar);
    if (diffusion_)
      D_index_ = params.add("advection_D", D_field_ ? ParamKind::Field : ParamKind::Scalar, 0.0, default_diffusion);
    if (amplitude_param_) A_index_ = params.add("advection_ic_amplitude", ParamKind::Scalar, PETSC_NINFINITY, amplitude_);

    PetscCall(DMCreateLocalVector(dm_, U_local_.out()));
    PetscCall(DMCreateLocalVector(dm_, X_local_.out()));
    if (diffusion_) {
      PetscCall(DMCreateGlobalVector(grid.dm(), D_.out()));
      PetscCall(DMCreateLocalVector(grid.dm(), D_local_.out()));
      if (D_field_) {
        PetscCall(DMCreateGlobalVector(grid.dm(), dD_.out()));
        PetscCall(DMCreateLocalVector(grid.dm(), dD_local_.out()));
      }
    }
    PetscCall(create_operator(dm_));
    dGda_.assign(grid.xm(), 0.0);
    dGdD_.assign(grid.xm(), 0.0);
    PetscFunctionReturn(0);
  }

  PetscErrorCode create_jacobian_p(Mat *Jp) override {
    PetscFunctionBeginUser;
    PetscCall(MatCreateShell(grid_->comm(), grid_->xm(), params_->local_size(), PETSC_DETERMINE, PETSC_DETERMINE, this, Jp));
    PetscCall(MatShellSetOperation(*Jp, MATOP_MULT, (void (*)(void))jp_mult));
    PetscCall(MatShellSetOperation(*Jp, MATOP_MULT_TRANSPOSE, (void (*)(void))jp_mult_transpose));
    PetscFunctionReturn(0);
  }

  PetscErrorCode set_parameters(Vec p) override {
    PetscFunctionBeginUser;
    PetscCall(params_->scalar(p, a_index_, &a_));
    if (diffusion_) {
      if (D_field_) PetscCall(params_->get_field(p, D_index_, D_));
      else {
        PetscReal D;
        PetscCall(params_->scalar(p, D_index_, &D));
        PetscCall(VecSet(D_, D));
      }
      PetscReal Dmin;
      PetscCall(VecMin(D_, nullptr, &Dmin));
      PetscCheck(Dmin >= 0, grid_->comm(), PETSC_ERR_ARG_OUTOFRANGE, "Diffusivity must be non-negative, found D = %g",
                 (double)Dmin);
      PetscCall(DMGlobalToLocal(grid_->dm(), D_, INSERT_VALUES, D_local_));
      PetscCall(face_diffusivity_range());
    }
    PetscCall(assemble(A_));
    PetscFunctionReturn(0);
  }

  // Records what the shell needs at this state: -D1 u (the column of a), the ghosted u for the
  // face gradients of a field D, and -B^T B u (the column of a scalar D).
  PetscErrorCode rhs_jacobian_p(PetscReal, Vec U, Mat Jp) override {
    PetscFunctionBeginUser;
    PetscCall(DMGlobalToLocal(dm_, U, INSERT_VALUES, U_local_));
    {
      const PetscScalar *u;
      PetscCall(DMDAVecGetArrayRead(dm_, U_local_, &u));
      const auto w = first_derivative_weights(scheme_, a_);
      const PetscReal ih = 1.0 / grid_->h();
      for (PetscInt il = 0; il < grid_->xm(); ++il) {
        const PetscInt i = grid_->xs() + il;
        PetscReal d1 = 0;
        for (PetscInt k = -2; k <= 2; ++k) // zero weights may lie beyond the ghosts: skip them
          if (w[k + 2] != 0) d1 += w[k + 2] * PetscRealPart(u[i + k]);
        dGda_[il] = -d1 * ih;
        if (diffusion_ && !D_field_) {
          PetscReal g = 0;
          for (PetscInt m = 0; m < face_.width; ++m) {
            const PetscInt f = i - face_.offset - m; // faces whose gradient reads u_i
            g -= face_.grad[m] * face_gradient(u, f) * ih * ih;
          }
          dGdD_[il] = g;
        }
      }
      PetscCall(DMDAVecRestoreArrayRead(dm_, U_local_, &u));
    }
    PetscCall(MatAssemblyBegin(Jp, MAT_FINAL_ASSEMBLY)); // resets any scaling TS applied last time
    PetscCall(MatAssemblyEnd(Jp, MAT_FINAL_ASSEMBLY));
    PetscFunctionReturn(0);
  }

  PetscErrorCode spectrum(Spectrum *s) override {
    const PetscInt n = grid_->n();
    const PetscReal h = grid_->h();
    const auto w = first_derivative_weights(scheme_, a_);
    // A scalar D makes A circulant (normal): its eigenvalues are the symbols below. A field D is
    // bounded through the field of values: the diffusion part lies in [-Dmax |b|^2, 0].
    const PetscReal D = diffusion_ ? Dface_max_ : 0.0;
    PetscReal re = 0, im = 0, l1 = 0, adv_l1 = 0, diff = 0;
    for (PetscInt k = 0; k < n; ++k) {
      const PetscReal th = 2 * PETSC_PI * k / n;
      std::complex<PetscReal> adv = 0, b = 0;
      for (PetscInt j = -2; j <= 2; ++j) adv += w[j + 2] * std::polar<PetscReal>(1.0, j * th);
      adv *= -a_ / h;
      if (diffusion_)
        for (PetscInt m = 0; m < face_.width; ++m) b += face_.grad[m] * std::polar<PetscReal>(1.0, (face_.offset + m) * th);
      const PetscReal d = -D * std::norm(b) / (h * h);
      const std::complex<PetscReal> lambda = adv + d;
      re = std::max(re, std::fabs(lambda.real()));
      im = std::max(im, std::fabs(lambda.imag()));
      l1 = std::max(l1, std::fabs(lambda.real()) + std::fabs(lambda.imag()));
      adv_l1 = std::max(adv_l1, std::fabs(adv.real()) + std::fabs(adv.imag()));
      diff = std::max(diff, -d);
    }
    if (diffusion_ && D_field_ && a_ != 0) l1 = adv_l1 + diff;
    const PetscReal tiny = 1e-12 * l1;
    if (re <= tiny || im <= tiny) { // on one axis: the axis check is exact
      s->imag_radius = im <= tiny ? 0 : im;
      s->real_radius = re <= tiny ? 0 : re;
    } else {
      s->imag_radius = s->real_radius = l1;
    }
    return 0;
  }

  PetscErrorCode initial_condition(Vec p, Vec U0) override {
    PetscFunctionBeginUser;
    PetscCall(set_parameters(p));
    PetscReal A = amplitude_;
    if (amplitude_param_) PetscCall(params_->scalar(p, A_index_, &A));
    Array U(U0);
    PetscCall(U.error());
    for (PetscInt il = 0; il < grid_->xm(); ++il) U[il] = A * profile(grid_->x(grid_->xs() + il));
    PetscFunctionReturn(0);
  }

  PetscErrorCode initial_condition_transpose(Vec, Vec lambda0, Vec grad) override {
    PetscFunctionBeginUser;
    if (!amplitude_param_) PetscFunctionReturn(0);
    PetscReal local = 0;
    {
      ConstArray L(lambda0);
      PetscCall(L.error());
      for (PetscInt il = 0; il < grid_->xm(); ++il) local += profile(grid_->x(grid_->xs() + il)) * PetscRealPart(L[il]);
    }
    PetscCall(params_->add_local_sum(grad, A_index_, local));
    PetscFunctionReturn(0);
  }

private:
  static PetscInt half_width(const StencilChoice &s) {
    const PetscInt adv = s.scheme == FD4 ? 2 : 1;
    const PetscInt diff = s.diffusion ? (s.diffusion_order == 4 ? 3 : 1) : 0;
    return std::max(adv, diff);
  }

  PetscReal profile(PetscReal x) const {
    const PetscReal L = grid_->x1() - grid_->x0();
    if (ic_ == SINUSOID) return std::sin(2 * PETSC_PI * mode_ * (x - grid_->x0()) / L + phase_);
    PetscReal d = x - center_;
    d -= L * std::floor(d / L + 0.5); // periodic distance in [-L/2, L/2)
    if (ic_ == GAUSSIAN) return std::exp(-(d / width_) * (d / width_));
    return std::fabs(d) < 0.5 * width_ ? 1.0 : 0.0;
  }

  // Face gradient (B u)_f without the 1/h, on a ghosted array indexed by global position.
  PetscReal face_gradient(const PetscScalar *u, PetscInt f) const {
    PetscReal g = 0;
    for (PetscInt m = 0; m < face_.width; ++m) g += face_.grad[m] * PetscRealPart(u[f + face_.offset + m]);
    return g;
  }
  PetscReal face_value(const PetscScalar *D, PetscInt f) const {
    PetscReal v = 0;
    for (PetscInt m = 0; m < face_.width; ++m) v += face_.interp[m] * PetscRealPart(D[f + face_.offset + m]);
    return v;
  }

  // Largest face diffusivity (for the spectrum) and a check that none is negative: a negative
  // D_f makes the operator anti-diffusive, which only the 4-point interpolation can produce.
  PetscErrorCode face_diffusivity_range() {
    const PetscScalar *D;
    PetscReal mm[2] = {PETSC_MAX_REAL, 0}; // min, max
    PetscFunctionBeginUser;
    PetscCall(DMDAVecGetArrayRead(grid_->dm(), D_local_, &D));
    for (PetscInt f = grid_->xs(); f < grid_->xs() + grid_->xm(); ++f) {
      const PetscReal v = face_value(D, f);
      mm[0] = std::min(mm[0], v);
      mm[1] = std::max(mm[1], v);
    }
    PetscCall(DMDAVecRestoreArrayRead(grid_->dm(), D_local_, &D));
    mm[0] = -mm[0];
    PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, mm, 2, MPIU_REAL, MPI_MAX, grid_->comm()));
    PetscCheck(-mm[0] >= 0, grid_->comm(), PETSC_ERR_ARG_OUTOFRANGE,
               "-fd_order 4 interpolates D to the cell faces with weights (-1, 9, 9, -1)/16, which gives a negative "
               "face diffusivity %g here: smooth the field D or use -fd_order 2",
               (double)-mm[0]);
    Dface_max_ = mm[1];
    PetscFunctionReturn(0);
  }

  PetscErrorCode assemble(Mat A) override {
    const PetscInt xs = grid_->xs(), xm = grid_->xm(), n = grid_->n(), r = grid_->stencil_width();
    const PetscReal ih = 1.0 / grid_->h();
    const auto w = first_derivative_weights(scheme_, a_);
    const PetscScalar *D = nullptr;
    std::vector<PetscInt> cols(2 * r + 1);
    std::vector<PetscScalar> vals(2 * r + 1), row(2 * r + 1);
    std::vector<char> used(2 * r + 1);
    PetscFunctionBeginUser;
    PetscCall(MatZeroEntries(A));
    if (diffusion_) PetscCall(DMDAVecGetArrayRead(grid_->dm(), D_local_, &D));
    for (PetscInt i = xs; i < xs + xm; ++i) {
      // Row i by offset k = j - i in -r..r (distinct columns: the grid has at least 2r + 3 points).
      // The diagonal is always stored so that an implicit TS's shift finds it.
      std::fill(row.begin(), row.end(), 0.0);
      std::fill(used.begin(), used.end(), 0);
      used[r] = 1;
      for (PetscInt k = -2; k <= 2; ++k)
        if (w[k + 2] != 0) {
          row[k + r] -= a_ * w[k + 2] * ih;
          used[k + r] = 1;
        }
      if (diffusion_) {
        for (PetscInt m = 0; m < face_.width; ++m) { // -B^T diag(D_f) B: faces f whose gradient reads u_i
          const PetscInt f = i - face_.offset - m;
          const PetscReal c = -face_.grad[m] * face_value(D, f) * ih * ih;
          for (PetscInt q = 0; q < face_.width; ++q) {
            row[q - m + r] += c * face_.grad[q];
            used[q - m + r] = 1;
          }
        }
      }
      PetscInt cnt = 0;
      for (PetscInt k = -r; k <= r; ++k) {
        if (!used[k + r]) continue;
        cols[cnt] = ((i + k) % n + n) % n;
        vals[cnt] = row[k + r];
        ++cnt;
      }
      PetscCall(MatSetValues(A, 1, &i, cnt, cols.data(), vals.data(), INSERT_VALUES));
    }
    if (diffusion_) PetscCall(DMDAVecRestoreArrayRead(grid_->dm(), D_local_, &D));
    PetscCall(MatAssemblyBegin(A, MAT_FINAL_ASSEMBLY));
    PetscCall(MatAssemblyEnd(A, MAT_FINAL_ASSEMBLY));
    PetscFunctionReturn(0);
  }

  // y = dG/dp x   (x in parameter space, y in state space)
  static PetscErrorCode jp_mult(Mat Jp, Vec x, Vec y) {
    AdvectionModel *m;
    PetscFunctionBeginUser;
    PetscCall(MatShellGetContext(Jp, &m));
    const Grid &g = *m->grid_;
    PetscReal da, dD = 0;
    PetscCall(m->params_->scalar(x, m->a_index_, &da));
    if (m->diffusion_ && !m->D_field_) PetscCall(m->params_->scalar(x, m->D_index_, &dD));
    const PetscScalar *u = nullptr, *ddl = nullptr;
    if (m->diffusion_ && m->D_field_) {
      PetscCall(m->params_->get_field(x, m->D_index_, m->dD_));
      PetscCall(DMGlobalToLocal(g.dm(), m->dD_, INSERT_VALUES, m->dD_local_));
      PetscCall(DMDAVecGetArrayRead(g.dm(), m->dD_local_, &ddl));
      PetscCall(DMDAVecGetArrayRead(m->dm_, m->U_local_, &u));
    }
    {
      Array Y(y);
      PetscCall(Y.error());
      const PetscReal ih = 1.0 / g.h();
      for (PetscInt il = 0; il < g.xm(); ++il) {
        PetscReal v = m->dGda_[il] * da;
        if (m->diffusion_ && !m->D_field_) v += m->dGdD_[il] * dD;
        if (ddl) { // -B^T (B u .* I dD)
          const PetscInt i = g.xs() + il;
          for (PetscInt q = 0; q < m->face_.width; ++q) {
            const PetscInt f = i - m->face_.offset - q;
            v -= m->face_.grad[q] * ih * m->face_gradient(u, f) * ih * m->face_value(ddl, f);
          }
        }
        Y[il] = v;
      }
    }
    if (ddl) {
      PetscCall(DMDAVecRestoreArrayRead(g.dm(), m->dD_local_, &ddl));
      PetscCall(DMDAVecRestoreArrayRead(m->dm_, m->U_local_, &u));
    }
    PetscFunctionReturn(0);
  }

  // y = (dG/dp)^T x   (x in state space, y in parameter space)
  static PetscErrorCode jp_mult_transpose(Mat Jp, Vec x, Vec y) {
    AdvectionModel *m;
    PetscFunctionBeginUser;
    PetscCall(MatShellGetContext(Jp, &m));
    const Grid &g = *m->grid_;
    PetscReal sa = 0, sD = 0;
    PetscCall(VecSet(y, 0.0));
    {
      ConstArray X(x);
      PetscCall(X.error());
      for (PetscInt il = 0; il < g.xm(); ++il) {
        sa += m->dGda_[il] * PetscRealPart(X[il]);
        if (m->diffusion_ && !m->D_field_) sD += m->dGdD_[il] * PetscRealPart(X[il]);
      }
    }
    PetscCall(m->params_->add_local_sum(y, m->a_index_, sa));
    if (m->diffusion_ && !m->D_field_) PetscCall(m->params_->add_local_sum(y, m->D_index_, sD));
    if (m->diffusion_ && m->D_field_) { // -I^T (B u .* B x): faces around each owned D_k
      const PetscScalar *u, *xl;
      PetscCall(DMGlobalToLocal(m->dm_, x, INSERT_VALUES, m->X_local_));
      PetscCall(DMDAVecGetArrayRead(m->dm_, m->U_local_, &u));
      PetscCall(DMDAVecGetArrayRead(m->dm_, m->X_local_, &xl));
      const ParamInfo &pi = m->params_->info(m->D_index_);
      const PetscReal ih2 = 1.0 / (g.h() * g.h());
      {
        Array Y(y);
        PetscCall(Y.error());
        for (PetscInt il = 0; il < pi.local_size; ++il) {
          const PetscInt k = g.xs() + il;
          PetscReal v = 0;
          for (PetscInt q = 0; q < m->face_.width; ++q) {
            const PetscInt f = k - m->face_.offset - q;
            v -= m->face_.interp[q] * m->face_gradient(u, f) * m->face_gradient(xl, f) * ih2;
          }
          Y[pi.local_offset + il] = v;
        }
      }
      PetscCall(DMDAVecRestoreArrayRead(m->dm_, m->U_local_, &u));
      PetscCall(DMDAVecRestoreArrayRead(m->dm_, m->X_local_, &xl));
    }
    PetscFunctionReturn(0);
  }

  const Grid *grid_ = nullptr;
  DM dm_ = nullptr;
  Parameters *params_ = nullptr;
  PetscInt scheme_ = FD2, ic_ = SINUSOID, mode_ = 1;
  PetscBool diffusion_ = PETSC_FALSE, D_field_ = PETSC_FALSE, amplitude_param_ = PETSC_FALSE;
  FaceStencil face_ = face_stencil(2);
  PetscInt a_index_ = -1, D_index_ = -1, A_index_ = -1;
  PetscReal a_ = 0, Dface_max_ = 0, amplitude_ = 1.0, phase_ = 0, center_ = 0, width_ = 0;
  OwnedVec D_, D_local_, dD_, dD_local_, U_local_, X_local_;
  std::vector<PetscReal> dGda_, dGdD_;
};

} // namespace

std::unique_ptr<Model> make_advection_model() { return std::make_unique<AdvectionModel>(); }

} // namespace flexipde
