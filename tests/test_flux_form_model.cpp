// Models that exist to exercise the pointwise layer's flux form on grids with walls; registered in the
// test binary only, so the conformance test (test_conformance.cpp) checks them like every model:
//
//   u_t = -sum_d div_d F_d - k u,     F_d = (u_f^2 + u_f'^2) / 4 - k_f (B_d u)_f / h    on each face f
//
// with u_f, u_f' the values on either side of the face, k_f = (k_i + k_{i+1}) / 2 and B the face
// gradient of order 2 (u_{i+1} - u_i) or 4 ((u_{i-1} - 27 u_i + 27 u_{i+1} - u_{i+2}) / 24, with the
// matching four-face divergence). k is the parameter (scalar or field). Walls on every side: the state
// reads 0 beyond them, and the points on and near them take the layer's gather of the composed G,
// the others the gather of the faces; on 2 ranks the points next to the rank boundary read their
// faces from the ghosted arrays.
#include "flexipde/pointwise.hpp"

namespace flexipde {

template <int Dim, int Order> class FluxTestModel {
public:
  static constexpr int dim = Dim, components = 1, radius = Order == 4 ? 3 : 1, parameters = 1;

  const char *name() const { return names[index()]; }
  const char *component_name(int) const { return "u"; }
  void grid_defaults(GridOptions &o) const {
    o.n = o.ny = Dim == 2 ? 12 : 24;
    o.periodic = o.periodic_y = PETSC_FALSE;
  }

  PetscErrorCode setup(const Grid &grid, Declarations &decl) {
    PetscBool field = PETSC_FALSE;
    std::string option = std::string("-") + names[index()] + "_k_field";
    PetscFunctionBeginUser;
    PetscCall(PetscOptionsGetBool(nullptr, nullptr, option.c_str(), &field, nullptr));
    decl.parameter(0, std::string(names[index()]) + "_k", field, 0.0, 0.05);
    PetscFunctionReturn(0);
  }

  static constexpr auto divergence() {
    if constexpr (Order == 4) return std::array<double, 4>{1.0 / 24, -27.0 / 24, 27.0 / 24, -1.0 / 24};
    else return std::array<double, 2>{-1.0, 1.0};
  }
  template <class P, int d> void flux(const P &pt, Direction<d>, typename P::Number *F) const {
    using T = typename P::Number;
    auto u = [&](int o) { return d == 0 ? pt.u(0, o) : pt.u(0, 0, o); };
    auto k = [&](int o) { return d == 0 ? pt.param(0, o) : pt.param(0, 0, o); };
    T grad = u(1) - u(0);
    if constexpr (Order == 4) grad = (u(-1) - u(2) + 27.0 * (u(1) - u(0))) * (1.0 / 24);
    F[0] = 0.25 * (sqr(u(0)) + sqr(u(1))) - 0.5 * (k(0) + k(1)) * grad * pt.inv_h(d);
  }
  template <class P> void source(const P &pt, typename P::Number *s) const { s[0] = -pt.param(0) * pt.u(0, 0); }

  template <class P> void initial(const P &pt, typename P::Number *u) const {
    const double x = pt.x(0), y = Dim == 2 ? pt.x(1) : 0.5;
    u[0] = std::sin(PETSC_PI * x) * std::sin(PETSC_PI * y) + 0.3 * std::cos(3 * x);
  }

private:
  static constexpr const char *names[] = {"flux_test", "flux_test4", "flux_test_2d"};
  static constexpr int index() { return Dim == 2 ? 2 : (Order == 4 ? 1 : 0); }
};

using FluxTest = FluxTestModel<1, 2>;
using FluxTest4 = FluxTestModel<1, 4>;
using FluxTest2D = FluxTestModel<2, 2>;
FLEXIPDE_REGISTER_MODEL("flux_test", PointwiseModel<FluxTest>);
FLEXIPDE_REGISTER_MODEL("flux_test4", PointwiseModel<FluxTest4>);
FLEXIPDE_REGISTER_MODEL("flux_test_2d", PointwiseModel<FluxTest2D>);

} // namespace flexipde
