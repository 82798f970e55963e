// Models that exist to exercise the pointwise layer's non-local couplings; registered in the test
// binary only, so the conformance test (test_conformance.cpp) checks them like every model:
//
//   u_t = -a (u_{i+1} - u_{i-1}) / 2h + B h,     a = L u,   h_i = k_i u_i^2,   x periodic,
//
// with L and B the cyclic shift (S u)_i = u_{(i + N/3) mod N}: a coupling to a point a third of the
// domain away, across ranks, whose transpose (the shift back) differs from itself. k is the
// parameter (scalar or field). The model states G at a point and its two maps with their
// transposes; the layer derives every product, and the conformance test compares them with
// differences of G.
#include "flexipde/pointwise.hpp"

namespace flexipde {

// The cyclic shift (S u)_i = u_{(i + N/3) mod N} of a periodic 1D grid, across ranks.
class CyclicShift {
public:
  static void grid_defaults(GridOptions &o) { // a small periodic grid
    o.n = 24;
    o.periodic = PETSC_TRUE;
  }
  PetscErrorCode setup(const Grid &grid) {
    OwnedVec v;
    OwnedIS from, to;
    PetscFunctionBeginUser;
    const PetscInt n = grid.n(), xs = grid.xs(), xm = grid.xm();
    std::vector<PetscInt> src(xm), dst(xm);
    for (PetscInt i = 0; i < xm; ++i) src[i] = (xs + i + n / 3) % n, dst[i] = xs + i;
    PetscCall(DMCreateGlobalVector(grid.dm(), v.out()));
    PetscCall(ISCreateGeneral(grid.comm(), xm, src.data(), PETSC_COPY_VALUES, from.out()));
    PetscCall(ISCreateGeneral(grid.comm(), xm, dst.data(), PETSC_COPY_VALUES, to.out()));
    PetscCall(VecScatterCreate(v, from, v, to, scatter_.out()));
    PetscFunctionReturn(0);
  }
  // out (+)= S in, or S^T in if reverse.
  PetscErrorCode apply(Vec in, Vec out, bool reverse, bool add) const {
    PetscFunctionBeginUser;
    if (!add) PetscCall(VecSet(out, 0.0));
    const ScatterMode mode = reverse ? SCATTER_REVERSE : SCATTER_FORWARD;
    PetscCall(VecScatterBegin(scatter_, in, out, ADD_VALUES, mode));
    PetscCall(VecScatterEnd(scatter_, in, out, ADD_VALUES, mode));
    PetscFunctionReturn(0);
  }

private:
  OwnedScatter scatter_;
};

class NonlocalTestModel {
public:
  static constexpr int dim = 1, components = 1, radius = 1, parameters = 1;
  static constexpr int auxiliaries = 1, outputs = 1;

  const char *name() const { return "nonlocal_test"; }
  const char *component_name(int) const { return "u"; }
  void grid_defaults(GridOptions &o) const { CyclicShift::grid_defaults(o); }

  PetscErrorCode setup(const Grid &grid, Declarations &decl) {
    PetscBool field = PETSC_FALSE;
    PetscFunctionBeginUser;
    PetscCall(PetscOptionsGetBool(nullptr, nullptr, "-nonlocal_test_k_field", &field, nullptr));
    PetscCheck(grid.periodic(), grid.comm(), PETSC_ERR_ARG_WRONG, "nonlocal_test: the grid must be periodic");
    decl.parameter(0, "nonlocal_test_k", field, PETSC_NINFINITY, 0.5);
    PetscCall(shift_.setup(grid));
    PetscFunctionReturn(0);
  }

  template <class P> void rhs(const P &pt, typename P::Number *g) const {
    g[0] = -pt.aux(0) * (pt.u(0, 1) - pt.u(0, -1)) * (0.5 * pt.inv_h());
    g[1] = pt.param(0) * sqr(pt.u(0, 0)); // h, entering G through B
  }
  template <class P> void initial(const P &pt, typename P::Number *u) const { u[0] = std::sin(2 * PETSC_PI * pt.x()) + 0.5; }

  // a = L u, the transpose's y += L^T z; G += B h, B^T x.
  PetscErrorCode auxiliary(int, Vec U, Vec a) const { return shift_.apply(U, a, false, false); }
  PetscErrorCode auxiliary_transpose(int, Vec z, Vec y) const { return shift_.apply(z, y, true, true); }
  PetscErrorCode output(int, Vec h, Vec G) const { return shift_.apply(h, G, false, true); }
  PetscErrorCode output_transpose(int, Vec x, Vec hx) const { return shift_.apply(x, hx, true, false); }

  PetscErrorCode spectrum(const ParameterBounds &, Spectrum *s) const {
    s->imag_radius = s->real_radius = 100; // the test's steps are far below any limit
    return 0;
  }

private:
  CyclicShift shift_;
};

FLEXIPDE_REGISTER_MODEL("nonlocal_test", PointwiseModel<NonlocalTestModel>);

// A linear model whose non-local maps enter G with coefficients: the layer's uniform coupling when
// they are the same at every point (k scalar, Varying false), else its general path:
//
//   u_t = -b (u_{i+1} - u_{i-1}) / 2h + k a_0 + w(x) a_1,   a_0 = S u,  a_1 = S^T u,
//   w = 1, or 1 + sin(2 pi x) / 2 (Varying),
//
// S the cyclic shift; b a scalar, k a scalar or a field. The maps are stated at once,
// with the transposes of both applied to one x (auxiliary_fields_adjoint).
template <bool Varying>
class CoupledTestModel {
public:
  static constexpr int dim = 1, components = 1, radius = 1, parameters = 2;
  static constexpr int auxiliaries = 2;
  static constexpr bool linear = true;

  const char *name() const { return Varying ? "coupled_test_varying" : "coupled_test"; }
  const char *component_name(int) const { return "u"; }
  void grid_defaults(GridOptions &o) const { CyclicShift::grid_defaults(o); }

  PetscErrorCode setup(const Grid &grid, Declarations &decl) {
    PetscBool field = PETSC_FALSE;
    PetscFunctionBeginUser;
    const std::string prefix = std::string("-") + name();
    PetscCall(PetscOptionsGetBool(nullptr, nullptr, (prefix + "_k_field").c_str(), &field, nullptr));
    PetscCheck(grid.periodic(), grid.comm(), PETSC_ERR_ARG_WRONG, "%s: the grid must be periodic", name());
    decl.parameter(0, std::string(name()) + "_b", false, PETSC_NINFINITY, 0.7);
    decl.parameter(1, std::string(name()) + "_k", field, PETSC_NINFINITY, 0.5);
    PetscCall(shift_.setup(grid));
    PetscFunctionReturn(0);
  }

  template <class P> void rhs(const P &pt, typename P::Number *g) const {
    const double w = Varying ? 1 + 0.5 * std::sin(2 * PETSC_PI * pt.x()) : 1.0;
    g[0] = -pt.param(0) * (pt.u(0, 1) - pt.u(0, -1)) * (0.5 * pt.inv_h()) + pt.param(1) * pt.aux(0) + w * pt.aux(1);
  }
  template <class P> void initial(const P &pt, typename P::Number *u) const { u[0] = std::sin(2 * PETSC_PI * pt.x()) + 0.5; }

  // a_0 = S U, a_1 = S^T U; y += S^T z_0 + S z_1; w_0 = S^T x, w_1 = S x.
  PetscErrorCode auxiliary_fields(Vec U, const Vec *a) const {
    PetscFunctionBeginUser;
    PetscCall(shift_.apply(U, a[0], false, false));
    PetscCall(shift_.apply(U, a[1], true, false));
    PetscFunctionReturn(0);
  }
  PetscErrorCode auxiliary_fields_transpose(const Vec *z, Vec y) const {
    PetscFunctionBeginUser;
    PetscCall(shift_.apply(z[0], y, true, true));
    PetscCall(shift_.apply(z[1], y, false, true));
    PetscFunctionReturn(0);
  }
  PetscErrorCode auxiliary_fields_adjoint(Vec x, const Vec *w) const {
    PetscFunctionBeginUser;
    PetscCall(shift_.apply(x, w[0], true, false));
    PetscCall(shift_.apply(x, w[1], false, false));
    PetscFunctionReturn(0);
  }

  PetscErrorCode spectrum(const ParameterBounds &, Spectrum *s) const {
    s->imag_radius = s->real_radius = 100; // the test's steps are far below any limit
    return 0;
  }

private:
  CyclicShift shift_;
};

FLEXIPDE_REGISTER_MODEL("coupled_test", PointwiseModel<CoupledTestModel<false>>);
FLEXIPDE_REGISTER_MODEL("coupled_test_varying", PointwiseModel<CoupledTestModel<true>>);

} // namespace flexipde
