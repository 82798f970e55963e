// Viscous Burgers equation on a periodic grid, in conservative flux form:
//
//   u_t + (u^2/2)_x = (nu(x) u_x)_x,      x in [x0, x1), periodic,
//
//   G_i = -(F_{i+1/2} - F_{i-1/2}) / h,
//   F_{i+1/2} = E(u_i, u_{i+1}) - nu_{i+1/2} (u_{i+1} - u_i) / h,      nu_{i+1/2} = (nu_i + nu_{i+1}) / 2,
//   E(a, b) = max(a, 0)^2 / 2 + min(b, 0)^2 / 2                         (Engquist-Osher).
//
// The Engquist-Osher flux is monotone (no new extrema at shocks, the entropy solution in the limit)
// and continuously differentiable, so gradients through a shock are exact derivatives of the
// discrete solution and Taylor tests see second-order remainders. The viscosity nu is a parameter:
// one scalar (-burgers_nu_field 0) or one value per grid point (-burgers_nu_field 1).
//
// Initial condition (-burgers_ic): "sine" u0 = A sin(2 pi (x - x0)/L) + B, which steepens into a
// shock at t = L / (2 pi A) when nu is small; "square" u0 = A on [xc - w/2, xc + w/2), B elsewhere,
// a shock and a rarefaction from the start; "random" a sum of -burgers_ic_modes sines with random
// amplitudes and phases drawn from -burgers_ic_seed (random_start.hpp: the same function of x as the
// learned_burgers model's, for reference solutions). A = -burgers_ic_amplitude, B = -burgers_ic_offset.
//
// The model states the face flux F (flux() below) and the divergence's weights (-1 at i - 1/2, +1 at
// i + 1/2); everything else (G, dG/du, dG/dnu, their transposes, the assembled Jacobian for implicit
// integrators, the fused adjoint sweeps) is derived from them by the pointwise layer.
//
//   mpiexec -n 2 ./flexipde -model burgers -task gradient -burgers_nu 0.01 -true_burgers_nu 0.02 -check_fd
//   mpiexec -n 2 ./flexipde -model burgers -task taylor -burgers_nu_field 1 -burgers_nu 0.01 -ts_type cn
//   mpiexec -n 2 ./flexipde -model burgers -task invert -burgers_nu_field 1 -burgers_nu 0.02
//           -true_burgers_nu_profile gaussian -true_burgers_nu 0.01 -true_burgers_nu_bump 0.01 -tao_monitor
//   (one command line)
#include "flexipde/pointwise.hpp"
#include "flexipde/random_start.hpp"

namespace flexipde {

class Burgers {
public:
  static constexpr int dim = 1, components = 1, radius = 1, parameters = 1;
  enum Parameter { nu = 0 };

  const char *name() const { return "burgers"; }
  const char *component_name(int) const { return "u"; }
  void grid_defaults(GridOptions &o) const {
    o.n = 128;
    o.periodic = PETSC_TRUE;
  }

  PetscErrorCode setup(const Grid &grid, Declarations &decl) {
    const char *ics[] = {"sine", "square", "random"};
    PetscBool nu_field = PETSC_FALSE;
    PetscFunctionBeginUser;
    PetscOptionsBegin(grid.comm(), nullptr, "Viscous Burgers u_t + (u^2/2)_x = (nu u_x)_x", "Burgers");
    PetscCall(PetscOptionsBool("-burgers_nu_field", "Viscosity nu is a field (one value per grid point), else one scalar",
                               "Burgers", nu_field, &nu_field, nullptr));
    PetscCall(PetscOptionsEList("-burgers_ic", "Initial condition", "Burgers", ics, 3, ics[ic_], &ic_, nullptr));
    PetscCall(PetscOptionsReal("-burgers_ic_amplitude", "Amplitude A of the start", "Burgers", amplitude_, &amplitude_, nullptr));
    PetscCall(PetscOptionsReal("-burgers_ic_offset", "Offset B added to the start", "Burgers", offset_, &offset_, nullptr));
    PetscCall(PetscOptionsReal("-burgers_ic_center", "Square start: centre xc", "Burgers", center_, &center_, nullptr));
    PetscCall(PetscOptionsReal("-burgers_ic_width", "Square start: width w", "Burgers", width_, &width_, nullptr));
    PetscCall(PetscOptionsInt("-burgers_ic_seed", "Random start: seed", "Burgers", seed_, &seed_, nullptr));
    PetscCall(PetscOptionsInt("-burgers_ic_modes", "Random start: number of sine modes", "Burgers", modes_, &modes_, nullptr));
    PetscOptionsEnd();
    PetscCheck(modes_ > 0, grid.comm(), PETSC_ERR_ARG_OUTOFRANGE, "-burgers_ic_modes must be positive");
    random_.make((unsigned)seed_, (int)modes_, amplitude_, offset_, grid.x1() - grid.x0());
    PetscCheck(grid.periodic(), grid.comm(), PETSC_ERR_ARG_WRONG, "burgers: the grid must be periodic (-grid_periodic 1)");
    x0_ = grid.x0(), length_ = grid.x1() - grid.x0();
    decl.parameter(nu, "burgers_nu", nu_field, 0.0, 0.01);
    PetscFunctionReturn(0);
  }

  // h (div F)_i = F_{i+1/2} - F_{i-1/2}: the weights of the faces i - 1/2 and i + 1/2.
  static constexpr std::array<double, 2> divergence() { return {-1.0, 1.0}; }

  // F at the face i + 1/2 (pt at i).
  template <class P, int d> void flux(const P &pt, Direction<d>, typename P::Number *F) const {
    using T = typename P::Number;
    const T u0 = pt.u(0, 0), u1 = pt.u(0, 1);
    const T nu_face = 0.5 * (pt.param(nu, 0) + pt.param(nu, 1));
    F[0] = engquist_osher(u0, u1) - nu_face * (u1 - u0) * pt.inv_h();
  }

  template <class P> void initial(const P &pt, typename P::Number *u) const {
    const double x = pt.x();
    if (ic_ == 0) u[0] = amplitude_ * std::sin(2 * PETSC_PI * (x - x0_) / length_) + offset_;
    else if (ic_ == 1) u[0] = std::fabs(x - center_) * 2 < width_ ? amplitude_ + offset_ : offset_;
    else u[0] = random_(x);
  }

  PetscErrorCode check_parameters(const ParameterBounds &b, MPI_Comm comm) const {
    PetscFunctionBeginUser;
    PetscCheck(b.min[nu] >= 0, comm, PETSC_ERR_ARG_OUTOFRANGE, "Viscosity must be non-negative, found nu = %g",
               (double)b.min[nu]);
    PetscFunctionReturn(0);
  }

private:
  template <class T> static T engquist_osher(const T &a, const T &b) {
    return 0.5 * sqr(max(a, T(0.0))) + 0.5 * sqr(min(b, T(0.0)));
  }

  PetscInt ic_ = 0, seed_ = 1, modes_ = 3;
  RandomStart random_;
  PetscReal amplitude_ = 1.0, offset_ = 0.0, center_ = 0.3, width_ = 0.3;
  PetscReal x0_ = 0, length_ = 1;
};

FLEXIPDE_REGISTER_MODEL("burgers", PointwiseModel<Burgers>);

} // namespace flexipde
