// A model that exists to exercise the pointwise layer's non-local couplings; registered in the test
// binary only, so the conformance test (test_conformance.cpp) checks it like every model:
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

class NonlocalTestModel {
public:
  static constexpr int dim = 1, components = 1, radius = 1, parameters = 1;
  static constexpr int auxiliaries = 1, outputs = 1;

  const char *name() const { return "nonlocal_test"; }
  const char *component_name(int) const { return "u"; }
  void grid_defaults(GridOptions &o) const {
    o.n = 24;
    o.periodic = PETSC_TRUE;
  }

  PetscErrorCode setup(const Grid &grid, Declarations &decl) {
    PetscBool field = PETSC_FALSE;
    OwnedVec v;
    OwnedIS from, to;
    PetscFunctionBeginUser;
    PetscCall(PetscOptionsGetBool(nullptr, nullptr, "-nonlocal_test_k_field", &field, nullptr));
    PetscCheck(grid.periodic(), grid.comm(), PETSC_ERR_ARG_WRONG, "nonlocal_test: the grid must be periodic");
    decl.parameter(0, "nonlocal_test_k", field, PETSC_NINFINITY, 0.5);
    const PetscInt n = grid.n(), xs = grid.xs(), xm = grid.xm();
    std::vector<PetscInt> src(xm), dst(xm);
    for (PetscInt i = 0; i < xm; ++i) src[i] = (xs + i + n / 3) % n, dst[i] = xs + i;
    PetscCall(DMCreateGlobalVector(grid.dm(), v.out()));
    PetscCall(ISCreateGeneral(grid.comm(), xm, src.data(), PETSC_COPY_VALUES, from.out()));
    PetscCall(ISCreateGeneral(grid.comm(), xm, dst.data(), PETSC_COPY_VALUES, to.out()));
    PetscCall(VecScatterCreate(v, from, v, to, shift_.out()));
    PetscFunctionReturn(0);
  }

  template <class P> void rhs(const P &pt, typename P::Number *g) const {
    g[0] = -pt.aux(0) * (pt.u(0, 1) - pt.u(0, -1)) * (0.5 * pt.inv_h());
    g[1] = pt.param(0) * sqr(pt.u(0, 0)); // h, entering G through B
  }
  template <class P> void initial(const P &pt, typename P::Number *u) const { u[0] = std::sin(2 * PETSC_PI * pt.x()) + 0.5; }

  // a = L u, the transpose's y += L^T z; G += B h, B^T x.
  PetscErrorCode auxiliary(int, Vec U, Vec a) const { return shift(U, a, false); }
  PetscErrorCode auxiliary_transpose(int, Vec z, Vec y) const { return shift(z, y, true); }
  PetscErrorCode output(int, Vec h, Vec G) const { return shift_add(h, G); }
  PetscErrorCode output_transpose(int, Vec x, Vec hx) const { return shift(x, hx, true, false); }

  PetscErrorCode spectrum(const ParameterBounds &, Spectrum *s) const {
    s->imag_radius = s->real_radius = 100; // the test's steps are far below any limit
    return 0;
  }

private:
  // out = S in (reverse: S^T in), added to out if add.
  PetscErrorCode shift(Vec in, Vec out, bool reverse, bool add = true) const {
    PetscFunctionBeginUser;
    if (!reverse) add = false;
    if (!add) PetscCall(VecSet(out, 0.0));
    const ScatterMode mode = reverse ? SCATTER_REVERSE : SCATTER_FORWARD;
    PetscCall(VecScatterBegin(shift_, in, out, ADD_VALUES, mode));
    PetscCall(VecScatterEnd(shift_, in, out, ADD_VALUES, mode));
    PetscFunctionReturn(0);
  }
  PetscErrorCode shift_add(Vec in, Vec out) const {
    PetscFunctionBeginUser;
    PetscCall(VecScatterBegin(shift_, in, out, ADD_VALUES, SCATTER_FORWARD));
    PetscCall(VecScatterEnd(shift_, in, out, ADD_VALUES, SCATTER_FORWARD));
    PetscFunctionReturn(0);
  }
  OwnedScatter shift_;
};

FLEXIPDE_REGISTER_MODEL("nonlocal_test", PointwiseModel<NonlocalTestModel>);

} // namespace flexipde
