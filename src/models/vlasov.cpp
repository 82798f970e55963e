// Vlasov-Poisson for electrons (charge -1, mass 1; time in 1/omega_p, length in Debye lengths) on a
// neutralising ion background of density 1, 1D in x and 1D in velocity v:
//
//   f_t + v f_x - E f_v = 0,     E_x = 1 - rho,   rho(x) = int f dv,   int E dx = 0,
//
// on the phase-space grid (x, v): x periodic on [0, L), v in [-v_max, v_max] (the grid's y direction,
// end points included), f = 0 beyond it. At every grid point (i, j):
//   G(f) = -v_j D_x f + E_i(f) D_v f  [- c (|v_j| / 12h d_x^4 f + E_cfl / 12hv Q f)]
//   D_x  centred fourth order, periodic: (f_{i-2} - 8 f_{i-1} + 8 f_{i+1} - f_{i+2}) / 12h;
//   D_v  conservative flux form (F_{j+1/2} - F_{j-1/2}) / hv, faces F_{j+1/2} = (-f_{j-1} + 7 f_j
//        + 7 f_{j+1} - f_{j+2}) / 12, no flux through the two outer faces: the centred stencil away
//        from the end rows (f = 0 beyond them); its columns sum to 0, so the mass is conserved to round-off;
//   E = -hv K S f  (the auxiliary field, a function of x alone): S sums over v, K is the spectral
//        zero-mean antiderivative, (K s)^_m = s^_m / (i kappa_m) for 0 < |m| < N_x/2 and 0 for the mean
//        and the Nyquist mode (E = K(1 - rho) = -K rho as K 1 = 0); the layer forms S f and reads E(x_i)
//        at every v_j, and its transpose with (-hv K)^T = hv K (K^T = -K);
//   the optional dissipation (-vlasov_dissipation c): d_x^4 the periodic fourth difference, Q = (B^T B)^2
//        with B^T B the second difference without flux through the velocity bounds; symmetric, negative
//        semi-definite, mass-conserving; c = 1 makes the x advection third-order upwind-biased.
// The pointwise layer (pointwise.hpp) derives dG/dU (a shell), its transpose, dU0/dp and the adjoint
// sweeps from rhs() and initial().
//
// f0 = (1 + alpha cos(k x)) F(v), k = 2 pi m / L (-vlasov_mode m), M(u; s) = exp(-u^2 / 2s^2) / (sqrt(2 pi) s):
//   -vlasov_ic landau      F = M(v; vt)                                     (k 0.5, alpha 0.01, v_max 6)
//   -vlasov_ic two_stream  F = [M(v - v0; vt) + M(v + v0; vt sqrt(r))] / 2  (k 0.2, alpha 1e-3, v0 2.4, v_max 8)
// with the scalar parameters vlasov_alpha, vlasov_vt, vlasov_v0, vlasov_temperature_ratio (r). -vlasov_k
// and -vlasov_vmax set the default domain [0, 2 pi / k) x [-v_max, v_max].
// Functionals: field_energy 0.5 h sum E^2, mass, momentum, kinetic_energy (cell sums of f, v f, v^2 f / 2),
// energy (kinetic + field), l2. Explicit stability: the spectrum lies in i [-R, R], R = 1.372 (v_max / h +
// E_max / hv), E_max the larger of max|E(f0)| and -vlasov_E_cfl; with dissipation, sampled symbols.
//
//   mpiexec --allow-run-as-root --oversubscribe -n 2 ./flexipde -model vlasov -task forward
//           -da_grid_x 64 -da_grid_y 128 -ts_dt 0.05 -ts_max_time 10                           (one line)
//   mpiexec --allow-run-as-root --oversubscribe -n 2 ./flexipde -model vlasov -vlasov_ic two_stream
//           -task taylor -da_grid_x 32 -da_grid_y 64 -ts_dt 0.1 -ts_max_time 5
//           -objective_type functional -objective_functional field_energy                       (one line)
//   mpiexec --allow-run-as-root --oversubscribe -n 2 ./flexipde -model vlasov -vlasov_ic two_stream
//           -task gradient -da_grid_x 32 -da_grid_y 64 -ts_type cn -ts_dt 0.1 -ts_max_time 5
//           -objective_type functional_integral -vlasov_dissipation 1 -check_fd                  (one line)
#include "flexipde/pointwise.hpp"
#include <algorithm>
#include <complex>
#include <cstring>
#include <fftw3.h>
#include <memory>

namespace flexipde {
namespace {

const char *const ic_names[] = {"landau", "two_stream"};
enum InitialCondition : PetscInt { landau = 0, two_stream = 1 };
struct IcDefaults {
  PetscReal k, alpha, vt, v0, ratio, vmax;
};
constexpr IcDefaults ic_defaults[2] = {{0.5, 0.01, 1.0, 0.0, 1.0, 6.0}, {0.2, 1e-3, 1.0, 2.4, 1.0, 8.0}};

PetscInt read_ic() {
  PetscInt ic = landau;
  (void)PetscOptionsGetEList(nullptr, nullptr, "-vlasov_ic", ic_names, 2, &ic, nullptr);
  return ic;
}

// K on all N_x points by a serial real FFT, the same on every rank: N_x is small next to the phase
// space, and a distributed transform would cost more in communication than this in arithmetic.
class Antiderivative {
public:
  Antiderivative() = default;
  Antiderivative(const Antiderivative &) = delete; // owns its plans
  Antiderivative &operator=(const Antiderivative &) = delete;
  void setup(PetscInt n, PetscReal length) {
    in_.assign(n, 0.0), out_.assign(n / 2 + 1, 0.0), inv_kappa_.assign(n / 2 + 1, 0.0);
    auto *c = reinterpret_cast<fftw_complex *>(out_.data());
    forward_ = fftw_plan_dft_r2c_1d((int)n, in_.data(), c, FFTW_ESTIMATE);
    backward_ = fftw_plan_dft_c2r_1d((int)n, c, in_.data(), FFTW_ESTIMATE);
    for (PetscInt m = 1; 2 * m < n; ++m) inv_kappa_[m] = length / (2 * PETSC_PI * m) / n; // and FFTW's 1/n
  }
  void apply(std::vector<PetscReal> &s) const { // s = K s: s^_m / (i kappa_m)
    std::copy(s.begin(), s.end(), in_.begin());
    fftw_execute(forward_);
    for (size_t m = 0; m < out_.size(); ++m) out_[m] *= std::complex<double>(0, -inv_kappa_[m]);
    fftw_execute(backward_);
    std::copy(in_.begin(), in_.end(), s.begin());
  }
  ~Antiderivative() {
    if (forward_) fftw_destroy_plan(forward_), fftw_destroy_plan(backward_);
  }

private:
  mutable std::vector<double> in_;
  mutable std::vector<std::complex<double>> out_;
  std::vector<PetscReal> inv_kappa_;
  fftw_plan forward_ = nullptr, backward_ = nullptr;
};

} // namespace

// Dissipative: the dissipation term is there (a compile-time constant of the sweeps: no branch in
// their loops; -vlasov_dissipation picks the instance).
template <bool Dissipative> class Vlasov {
public:
  static constexpr int dim = 2, components = 1, radius = 2, parameters = 4, auxiliaries = 1;
  static constexpr bool auxiliaries_from_column_sums = true; // E(x) from rho(x) = hv sum_j f(x, v_j)
  static constexpr int rhs_parameters = 0; // the parameters shape f0 alone
  enum Parameter { alpha, vt, v0, ratio };

  const char *name() const { return "vlasov"; }
  const char *component_name(int) const { return "f"; }
  void grid_defaults(GridOptions &g) const {
    const IcDefaults &d = ic_defaults[read_ic()];
    PetscReal k = d.k, vmax = d.vmax;
    (void)PetscOptionsGetReal(nullptr, nullptr, "-vlasov_k", &k, nullptr);
    (void)PetscOptionsGetReal(nullptr, nullptr, "-vlasov_vmax", &vmax, nullptr);
    g.periodic = PETSC_TRUE, g.periodic_y = PETSC_FALSE;
    g.n = 64, g.ny = 128;
    g.x0 = 0, g.x1 = k > 0 ? 2 * PETSC_PI / k : 1.0; // setup reports a bad k
    g.y0 = -vmax, g.y1 = vmax;
  }

  PetscErrorCode setup(const Grid &grid, Declarations &decl) {
    PetscFunctionBeginUser;
    ic_ = read_ic();
    const IcDefaults &d = ic_defaults[ic_];
    PetscReal k = d.k, vmax = d.vmax;
    PetscOptionsBegin(grid.comm(), nullptr, "Vlasov-Poisson model f_t + v f_x - E f_v = 0, E_x = 1 - int f dv", "Vlasov");
    PetscCall(PetscOptionsEList("-vlasov_ic", "Initial distribution: landau (one Maxwellian) or two_stream (two beams)",
                                "Vlasov", ic_names, 2, ic_names[ic_], &ic_, nullptr));
    PetscCall(PetscOptionsReal("-vlasov_k", "Perturbation wavenumber: sets the default domain length 2 pi / k", "Vlasov", k, &k, nullptr));
    PetscCall(PetscOptionsReal("-vlasov_vmax", "Velocity bound: sets the default -grid_y0 -vmax, -grid_y1 vmax", "Vlasov", vmax, &vmax, nullptr));
    PetscCall(PetscOptionsInt("-vlasov_mode", "Number m of perturbation periods in the domain (k = 2 pi m / L)", "Vlasov", mode_, &mode_, nullptr));
    PetscCall(PetscOptionsReal("-vlasov_dissipation", "Strength c of the fourth-difference dissipation (0: none; 1: third-order upwind-biased in x)",
                               "Vlasov", dissipation_, &dissipation_, nullptr));
    PetscCall(PetscOptionsReal("-vlasov_E_cfl", "Largest |E| the explicit stability check assumes (with max|E| at t = 0)", "Vlasov", E_cfl_, &E_cfl_, nullptr));
    PetscOptionsEnd();
    PetscCheck(grid.dim() == 2, grid.comm(), PETSC_ERR_ARG_WRONG, "Model vlasov needs a 2D phase-space grid");
    PetscCheck(k > 0, grid.comm(), PETSC_ERR_ARG_OUTOFRANGE, "-vlasov_k must be positive, got %g", (double)k);
    PetscCheck(vmax > 0, grid.comm(), PETSC_ERR_ARG_OUTOFRANGE, "-vlasov_vmax must be positive, got %g", (double)vmax);
    PetscCheck(dissipation_ >= 0, grid.comm(), PETSC_ERR_ARG_OUTOFRANGE, "-vlasov_dissipation must be non-negative, got %g", (double)dissipation_);
    PetscCheck(mode_ >= 1, grid.comm(), PETSC_ERR_ARG_OUTOFRANGE, "-vlasov_mode must be at least 1, got %" PetscInt_FMT, mode_);
    PetscCheck(grid.periodic() && !grid.periodic_y(), grid.comm(), PETSC_ERR_ARG_WRONG,
               "Model vlasov needs x periodic (-grid_periodic 1) and v not periodic (-grid_periodic_y 0)");
    grid_ = &grid;
    k_ = 2 * PETSC_PI * mode_ / (grid.x1() - grid.x0());
    cx_ = 1 / (12 * grid.h()), cv_ = 1 / (12 * grid.hy());
    decl.parameter(alpha, "vlasov_alpha", false, PETSC_NINFINITY, d.alpha);
    decl.parameter(vt, "vlasov_vt", false, 0.0, d.vt);
    if (ic_ == two_stream) {
      decl.parameter(v0, "vlasov_v0", false, PETSC_NINFINITY, d.v0);
      decl.parameter(ratio, "vlasov_temperature_ratio", false, 0.0, d.ratio);
    } else decl.fixed(v0, d.v0), decl.fixed(ratio, d.ratio);
    auto K = std::make_shared<Antiderivative>();
    K->setup(grid.n(), grid.x1() - grid.x0());
    K_ = K;
    column_ = std::make_shared<std::vector<PetscReal>>(grid.n(), 0.0);
    PetscFunctionReturn(0);
  }

  template <class P> void rhs(const P &pt, typename P::Number *g) const {
    const double v = pt.x(1);
    g[0] = -v * dx(pt) + pt.aux(0) * dv(pt);
    if constexpr (Dissipative) g[0] -= dissipation_ * (std::fabs(v) * cx_ * d4x(pt) + E_cfl_ * cv_ * q(pt));
  }
  template <class P> void initial(const P &pt, typename P::Number *f) const {
    f[0] = (1.0 + pt.param(alpha) * std::cos(k_ * pt.x(0))) * profile(pt.x(1), pt.param(vt), pt.param(v0), pt.param(ratio));
  }
  PetscErrorCode check_parameters(const ParameterBounds &b, MPI_Comm comm) const {
    PetscFunctionBeginUser;
    PetscCheck(b.min[vt] > 0, comm, PETSC_ERR_ARG_OUTOFRANGE, "vlasov_vt (thermal spread) must be positive, got %g", (double)b.min[vt]);
    PetscCheck(b.min[ratio] > 0, comm, PETSC_ERR_ARG_OUTOFRANGE, "vlasov_temperature_ratio must be positive, got %g", (double)b.min[ratio]);
    PetscFunctionReturn(0);
  }

  // E = -hv K s from the column sums s = S f (the layer sums f over v and reads E(x) at every v), and
  // the transpose's w += (-hv K)^T z = hv K z.
  PetscErrorCode auxiliary(int, const PetscReal *s, PetscReal *E) const {
    std::transform(s, s + grid_->n(), column_->begin(), [&](PetscReal r) { return -grid_->hy() * r; });
    K_->apply(*column_);
    std::copy(column_->begin(), column_->end(), E);
    return 0;
  }
  PetscErrorCode auxiliary_transpose(int, const PetscReal *z, PetscReal *w) const {
    std::transform(z, z + grid_->n(), column_->begin(), [&](PetscReal r) { return grid_->hy() * r; });
    K_->apply(*column_);
    for (PetscInt i = 0; i < grid_->n(); ++i) w[i] += (*column_)[i];
    return 0;
  }

  std::string functional_names() const { return "field_energy, mass, momentum, kinetic_energy, energy, l2"; }
  // F(f) and dF/df: the moments cell sum m(v) f, the field energy W = 0.5 h sum E^2 (dW/df = h hv R K E),
  // and the L2 norm.
  PetscErrorCode functional(const char *fname, Vec f, PetscReal *value, Vec dFdU) const {
    enum { field_energy, mass, momentum, kinetic_energy, energy, l2, none };
    const char *names[] = {"field_energy", "mass", "momentum", "kinetic_energy", "energy", "l2"};
    int which = field_energy;
    while (which < none && std::strcmp(fname, names[which])) ++which;
    PetscFunctionBeginUser;
    PetscCheck(which != none, grid_->comm(), PETSC_ERR_ARG_WRONG, "Model vlasov has no functional '%s': choose one of %s",
               fname, functional_names().c_str());
    const Grid &g = *grid_;
    const PetscReal cell = g.h() * g.hy();
    const bool with_field = which == field_energy || which == energy;
    PetscReal W = 0, local[2] = {0, 0}; // cell sum m(v) f, cell sum f^2
    if (with_field) {
      PetscCall(field(f));
      for (PetscReal e : (*column_)) W += 0.5 * g.h() * e * e;
      K_->apply(*column_); // K E
    }
    auto moment = [&](PetscReal v) { return which == mass ? 1.0 : which == momentum ? v : which == field_energy ? 0.0 : 0.5 * v * v; };
    const PetscScalar *u;
    PetscScalar *d = nullptr;
    PetscCall(VecGetArrayRead(f, &u));
    if (dFdU) PetscCall(VecGetArray(dFdU, &d));
    for (PetscInt jl = 0, n = 0; jl < g.ym(); ++jl)
      for (PetscInt i = g.xs(); i < g.xs() + g.xm(); ++i, ++n) {
        const PetscReal m = moment(g.y(g.ys() + jl)), fv = PetscRealPart(u[n]);
        local[0] += cell * m * fv, local[1] += cell * fv * fv;
        if (d) d[n] = cell * m + (with_field ? cell * (*column_)[i] : 0.0);
      }
    PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, local, 2, MPIU_REAL, MPI_SUM, g.comm()));
    const PetscReal norm = std::sqrt(local[1]);
    if (value) *value = which == l2 ? norm : local[0] + W;
    for (PetscInt n = 0; d && which == l2 && n < g.local_points(); ++n) d[n] = norm > 0 ? cell * PetscRealPart(u[n]) / norm : 0.0;
    if (dFdU) PetscCall(VecRestoreArray(dFdU, &d));
    PetscCall(VecRestoreArrayRead(f, &u));
    PetscFunctionReturn(0);
  }

  // The symbols of D_x and D_v at the largest |v| and |E| (E_max: max|E(f0)| at these parameters, or E_cfl).
  PetscErrorCode spectrum(const ParameterBounds &b, Spectrum *s) const {
    const Grid &g = *grid_;
    PetscFunctionBeginUser;
    PetscReal F = 0; // S f0 = (1 + alpha cos k x) sum_j F(v_j)
    for (PetscInt j = 0; j < g.ny(); ++j) F += profile(g.y(j), b.min[vt], b.min[v0], b.min[ratio]);
    for (PetscInt i = 0; i < g.n(); ++i) (*column_)[i] = -g.hy() * (1 + b.min[alpha] * std::cos(k_ * g.x(i))) * F;
    K_->apply(*column_); // E(f0) = -hv K S f0
    PetscReal Emax = E_cfl_, symbol = 0;
    for (PetscReal e : (*column_)) Emax = std::max(Emax, std::fabs(e));
    for (PetscInt q = 0; q <= 1000; ++q) symbol = std::max(symbol, sym(PETSC_PI * q / 1000));
    const PetscReal vmax = std::max(std::fabs(g.y0()), std::fabs(g.y1())), ax = vmax / g.h(), av = Emax / g.hy();
    s->imag_radius = symbol * (ax + av), s->real_radius = 0;
    s->samples.clear();
    for (int a = 0; dissipation_ > 0 && a <= 48; ++a)
      for (int c = 0; c <= 48; ++c) {
        const PetscReal tx = PETSC_PI * a / 48, tv = PETSC_PI * c / 48;
        const PetscReal re = -dissipation_ / 12 * (ax * sqr(2 - 2 * std::cos(tx)) + av * sqr(2 - 2 * std::cos(tv)));
        s->samples.emplace_back(re, ax * sym(tx) + av * sym(tv));
        s->samples.emplace_back(re, -ax * sym(tx) - av * sym(tv));
      }
    PetscFunctionReturn(0);
  }

private:
  template <class P> auto dx(const P &pt) const { return (pt.u(0, -2) - 8.0 * pt.u(0, -1) + 8.0 * pt.u(0, 1) - pt.u(0, 2)) * cx_; }
  template <class P> auto face(const P &pt, int o) const { // 12 F_{j+o+1/2}
    return -pt.u(0, 0, o - 1) + 7.0 * pt.u(0, 0, o) + 7.0 * pt.u(0, 0, o + 1) - pt.u(0, 0, o + 2);
  }
  template <class P> auto dv(const P &pt) const {
    if (pt.wall(1, 0)) return face(pt, 0) * cv_;
    if (pt.wall(1, 1)) return -face(pt, -1) * cv_;
    return (pt.u(0, 0, -2) - 8.0 * pt.u(0, 0, -1) + 8.0 * pt.u(0, 0, 1) - pt.u(0, 0, 2)) * cv_;
  }
  template <class P> auto d4x(const P &pt) const {
    return pt.u(0, -2) - 4.0 * pt.u(0, -1) + 6.0 * pt.u(0, 0) - 4.0 * pt.u(0, 1) + pt.u(0, 2);
  }
  // (B^T B f) at row j + o, and Q f = (B^T B)^2 f: differences between rows, none through the bounds.
  template <class P> auto lap(const P &pt, int o) const {
    const PetscInt j = pt.index(1) + o;
    typename P::Number s(0.0);
    if (j > 0) s += pt.u(0, 0, o - 1) - pt.u(0, 0, o);
    if (j < pt.points(1) - 1) s += pt.u(0, 0, o + 1) - pt.u(0, 0, o);
    return s;
  }
  template <class P> auto q(const P &pt) const {
    return (pt.index(1) > 0 ? lap(pt, -1) - lap(pt, 0) : 0.0) + (pt.index(1) < pt.points(1) - 1 ? lap(pt, 1) - lap(pt, 0) : 0.0);
  }
  static PetscReal sym(PetscReal th) { return (8 * std::sin(th) - std::sin(2 * th)) / 6; } // of 12 h D_x
  template <class T> static T maxwellian(const T &u, const T &s) { return exp(-0.5 * u * u / (s * s)) / (std::sqrt(2 * PETSC_PI) * s); }
  template <class T> T profile(double v, const T &vt, const T &v0, const T &r) const {
    if (ic_ == landau) return maxwellian(T(v), vt);
    return 0.5 * (maxwellian(v - v0, vt) + maxwellian(v + v0, vt * sqrt(r)));
  }

  // column_ = S in over all x (the sum over v across the ranks of a column; collective).
  PetscErrorCode column_sums(Vec in) const {
    const Grid &g = *grid_;
    const PetscScalar *u;
    PetscFunctionBeginUser;
    std::fill(column_->begin(), column_->end(), 0.0);
    PetscCall(VecGetArrayRead(in, &u));
    for (PetscInt jl = 0, n = 0; jl < g.ym(); ++jl)
      for (PetscInt i = g.xs(); i < g.xs() + g.xm(); ++i) (*column_)[i] += PetscRealPart(u[n++]);
    PetscCall(VecRestoreArrayRead(in, &u));
    PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, column_->data(), (PetscMPIInt)g.n(), MPIU_REAL, MPI_SUM, g.comm()));
    PetscFunctionReturn(0);
  }
  PetscErrorCode field(Vec f) const { // column_ = E(f) = -hv K S f
    PetscFunctionBeginUser;
    PetscCall(column_sums(f));
    for (PetscReal &r : (*column_)) r *= -grid_->hy();
    K_->apply(*column_);
    PetscFunctionReturn(0);
  }

  const Grid *grid_ = nullptr;
  PetscInt ic_ = landau, mode_ = 1;
  PetscReal k_ = 0.5, cx_ = 1, cv_ = 1, dissipation_ = 0, E_cfl_ = 1;
  std::shared_ptr<const Antiderivative> K_; // shared by the copies of the model the sweeps make
  // a length-N_x work array (S f, E, K E), shared by the copies of the model the sweeps make
  std::shared_ptr<std::vector<PetscReal>> column_;
};

std::unique_ptr<Model> make_vlasov() {
  PetscReal c = 0;
  (void)PetscOptionsGetReal(nullptr, nullptr, "-vlasov_dissipation", &c, nullptr);
  if (c > 0) return std::make_unique<PointwiseModel<Vlasov<true>>>();
  return std::make_unique<PointwiseModel<Vlasov<false>>>(); // (a negative c is refused at setup)
}

static const ModelRegistration vlasov("vlasov", make_vlasov);

} // namespace flexipde
