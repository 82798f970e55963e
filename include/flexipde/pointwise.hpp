// The pointwise stencil layer: a model states G at one grid point, once; flexipde derives the rest.
//
// A model is a class `Eq` (see src/models/burgers.cpp and docs/adding_a_model.md) that says
//   static constexpr int dim, components, radius, parameters;   and optionally  shape (star/box),
//   linear (G linear in U), second_order_pairs (m: G_q = p, G_p independent of p),
//   const char *name() const;  const char *component_name(int) const;
//   PetscErrorCode setup(const Grid &, Declarations &);          options, parameters
//   template <class P> void rhs(const P &pt, typename P::Number *g) const;      G at one point
//   template <class P> void initial(const P &pt, typename P::Number *u0) const; U0(p) at one point
// where `pt` reads the state on the stencil (pt.u(c, dx[, dy])), the parameters (pt.param(k, dx[, dy])),
// and the geometry (pt.x(), pt.index(d), pt.wall(d, side), pt.h(d), pt.t()). Both functions are
// templates in the number type P::Number, and PointwiseModel<Eq> evaluates them at
//   double                              G and U0 themselves,
//   Dual<double, 1>                     products with dG/dU and dG/dp (one direction),
//   Dual<double, stencil * components>  the rows of dG/dU for the assembled Jacobian,
//   Dual<double, components + parameters>, seeded at one stencil offset at a time
//                                       the transposes (dG/dU)^T x and (dG/dp)^T x in gather form:
//     y(j) = sum_o sum_c dG_c(j - o)/dU(j) x_c(j - o),  one write per point and no reverse exchange,
//   and their nestings for second derivatives.
// Its `Jacobian` is never written by hand. Every parameter is held as a field on the ghosted grid (a
// scalar parameter as a constant one): a scalar's gradient is the sum of the field gradient.
//
// Ghost width: the transposes evaluate G at the neighbours of owned points, whose stencils reach
// 2 * radius from them; the state DM therefore has 2 * radius ghosts, the assembled Jacobian radius.
#pragma once
#include "flexipde/dual.hpp"
#include "flexipde/model.hpp"
#include "flexipde/leapfrog.hpp"
#include "flexipde/survey.hpp"
#include <array>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

// The sweeps inline everything they call, the model's pointwise functions above all: only then do
// the zero lanes of seeds placed elsewhere fold away.
#define FLEXIPDE_SWEEP __attribute__((flatten))

namespace flexipde {

enum class StencilShape { Star, Box };

// The smallest and largest value of each parameter (a scalar's value twice), as set last.
struct ParameterBounds {
  std::vector<PetscReal> min, max;
};

// What a model declares at setup: its parameters (each a scalar or a field, or fixed when the scene
// does not make it a parameter) and their defaults.
class Declarations {
public:
  Declarations(Parameters &params, int count) : params_(params), index_(count, -1), fixed_(count, 0.0) {}
  // Parameter `k` (0 <= k < Eq::parameters) as `name`, a field or a scalar, with the lower bound an
  // optimiser respects and the value used when the options give none.
  void parameter(int k, const std::string &name, bool field, PetscReal lower, PetscReal initial) {
    index_[k] = params_.add(name, field ? ParamKind::Field : ParamKind::Scalar, lower, initial);
  }
  // Parameter slot `k` held at `value` (not a parameter of this scene: no gradient, no option).
  void fixed(int k, PetscReal value) { fixed_[k] = value, index_[k] = -1; }
  PetscInt index(int k) const { return index_[k]; }
  PetscReal fixed_value(int k) const { return fixed_[k]; }

private:
  Parameters &params_;
  std::vector<PetscInt> index_;
  std::vector<PetscReal> fixed_;
};

namespace pointwise {

// Compile-time stencil offsets: entry e of a star or box stencil of the given radius in D dimensions.
template <int D, int R, StencilShape S>
struct Stencil {
  static constexpr int size = S == StencilShape::Star ? 1 + 2 * R * D : (D == 1 ? 2 * R + 1 : (2 * R + 1) * (2 * R + 1));
  static constexpr std::array<int, 2> offset(int e) {
    if constexpr (S == StencilShape::Star) {
      if (e == 0) return {0, 0};
      const int d = (e - 1) / (2 * R), k = (e - 1) % (2 * R), o = k < R ? k - R : k - R + 1;
      return d == 0 ? std::array<int, 2>{o, 0} : std::array<int, 2>{0, o};
    } else {
      return {e % (2 * R + 1) - R, D == 1 ? 0 : e / (2 * R + 1) - R};
    }
  }
  static constexpr int entry(int dx, int dy) {
    for (int e = 0; e < size; ++e)
      if (offset(e)[0] == dx && offset(e)[1] == dy) return e;
    return -1;
  }
};

enum class Mode { Value, Tangent, Rows, Gather };

// Everything a sweep reads around one point. Arrays are the ghosted local ones (x fastest, components
// interleaved): `at` is the point's index in them, `sy` their row length.
struct Frame {
  const PetscScalar *U = nullptr;  // state
  const PetscScalar *X = nullptr;  // direction of the state (Tangent; null: 0)
  const PetscScalar *P = nullptr;  // parameters, `np` per point
  const PetscScalar *dP = nullptr; // direction of the parameters (Tangent; null: 0)
  const PetscScalar *A = nullptr;  // auxiliary fields a = L U, `na` per point (non-local linear maps of the state)
  const PetscScalar *dA = nullptr; // their direction L X (Tangent; null: 0)
  PetscInt np = 0, na = 0, sy = 0;
  PetscReal t = 0;
  PetscReal h[2] = {1, 1}, ih[2] = {1, 1}, x0[2] = {0, 0};
  PetscInt n[2] = {1, 1};
  bool periodic[2] = {false, false};
  // Beyond a wall the state is the odd reflection of the inside (u = 0 on the wall, fourth-order
  // stencils stay consistent next to it), else 0.
  bool odd[2] = {false, false};
  int dim = 1;
};

// The point view handed to a model's rhs() and initial(). Mode and seeds decide what a Number is:
//   Value    double;  Tangent  Dual<double, 1> in the direction (X, dP);
//   Rows     Dual<double, E * C>, lane e * C + c for state component c at stencil entry e;
//   Gather   Dual<double, C + K + NP>, lanes c for U_c, C + k for auxiliary field k and C + K + k for
//            parameter k, at offset (SX, SY) only.
// CK: the point is near a wall or the ghost band, and every read is checked: positions beyond a wall
// are reflected or zero, and (Gather) the seeded input is found by its position (ti, tj) at run time.
template <int C, int K, int NP, class Sten, Mode M, int SX = 0, int SY = 0, bool CK = false>
class Point {
public:
  using Number = std::conditional_t<
      M == Mode::Value, double,
      std::conditional_t<M == Mode::Tangent, Dual<double, 1>,
                         std::conditional_t<M == Mode::Rows, Dual<double, Sten::size * C>, Dual<double, C + K + NP>>>>;
  Point(const Frame &f, PetscInt at, PetscInt i, PetscInt j, PetscInt ti = 0, PetscInt tj = 0)
      : f_(f), at_(at), i_(i), j_(j), ti_(ti), tj_(tj) {}

  // State component c at offset (dx, dy) from the point.
  Number u(int c, int dx, int dy = 0) const {
    if constexpr (CK) return u_checked(c, dx, dy);
    const PetscInt k = (at_ + dx + dy * f_.sy) * C + c;
    const double v = PetscRealPart(f_.U[k]);
    if constexpr (M == Mode::Value) return v;
    else if constexpr (M == Mode::Tangent) {
      Number r(v);
      r.d[0] = f_.X ? PetscRealPart(f_.X[k]) : 0.0;
      return r;
    } else if constexpr (M == Mode::Rows) return Number::seeded(v, Sten::entry(dx, dy) * C + c);
    else return dx == SX && dy == SY ? Number::seeded(v, c) : Number(v);
  }
  // Parameter k (a field's value at the offset; a scalar's value anywhere).
  Number param(int k, int dx = 0, int dy = 0) const {
    const PetscInt a = (at_ + dx + dy * f_.sy) * f_.np + k;
    const double v = PetscRealPart(f_.P[a]); // 0 beyond a wall
    if constexpr (M == Mode::Tangent) {
      Number r(v);
      r.d[0] = f_.dP ? PetscRealPart(f_.dP[a]) : 0.0;
      return r;
    } else if constexpr (M == Mode::Gather) {
      const bool seed = CK ? i_ + dx == ti_ && j_ + dy == tj_ : dx == SX && dy == SY;
      return seed ? Number::seeded(v, C + K + k) : Number(v);
    } else return v;
  }
  // Auxiliary field k (Eq::auxiliaries: a = L U from the model's non-local linear maps) at the offset.
  Number aux(int k, int dx = 0, int dy = 0) const {
    static_assert(M != Mode::Rows, "a model with auxiliary fields has no assembled Jacobian");
    const PetscInt a = (at_ + dx + dy * f_.sy) * K + k;
    const double v = PetscRealPart(f_.A[a]); // 0 beyond a wall
    if constexpr (M == Mode::Tangent) {
      Number r(v);
      r.d[0] = f_.dA ? PetscRealPart(f_.dA[a]) : 0.0;
      return r;
    } else if constexpr (M == Mode::Gather) {
      const bool seed = CK ? i_ + dx == ti_ && j_ + dy == tj_ : dx == SX && dy == SY;
      return seed ? Number::seeded(v, C + k) : Number(v);
    } else return v;
  }
  PetscReal t() const { return f_.t; }
  PetscInt index(int d = 0) const { return d == 0 ? i_ : j_; }
  PetscReal h(int d = 0) const { return f_.h[d]; }
  PetscReal inv_h(int d = 0) const { return f_.ih[d]; } // 1/h: a product instead of a division per point
  PetscReal x(int d = 0) const { return f_.x0[d] + (d == 0 ? i_ : j_) * f_.h[d]; }
  PetscInt points(int d = 0) const { return f_.n[d]; }
  // True on a non-periodic direction's first (side 0) or last (side 1) point.
  // (An unchecked point is never on a wall: known at compile time.)
  bool wall(int d, int side) const {
    if (!CK || f_.periodic[d]) return false;
    const PetscInt i = d == 0 ? i_ : j_;
    return side == 0 ? i == 0 : i == f_.n[d] - 1;
  }
  bool on_wall() const { return wall(0, 0) || wall(0, 1) || (f_.dim > 1 && (wall(1, 0) || wall(1, 1))); }

private:
  // Position g in direction d, kept when inside (or periodic), reflected beyond a wall (sign flipped),
  // or false: the state is 0 there.
  bool fold(int d, PetscInt &g, double &sign) const {
    const PetscInt n = f_.n[d];
    if (f_.periodic[d] || (g >= 0 && g < n)) return true;
    if (!f_.odd[d]) return false;
    g = g < 0 ? -g : 2 * (n - 1) - g;
    sign = -sign;
    return true;
  }
  Number u_checked(int c, int dx, int dy) const {
    PetscInt gi = i_ + dx, gj = j_ + dy;
    double sign = 1;
    if (!fold(0, gi, sign) || !fold(1, gj, sign)) return Number(0.0);
    const PetscInt k = (at_ + (gi - i_) + (gj - j_) * f_.sy) * C + c;
    const double v = sign * PetscRealPart(f_.U[k]);
    if constexpr (M == Mode::Value) return v;
    else {
      Number r(v);
      if constexpr (M == Mode::Tangent) r.d[0] = f_.X ? sign * PetscRealPart(f_.X[k]) : 0.0;
      else if constexpr (M == Mode::Rows) r.d[Sten::entry((int)(gi - i_), (int)(gj - j_)) * C + c] = sign;
      else if (gi == ti_ && gj == tj_) r.d[c] = sign;
      return r;
    }
  }

  const Frame &f_;
  PetscInt at_, i_, j_, ti_, tj_;
};

template <class Eq, class = void> struct ShapeOf {
  static constexpr StencilShape value = StencilShape::Star;
};
template <class Eq> struct ShapeOf<Eq, std::void_t<decltype(Eq::shape)>> {
  static constexpr StencilShape value = Eq::shape;
};
template <class Eq, class = void> struct LinearOf : std::false_type {};
template <class Eq> struct LinearOf<Eq, std::void_t<decltype(Eq::linear)>> : std::bool_constant<Eq::linear> {};
template <class Eq, class = void> struct PairsOf : std::integral_constant<int, 0> {};
// Optional runtime statements: whether the second-order form holds in this scene (a damping term may
// break it), whether the state is oddly reflected beyond walls, which component point sources force.
template <class Eq, class = void> struct HasSecondOrderActive : std::false_type {};
template <class Eq>
struct HasSecondOrderActive<Eq, std::void_t<decltype(std::declval<const Eq &>().second_order_active())>> : std::true_type {};
template <class Eq, class = void> struct HasOddWalls : std::false_type {};
template <class Eq> struct HasOddWalls<Eq, std::void_t<decltype(std::declval<const Eq &>().odd_walls())>> : std::true_type {};
template <class Eq, class = void> struct HasForcing : std::false_type {};
template <class Eq> struct HasForcing<Eq, std::void_t<decltype(Eq::forced_component)>> : std::true_type {};
template <class Eq>
struct PairsOf<Eq, std::void_t<decltype(Eq::second_order_pairs)>> : std::integral_constant<int, Eq::second_order_pairs> {};
// Non-local couplings: `auxiliaries` fields a_k = L_k U read at points (pt.aux), and `outputs` fields h_m
// written by rhs after the C components, entering G through G += B_m h_m (L, B: the model's linear maps).
template <class Eq, class = void> struct AuxOf : std::integral_constant<int, 0> {};
template <class Eq> struct AuxOf<Eq, std::void_t<decltype(Eq::auxiliaries)>> : std::integral_constant<int, Eq::auxiliaries> {};
template <class Eq, class = void> struct OutputsOf : std::integral_constant<int, 0> {};
template <class Eq> struct OutputsOf<Eq, std::void_t<decltype(Eq::outputs)>> : std::integral_constant<int, Eq::outputs> {};
// Optional named functionals of the state (Model::functional): `functional_names()` and
// `functional(name, U, value, dFdU)`, forwarded as the model states them.
template <class Eq, class = void> struct HasFunctionals : std::false_type {};
template <class Eq>
struct HasFunctionals<Eq, std::void_t<decltype(std::declval<const Eq &>().functional_names())>> : std::true_type {};

} // namespace pointwise

// A Model made from pointwise equations: every product the integrators and adjoints ask for is a sweep
// of Eq::rhs at some number type.
template <class Eq>
class PointwiseModel final : public Model {
  static constexpr int D = Eq::dim, C = Eq::components, R = Eq::radius, NP = Eq::parameters;
  static constexpr int K = pointwise::AuxOf<Eq>::value, H = pointwise::OutputsOf<Eq>::value;
  static constexpr bool Local = K == 0 && H == 0; // else dG/dU is applied, never assembled
  static constexpr StencilShape Shape = pointwise::ShapeOf<Eq>::value;
  using Sten = pointwise::Stencil<D, R, Shape>;
  using Mode = pointwise::Mode;
  template <Mode M, int SX = 0, int SY = 0, bool CK = false> using Pt = pointwise::Point<C, K, NP, Sten, M, SX, SY, CK>;
  template <bool CK> using Check = std::integral_constant<bool, CK>;
  static_assert(D == 1 || D == 2, "the grid is 1D or 2D");
  static_assert(Local || pointwise::PairsOf<Eq>::value == 0, "the leapfrog kick handles local models only");
  // A state as the sweeps read it: ghosted, with its auxiliary fields (K per point, ghosted) if any.
  struct LocalState {
    OwnedVec u, a;
  };

public:
  const char *name() const override { return eq_.name(); }
  PetscInt dof() const override { return C; }
  const char *component_name(PetscInt c) const override { return eq_.component_name((int)c); }
  PetscInt stencil_width(MPI_Comm) const override { return 2 * R; }
  PetscInt dim() const override { return D; }
  void grid_defaults(GridOptions &o) const override { eq_.grid_defaults(o); }
  bool linear() const override { return pointwise::LinearOf<Eq>::value; }
  bool jacobian_constant() const override { return pointwise::LinearOf<Eq>::value; }
  PetscInt second_order_pairs() const override {
    if constexpr (pointwise::HasSecondOrderActive<Eq>::value)
      if (!eq_.second_order_active()) return 0;
    return pointwise::PairsOf<Eq>::value;
  }

  PetscErrorCode setup(const Grid &grid, DM state_dm, Parameters &params) override {
    PetscFunctionBeginUser;
    grid_ = &grid;
    dm_ = state_dm;
    params_ = &params;
    Declarations decl(params, NP);
    PetscCall(eq_.setup(grid, decl));
    for (int k = 0; k < NP; ++k) index_[k] = decl.index(k), fixed_[k] = decl.fixed_value(k);
    PetscCall(grid.create_dm(NP, param_dm_.out()));
    PetscCall(DMCreateLocalVector(param_dm_, P_.out()));
    PetscCall(VecSet(P_, 0.0)); // beyond a wall: never written, reads 0
    PetscCall(VecDuplicate(P_, dP_.out()));
    PetscCall(VecSet(dP_, 0.0));
    PetscCall(DMCreateGlobalVector(param_dm_, Pg_.out()));
    PetscCall(DMCreateLocalVector(dm_, Xl_.out()));
    PetscCall(VecSet(Xl_, 0.0));
    PetscCall(create_state(st_));
    PetscCall(create_state(jac_));
    PetscCall(create_state(jp_));
    if constexpr (K > 0) {
      PetscCall(grid.create_dm(K, aux_dm_.out()));
      PetscCall(DMCreateGlobalVector(aux_dm_, Ag_.out()));
      PetscCall(VecDuplicate(Ag_, Zg_.out()));
      PetscCall(DMCreateLocalVector(aux_dm_, dAl_.out()));
      PetscCall(VecSet(dAl_, 0.0));
      for (auto *s : {&st_, &jac_, &jp_}) {
        PetscCall(VecDuplicate(dAl_, s->a.out()));
        PetscCall(VecSet(s->a, 0.0));
      }
    }
    if constexpr (H > 0) {
      PetscCall(grid.create_dm(H, out_dm_.out()));
      PetscCall(DMCreateGlobalVector(out_dm_, Hg_.out()));
      PetscCall(DMCreateLocalVector(out_dm_, XHl_.out()));
      PetscCall(VecSet(XHl_, 0.0));
    }
    if constexpr (!Local) {
      PetscCall(DMCreateGlobalVector(grid.dm(), field_.out()));
      PetscCall(DMCreateGlobalVector(dm_, Yt_.out()));
    }
    scalar_acc_.assign((size_t)NP, std::vector<PetscReal>());
    for (int k = 0; k < NP; ++k)
      if (index_[k] >= 0 && params.info(index_[k]).kind == ParamKind::Scalar) scalar_acc_[k].assign(grid.local_points(), 0.0);
    frame_.sy = D == 2 ? ghost_xm() : 0;
    frame_.h[0] = grid.h(), frame_.h[1] = grid.hy();
    frame_.ih[0] = 1 / grid.h(), frame_.ih[1] = 1 / grid.hy();
    frame_.x0[0] = grid.x0(), frame_.x0[1] = grid.y0();
    frame_.n[0] = grid.n(), frame_.n[1] = grid.ny();
    frame_.periodic[0] = grid.periodic(), frame_.periodic[1] = grid.periodic_y();
    if constexpr (pointwise::HasOddWalls<Eq>::value) frame_.odd[0] = frame_.odd[1] = eq_.odd_walls();
    frame_.np = NP;
    frame_.na = K;
    frame_.dim = D;
    PetscFunctionReturn(0);
  }

  // Every parameter into the ghosted local array P_ (fields with their neighbours, scalars constant).
  PetscErrorCode set_parameters(Vec p) override {
    OwnedVec f;
    PetscFunctionBeginUser;
    PetscCall(DMCreateGlobalVector(grid_->dm(), f.out()));
    for (int k = 0; k < NP; ++k) {
      if (index_[k] >= 0) PetscCall(params_->as_field(p, index_[k], f));
      else PetscCall(VecSet(f, fixed_[k]));
      PetscCall(VecStrideScatter(f, k, Pg_, INSERT_VALUES));
    }
    PetscCall(DMGlobalToLocal(param_dm_, Pg_, INSERT_VALUES, P_));
    bounds_.min.assign(NP, 0.0), bounds_.max.assign(NP, 0.0);
    for (int k = 0; k < NP; ++k) {
      PetscCall(VecStrideMin(Pg_, k, nullptr, &bounds_.min[k]));
      PetscCall(VecStrideMax(Pg_, k, nullptr, &bounds_.max[k]));
    }
    if constexpr (HasCheck<Eq>::value) PetscCall(eq_.check_parameters(bounds_, grid_->comm()));
    PetscFunctionReturn(0);
  }

  FLEXIPDE_SWEEP PetscErrorCode rhs(PetscReal t, Vec U, Vec G) override {
    PetscFunctionBeginUser;
    PetscCall(load(U, st_));
    {
      ConstArray u(st_.u), p(P_), a(st_.a);
      Array g(G);
      PetscCall(u.error());
      PetscCall(p.error());
      PetscCall(g.error());
      pointwise::Frame f = frame(t, u.data(), p.data());
      f.A = a.data();
      PetscScalar *out = g.data();
      PetscScalar *hout = nullptr;
      if constexpr (H > 0) PetscCall(VecGetArray(Hg_, &hout));
      for_points(R, [&](PetscInt at, PetscInt own, PetscInt i, PetscInt j, auto ck) {
        double gv[C + H];
        eq_.rhs(Pt<Mode::Value, 0, 0, decltype(ck)::value>(f, at, i, j), gv);
        for (int c = 0; c < C; ++c) out[own * C + c] = gv[c];
        for (int m = 0; m < H; ++m) hout[own * H + m] = gv[C + m];
      });
      if constexpr (H > 0) PetscCall(VecRestoreArray(Hg_, &hout));
      if constexpr (pointwise::HasForcing<Eq>::value)
        if (source_)
          for (PetscInt k = 0; k < source_->stencil.n; ++k)
            out[source_->stencil.local[k] * C + Eq::forced_component] += source_->density(k, t);
    }
    PetscCall(add_outputs(G));
    PetscFunctionReturn(0);
  }

  // y = dG/dU x + dG/dp dp at state U (either direction may be null), one sweep of Tangent numbers.
  FLEXIPDE_SWEEP PetscErrorCode tangent(PetscReal t, const LocalState &s, Vec x, Vec dp, Vec y) {
    PetscFunctionBeginUser;
    if (x) PetscCall(to_local(x, Xl_));
    if (dp) PetscCall(params_to_local(dp, dP_));
    if constexpr (K > 0)
      if (x) PetscCall(auxiliaries(x, dAl_));
    {
      ConstArray u(s.u), xa(x ? Xl_.get() : nullptr), p(P_), dpa(dp ? dP_.get() : nullptr), a(s.a),
          da(K > 0 && x ? dAl_.get() : nullptr);
      Array ya(y);
      PetscCall(ya.error());
      pointwise::Frame f = frame(t, u.data(), p.data());
      f.X = xa.data();
      f.dP = dpa.data();
      f.A = a.data();
      f.dA = da.data();
      PetscScalar *out = ya.data();
      PetscScalar *hout = nullptr;
      if constexpr (H > 0) PetscCall(VecGetArray(Hg_, &hout));
      for_points(R, [&](PetscInt at, PetscInt own, PetscInt i, PetscInt j, auto ck) {
        typename Pt<Mode::Tangent>::Number gv[C + H];
        eq_.rhs(Pt<Mode::Tangent, 0, 0, decltype(ck)::value>(f, at, i, j), gv);
        for (int c = 0; c < C; ++c) out[own * C + c] = gv[c].d[0];
        for (int m = 0; m < H; ++m) hout[own * H + m] = gv[C + m].d[0];
      });
      if constexpr (H > 0) PetscCall(VecRestoreArray(Hg_, &hout));
    }
    PetscCall(add_outputs(y));
    PetscFunctionReturn(0);
  }

  // The transposes at state s: y = (dG/dU)^T x (y null: not formed) and, for every parameter k,
  // gk[j] += w sum (dG/dp_k(j))^T x (gk null: not wanted), in one gather sweep; xl is x ghosted and xh
  // the outputs' B^T x ghosted. Components of x outside [clo, chi) are taken as 0, and only y's
  // components in [ylo, yhi) are written (added, times w, if add_y): the leapfrog's kick is this with
  // x = lambda_p, y = lambda_q. z (auxiliary fields; null: none) gets the gather of (dG/da)^T x.
  template <int CLO = 0, int CHI = C, int YLO = 0, int YHI = C>
  FLEXIPDE_SWEEP PetscErrorCode gather(PetscReal t, const LocalState &s, const PetscScalar *xl, const PetscScalar *xh,
                                       PetscScalar *y, bool add_y, PetscReal w, PetscReal *const *gk, PetscScalar *z) {
    PetscFunctionBeginUser;
    {
      ConstArray u(s.u), p(P_), a(s.a);
      PetscCall(u.error());
      PetscCall(p.error());
      pointwise::Frame f = frame(t, u.data(), p.data());
      f.A = a.data();
      const PetscInt nx = grid_->n(), ny = grid_->ny();
      const bool px = grid_->periodic(), py = grid_->periodic_y();
      for_points(2 * R, [&](PetscInt at, PetscInt own, PetscInt i, PetscInt j, auto ck) {
        double yv[C] = {};
        double zv[K > 0 ? K : 1] = {};
        double gv[NP > 0 ? NP : 1] = {};
        gather_offsets<CLO, CHI, decltype(ck)::value>(f, xl, xh, at, i, j, nx, ny, px, py, yv, zv, gv,
                                                       std::make_integer_sequence<int, Sten::size>());
        if (y)
          for (int c = YLO; c < YHI; ++c) {
            if (add_y) y[own * C + c] += w * yv[c];
            else y[own * C + c] = yv[c];
          }
        if (z)
          for (int k = 0; k < K; ++k) z[own * K + k] = zv[k];
        if (gk)
          for (int k = 0; k < NP; ++k)
            if (gk[k]) gk[k][own] += w * gv[k];
      });
    }
    PetscFunctionReturn(0);
  }

  // The gather of x at the state s into y (null: none) and, unless mu is null, mu += w (dG/dp)^T x: a
  // field's entries in place, a scalar's pointwise terms into its accumulator if `defer` (the
  // integrators' own sweeps during an adjoint solve; end_adjoint sums them), else summed now
  // (collective; the shells, whose products PETSc scales after the fact). The non-local maps enter
  // as B^T x before the sweep and L^T z after it.
  template <int CLO = 0, int CHI = C, int YLO = 0, int YHI = C>
  PetscErrorCode transpose(PetscReal t, const LocalState &s, Vec x, Vec y, bool add_y, PetscReal w, Vec mu, bool defer) {
    PetscFunctionBeginUser;
    PetscCall(to_local(x, Xl_));
    if constexpr (H > 0) {
      for (int m = 0; m < H; ++m) {
        PetscCall(eq_.output_transpose(m, x, field_));
        PetscCall(VecStrideScatter(field_, m, Hg_, INSERT_VALUES));
      }
      PetscCall(DMGlobalToLocal(out_dm_, Hg_, INSERT_VALUES, XHl_));
    }
    {
      ConstArray xa(Xl_), xha(XHl_);
      PetscScalar *ya = nullptr, *m = nullptr, *za = nullptr;
      if (y) PetscCall(VecGetArray(y, &ya));
      if (mu) PetscCall(VecGetArray(mu, &m));
      if (K > 0 && y) PetscCall(VecGetArray(Zg_, &za));
      PetscReal *gk[NP > 0 ? NP : 1] = {};
      if (mu) fill_gradient_targets(m, defer, gk);
      PetscCall((gather<CLO, CHI, YLO, YHI>(t, s, xa.data(), xha.data(), ya, add_y, w, mu ? gk : nullptr, za)));
      if (za) PetscCall(VecRestoreArray(Zg_, &za));
      if (mu) PetscCall(VecRestoreArray(mu, &m));
      if (y) PetscCall(VecRestoreArray(y, &ya));
    }
    if constexpr (K > 0)
      if (y) {
        PetscCall(VecSet(Yt_, 0.0));
        for (int k = 0; k < K; ++k) {
          PetscCall(VecStrideGather(Zg_, k, field_, INSERT_VALUES));
          PetscCall(eq_.auxiliary_transpose(k, field_, Yt_));
        }
        PetscCall(VecAXPY(y, add_y ? w : 1.0, Yt_));
      }
    if (mu && !defer) PetscCall(flush_scratch_scalars(mu));
    PetscFunctionReturn(0);
  }

  PetscErrorCode create_jacobian(Mat *J) override {
    PetscFunctionBeginUser;
    if constexpr (!Local) { // applied at the state of the last rhs_jacobian, solved with by Krylov methods
      const PetscInt n = grid_->local_points() * C;
      PetscCall(MatCreateShell(grid_->comm(), n, n, PETSC_DETERMINE, PETSC_DETERMINE, this, J));
      PetscCall(MatShellSetOperation(*J, MATOP_MULT, (void (*)(void))jmf_mult));
      PetscCall(MatShellSetOperation(*J, MATOP_MULT_TRANSPOSE, (void (*)(void))jmf_mult_transpose));
      PetscCall(MatSetUp(*J));
      PetscFunctionReturn(0);
    }
    PetscCall(grid_->create_dm(C, matrix_dm_.out(), R, Shape == StencilShape::Star));
    PetscCall(DMSetMatrixPreallocateOnly(matrix_dm_, PETSC_TRUE));
    PetscCall(DMCreateMatrix(matrix_dm_, J));
    PetscCall(MatSetOption(*J, MAT_NEW_NONZERO_ALLOCATION_ERR, PETSC_FALSE));
    PetscCall(find_pattern());
    PetscFunctionReturn(0);
  }
  // dG/dU row by row: Eq::rhs at Dual numbers with one lane per stencil entry and component; only the
  // entries structurally nonzero (pattern_, found once at random inputs) are inserted.
  PetscErrorCode rhs_jacobian(PetscReal t, Vec U, Mat J) override {
    PetscFunctionBeginUser;
    PetscCall(load(U, jac_));
    if constexpr (Local) {
      PetscCall(MatZeroEntries(J));
      PetscCall(assemble_rows(t, jac_.u, J, nullptr));
    }
    PetscCall(MatAssemblyBegin(J, MAT_FINAL_ASSEMBLY));
    PetscCall(MatAssemblyEnd(J, MAT_FINAL_ASSEMBLY));
    PetscFunctionReturn(0);
  }
  // Only for a linear G (the Simulation applies it at whatever state): dG/dU does not depend on U.
  PetscErrorCode create_jacobian_matrix_free(Mat *J) override {
    const PetscInt n = grid_->local_points() * C;
    PetscFunctionBeginUser;
    *J = nullptr;
    if (!pointwise::LinearOf<Eq>::value || !Local) PetscFunctionReturn(0); // (non-local: the Jacobian is this shell)
    PetscCall(MatCreateShell(grid_->comm(), n, n, PETSC_DETERMINE, PETSC_DETERMINE, this, J));
    PetscCall(MatShellSetOperation(*J, MATOP_MULT, (void (*)(void))jmf_mult));
    PetscCall(MatShellSetOperation(*J, MATOP_MULT_TRANSPOSE, (void (*)(void))jmf_mult_transpose));
    PetscFunctionReturn(0);
  }
  PetscErrorCode create_jacobian_p(Mat *Jp) override {
    const PetscInt n = grid_->local_points() * C;
    PetscFunctionBeginUser;
    PetscCall(MatCreateShell(grid_->comm(), n, params_->local_size(), PETSC_DETERMINE, PETSC_DETERMINE, this, Jp));
    PetscCall(MatShellSetOperation(*Jp, MATOP_MULT, (void (*)(void))jp_mult));
    PetscCall(MatShellSetOperation(*Jp, MATOP_MULT_TRANSPOSE, (void (*)(void))jp_mult_transpose));
    PetscFunctionReturn(0);
  }
  // The shells read the state of the last rhs_jacobian_p call (and the matrix-free dG/dU, of the last
  // rhs_jacobian call or the state handed to stage products).
  PetscErrorCode rhs_jacobian_p(PetscReal t, Vec U, Mat Jp) override {
    PetscFunctionBeginUser;
    PetscCall(load(U, jp_));
    jp_t_ = t;
    PetscCall(MatAssemblyBegin(Jp, MAT_FINAL_ASSEMBLY)); // resets the scaling a theta adjoint applied last time
    PetscCall(MatAssemblyEnd(Jp, MAT_FINAL_ASSEMBLY));
    PetscFunctionReturn(0);
  }

  // Explicit RK adjoint stage: y = (dG/dU)^T x and mu += (dG/dp)^T x, one sweep.
  bool has_stage_adjoint() const override { return true; }
  PetscErrorCode stage_adjoint(PetscReal t, Vec U, const PetscScalar *, Vec x, Vec y, Vec mu) override {
    PetscFunctionBeginUser;
    PetscCall(load(U, st_));
    PetscCall(transpose(t, st_, x, y, false, 1.0, mu, in_adjoint_));
    PetscFunctionReturn(0);
  }

  // Leapfrog kick at one time level: lambda_p += drift lambda_q, then lambda_q += w (dG_p/dq)^T lambda_p
  // and mu += w (dG_p/dp)^T lambda_p, the transposes in one gather sweep.
  bool has_second_order_adjoint() const override { return pointwise::PairsOf<Eq>::value > 0; }
  PetscErrorCode second_order_adjoint(PetscReal t, Vec U, const PetscScalar *, Vec lambda, PetscReal w, Vec mu,
                                      PetscReal drift, const PetscScalar *) override {
    constexpr int m = pointwise::PairsOf<Eq>::value;
    PetscFunctionBeginUser;
    if constexpr (m > 0) {
      PetscCall(load(U, st_));
      if (drift != 0) {
        Array l(lambda);
        PetscCall(l.error());
        leapfrog_drift_transpose(l.data(), 0, grid_->local_points(), m, drift);
      }
      PetscCall((transpose<m, 2 * m, 0, m>(t, st_, lambda, lambda, true, w, mu, in_adjoint_)));
    }
    PetscFunctionReturn(0);
  }
  // Within one adjoint solve a scalar's pointwise terms accumulate, summed once at the end.
  void begin_adjoint() override {
    in_adjoint_ = true;
    for (auto &a : scalar_acc_) std::fill(a.begin(), a.end(), 0.0);
  }
  PetscErrorCode end_adjoint(Vec mu) override {
    PetscFunctionBeginUser;
    const bool was = in_adjoint_;
    in_adjoint_ = false;
    if (!was || !mu) PetscFunctionReturn(0);
    for (int k = 0; k < NP; ++k)
      if (!scalar_acc_[k].empty()) PetscCall(params_->add_local_sum(mu, index_[k], sum(scalar_acc_[k])));
    PetscFunctionReturn(0);
  }

  // Point sources (survey.hpp) add their forcing density to component Eq::forced_component.
  bool accepts_point_source() const override { return pointwise::HasForcing<Eq>::value; }
  PetscErrorCode set_point_source(const PointSource *s) override {
    source_ = s;
    return 0;
  }

  // Eigenvalue bounds of dG/dU for the explicit stability check: the model's own when it states them
  // (Eq::spectrum), else Gershgorin's discs of the assembled rows at the current state.
  PetscErrorCode spectrum(Spectrum *s) override {
    PetscFunctionBeginUser;
    static_assert(HasSpectrum<Eq>::value || Local, "a model with non-local maps states its spectrum");
    if constexpr (HasSpectrum<Eq>::value) PetscCall(eq_.spectrum(bounds_, s));
    else PetscCall(gershgorin(s));
    PetscFunctionReturn(0);
  }

  // Named functionals: the model's own (Eq::functional_names, Eq::functional), else none.
  std::string functional_names() const override {
    if constexpr (pointwise::HasFunctionals<Eq>::value) return eq_.functional_names();
    else return Model::functional_names();
  }
  PetscErrorCode functional(const char *fname, Vec U, PetscReal *value, Vec dFdU) override {
    if constexpr (pointwise::HasFunctionals<Eq>::value) return eq_.functional(fname, U, value, dFdU);
    else return Model::functional(fname, U, value, dFdU);
  }

  // U0 = U0(p) pointwise, and grad += (dU0/dp)^T lambda0 from Dual numbers in the parameters.
  FLEXIPDE_SWEEP PetscErrorCode initial_condition(Vec p, Vec U0) override {
    PetscFunctionBeginUser;
    {
      ConstArray pa(P_);
      Array u(U0);
      PetscCall(u.error());
      pointwise::Frame f = frame(0, nullptr, pa.data());
      PetscScalar *out = u.data();
      for_points(0, [&](PetscInt at, PetscInt own, PetscInt i, PetscInt j, auto ck) {
        double uv[C];
        eq_.initial(Pt<Mode::Value, 0, 0, decltype(ck)::value>(f, at, i, j), uv);
        for (int c = 0; c < C; ++c) out[own * C + c] = uv[c];
      });
    }
    PetscCall(to_local(U0, st_.u)); // the state the default spectrum is taken at
    PetscFunctionReturn(0);
  }
  FLEXIPDE_SWEEP PetscErrorCode initial_condition_transpose(Vec p, Vec lambda0, Vec grad) override {
    PetscFunctionBeginUser;
    if (NP == 0) PetscFunctionReturn(0);
    {
      ConstArray pa(P_), l(lambda0);
      PetscScalar *g;
      PetscCall(VecGetArray(grad, &g));
      PetscReal *gk[NP > 0 ? NP : 1] = {};
      fill_gradient_targets(g, false, gk);
      pointwise::Frame f = frame(0, nullptr, pa.data());
      const PetscScalar *lam = l.data();
      for_points(0, [&](PetscInt at, PetscInt own, PetscInt i, PetscInt j, auto ck) {
        typename Pt<Mode::Gather>::Number uv[C];
        eq_.initial(Pt<Mode::Gather, 0, 0, decltype(ck)::value>(f, at, i, j, i, j), uv);
        for (int k = 0; k < NP; ++k)
          if (gk[k]) {
            double s = 0;
            for (int c = 0; c < C; ++c) s += uv[c].d[C + K + k] * PetscRealPart(lam[own * C + c]);
            gk[k][own] += s;
          }
      });
      PetscCall(VecRestoreArray(grad, &g));
    }
    PetscCall(flush_scratch_scalars(grad));
    PetscFunctionReturn(0);
  }

private:
  template <class E, class = void> struct HasSpectrum : std::false_type {};
  template <class E>
  struct HasSpectrum<E, std::void_t<decltype(std::declval<const E &>().spectrum(std::declval<const ParameterBounds &>(),
                                                                                  std::declval<Spectrum *>()))>>
      : std::true_type {};
  template <class E, class = void> struct HasCheck : std::false_type {};
  template <class E>
  struct HasCheck<E, std::void_t<decltype(std::declval<const E &>().check_parameters(std::declval<const ParameterBounds &>(),
                                                                                      MPI_Comm()))>> : std::true_type {};

  PetscInt ghost_xm() const {
    PetscInt gxm;
    DMDAGetGhostCorners(dm_, nullptr, nullptr, nullptr, &gxm, nullptr, nullptr);
    return gxm;
  }
  pointwise::Frame frame(PetscReal t, const PetscScalar *U, const PetscScalar *P) const {
    pointwise::Frame f = frame_;
    f.t = t, f.U = U, f.P = P;
    return f;
  }
  // Every owned point: its index in the ghosted arrays, in the owned block, its grid indices, and
  // Check<true> when it lies within `margin` of a wall (its reads are checked), else Check<false>.
  template <class F> void for_points(PetscInt margin, F &&body) const {
    PetscInt gxs, gys, gxm, gym;
    DMDAGetGhostCorners(dm_, &gxs, &gys, nullptr, &gxm, &gym, nullptr);
    const PetscInt xs = grid_->xs(), xm = grid_->xm(), ys = grid_->ys(), ym = grid_->ym();
    const PetscInt nx = grid_->n(), ny = grid_->ny();
    if (D == 1) gys = 0;
    PetscInt lo = xs, hi = xs + xm;
    margin = std::max<PetscInt>(margin, 1); // wall points are always checked
    if (!grid_->periodic()) lo = std::max(lo, margin), hi = std::max(lo, std::min(hi, nx - margin));
    for (PetscInt j = ys; j < ys + ym; ++j) {
      const PetscInt row = (j - gys) * gxm - gxs, own_row = (j - ys) * xm - xs;
      const bool inside = D == 1 || grid_->periodic_y() || (j >= margin && j < ny - margin);
      if (!inside) {
        for (PetscInt i = xs; i < xs + xm; ++i) body(row + i, own_row + i, i, j, Check<true>());
        continue;
      }
      for (PetscInt i = xs; i < lo; ++i) body(row + i, own_row + i, i, j, Check<true>());
      for (PetscInt i = lo; i < hi; ++i) body(row + i, own_row + i, i, j, Check<false>());
      for (PetscInt i = hi; i < xs + xm; ++i) body(row + i, own_row + i, i, j, Check<true>());
    }
  }
  PetscErrorCode to_local(Vec g, Vec l) const {
    PetscFunctionBeginUser;
    PetscCall(DMGlobalToLocal(dm_, g, INSERT_VALUES, l));
    PetscFunctionReturn(0);
  }
  PetscErrorCode create_state(LocalState &s) const {
    PetscFunctionBeginUser;
    PetscCall(DMCreateLocalVector(dm_, s.u.out()));
    PetscCall(VecSet(s.u, 0.0));
    PetscFunctionReturn(0);
  }
  // The state U ghosted, and its auxiliary fields.
  PetscErrorCode load(Vec U, LocalState &s) {
    PetscFunctionBeginUser;
    PetscCall(to_local(U, s.u));
    if constexpr (K > 0) PetscCall(auxiliaries(U, s.a));
    PetscFunctionReturn(0);
  }
  // a_k = L_k U for every k, ghosted into `local` (K per point).
  PetscErrorCode auxiliaries(Vec U, Vec local) {
    PetscFunctionBeginUser;
    if constexpr (K > 0) {
      for (int k = 0; k < K; ++k) {
        PetscCall(eq_.auxiliary(k, U, field_));
        PetscCall(VecStrideScatter(field_, k, Ag_, INSERT_VALUES));
      }
      PetscCall(DMGlobalToLocal(aux_dm_, Ag_, INSERT_VALUES, local));
    }
    PetscFunctionReturn(0);
  }
  // G += sum_m B_m h_m, the outputs h the last sweep left in Hg_.
  PetscErrorCode add_outputs(Vec G) {
    PetscFunctionBeginUser;
    if constexpr (H > 0)
      for (int m = 0; m < H; ++m) {
        PetscCall(VecStrideGather(Hg_, m, field_, INSERT_VALUES));
        PetscCall(eq_.output(m, field_, G));
      }
    PetscFunctionReturn(0);
  }
  // A parameter-shaped Vec (packed, Parameters layout) into a ghosted array like P_.
  PetscErrorCode params_to_local(Vec p, Vec l) {
    OwnedVec f;
    PetscFunctionBeginUser;
    PetscCall(DMCreateGlobalVector(grid_->dm(), f.out()));
    for (int k = 0; k < NP; ++k) {
      if (index_[k] >= 0) PetscCall(params_->as_field(p, index_[k], f));
      else PetscCall(VecSet(f, 0.0));
      PetscCall(VecStrideScatter(f, k, Pg_, INSERT_VALUES));
    }
    PetscCall(DMGlobalToLocal(param_dm_, Pg_, INSERT_VALUES, l));
    PetscFunctionReturn(0);
  }
  // Where parameter k's pointwise gradient goes: a field's entries of the packed array m, a scalar's
  // accumulator during an adjoint, else a scratch array summed by flush_scratch_scalars.
  void fill_gradient_targets(PetscScalar *m, bool in_adjoint, PetscReal **gk) {
    for (int k = 0; k < NP; ++k) {
      gk[k] = nullptr;
      if (index_[k] < 0) continue;
      const ParamInfo &pi = params_->info(index_[k]);
      if (pi.kind == ParamKind::Field) gk[k] = reinterpret_cast<PetscReal *>(m + pi.local_offset);
      else if (in_adjoint) gk[k] = scalar_acc_[k].data();
      else {
        scratch_scalar_[k].assign(grid_->local_points(), 0.0);
        gk[k] = scratch_scalar_[k].data();
      }
    }
  }
  PetscErrorCode flush_scratch_scalars(Vec mu) {
    PetscFunctionBeginUser;
    for (int k = 0; k < NP; ++k)
      if (index_[k] >= 0 && params_->info(index_[k]).kind == ParamKind::Scalar && !scratch_scalar_[k].empty()) {
        PetscCall(params_->add_local_sum(mu, index_[k], sum(scratch_scalar_[k])));
        scratch_scalar_[k].clear();
      }
    PetscFunctionReturn(0);
  }
  static PetscReal sum(const std::vector<PetscReal> &a) {
    PetscReal s[4] = {0, 0, 0, 0};
    size_t i = 0;
    for (; i + 4 <= a.size(); i += 4) s[0] += a[i], s[1] += a[i + 1], s[2] += a[i + 2], s[3] += a[i + 3];
    for (; i < a.size(); ++i) s[0] += a[i];
    return (s[0] + s[1]) + (s[2] + s[3]);
  }

  // The gather at owned point (i, j): for each stencil offset o, G at the point j - o (when it exists)
  // differentiated with respect to the inputs at j, contracted with x there.
  template <int CLO, int CHI, bool CK, int... E>
  void gather_offsets(const pointwise::Frame &f, const PetscScalar *xl, const PetscScalar *xh, PetscInt at, PetscInt i,
                      PetscInt j, PetscInt nx, PetscInt ny, bool px, bool py, double *yv, double *zv, double *gv,
                      std::integer_sequence<int, E...>) const {
    (gather_one<Sten::offset(E)[0], Sten::offset(E)[1], CLO, CHI, CK>(f, xl, xh, at, i, j, nx, ny, px, py, yv, zv, gv), ...);
  }
  template <int OX, int OY, int CLO, int CHI, bool CK>
  void gather_one(const pointwise::Frame &f, const PetscScalar *xl, const PetscScalar *xh, PetscInt at, PetscInt i,
                  PetscInt j, PetscInt nx, PetscInt ny, bool px, bool py, double *yv, double *zv, double *gv) const {
    const PetscInt si = i - OX, sj = j - OY;
    if constexpr (CK) {
      if (!px && (si < 0 || si >= nx)) return;
      if (D == 2 && !py && (sj < 0 || sj >= ny)) return;
    }
    const PetscInt sat = at - OX - OY * f.sy;
    typename Pt<Mode::Gather, OX, OY, CK>::Number gd[C + H];
    eq_.rhs(Pt<Mode::Gather, OX, OY, CK>(f, sat, si, sj, i, j), gd);
    auto contract = [&](const auto &g, double xc) {
      for (int cc = 0; cc < C; ++cc) yv[cc] += g.d[cc] * xc;
      for (int k = 0; k < K; ++k) zv[k] += g.d[C + k] * xc;
      for (int k = 0; k < NP; ++k) gv[k] += g.d[C + K + k] * xc;
    };
    for (int c = CLO; c < CHI; ++c) contract(gd[c], PetscRealPart(xl[sat * C + c]));
    for (int m = 0; m < H; ++m) contract(gd[C + m], PetscRealPart(xh[sat * H + m]));
  }

  // The structurally nonzero entries of a row block (stencil entry, output, input component): those
  // nonzero at random state and parameters at any owned point, or at any point on any rank.
  FLEXIPDE_SWEEP PetscErrorCode find_pattern() {
    OwnedVec Ur, Pr;
    PetscFunctionBeginUser;
    if constexpr (!Local) PetscFunctionReturn(0);
    else {
    PetscCall(VecDuplicate(st_.u, Ur.out()));
    PetscCall(VecDuplicate(P_, Pr.out()));
    {
      PetscRandom rnd;
      PetscCall(PetscRandomCreate(PETSC_COMM_SELF, &rnd));
      PetscCall(PetscRandomSetInterval(rnd, 0.5, 1.5));
      PetscCall(VecSetRandom(Ur, rnd));
      PetscCall(VecSetRandom(Pr, rnd));
      PetscCall(PetscRandomDestroy(&rnd));
    }
    std::vector<int> local(Sten::size * C * C, 0);
    {
      ConstArray u(Ur), p(Pr);
      const pointwise::Frame f = frame(0.5, u.data(), p.data());
      for_points(R, [&](PetscInt at, PetscInt, PetscInt i, PetscInt j, auto ck) {
        typename Pt<Mode::Rows>::Number gd[C];
        eq_.rhs(Pt<Mode::Rows, 0, 0, decltype(ck)::value>(f, at, i, j), gd);
        for (int c = 0; c < C; ++c)
          for (int l = 0; l < Sten::size * C; ++l)
            if (gd[c].d[l] != 0) local[(l / C) * C * C + c * C + l % C] = 1;
      });
    }
    pattern_.assign(local.size(), 0);
    PetscCallMPI(MPI_Allreduce(local.data(), pattern_.data(), (int)local.size(), MPI_INT, MPI_MAX, grid_->comm()));
    }
    PetscFunctionReturn(0);
  }
  FLEXIPDE_SWEEP PetscErrorCode assemble_rows(PetscReal t, Vec Uloc, Mat J, PetscReal *gersh) {
    PetscFunctionBeginUser;
    if constexpr (!Local) PetscFunctionReturn(0);
    else {
    ConstArray u(Uloc), p(P_);
    PetscCall(u.error());
    const pointwise::Frame f = frame(t, u.data(), p.data());
    PetscErrorCode ierr = 0;
    for_points(R, [&](PetscInt at, PetscInt, PetscInt i, PetscInt j, auto ck) {
      if (ierr) return;
      typename Pt<Mode::Rows>::Number gd[C];
      eq_.rhs(Pt<Mode::Rows, 0, 0, decltype(ck)::value>(f, at, i, j), gd);
      for (int c = 0; c < C; ++c) {
        MatStencil row{};
        row.i = i, row.j = j, row.c = c;
        MatStencil cols[Sten::size * C];
        PetscScalar vals[Sten::size * C];
        PetscInt nc = 0;
        double diag = 0, off = 0;
        for (int e = 0; e < Sten::size; ++e) {
          const auto o = Sten::offset(e);
          const PetscInt ci = i + o[0], cj = j + o[1];
          const bool outside = (!f.periodic[0] && (ci < 0 || ci >= f.n[0])) || (D == 2 && !f.periodic[1] && (cj < 0 || cj >= f.n[1]));
          for (int cc = 0; cc < C; ++cc) {
            if (!pattern_[e * C * C + c * C + cc] || outside) continue;
            const double v = gd[c].d[e * C + cc];
            cols[nc].i = ci, cols[nc].j = cj, cols[nc].k = 0, cols[nc].c = cc;
            vals[nc++] = v;
            if (e == 0 && cc == c) diag += v;
            else off += std::fabs(v);
          }
        }
        if (J) ierr = MatSetValuesStencil(J, 1, &row, nc, cols, vals, ADD_VALUES);
        if (gersh) { // the disc {|z - diag| <= off} inside {|z + a| <= a} when diag <= 0 and off <= -diag
          const double a = -diag;
          gersh[0] = std::max(gersh[0], std::fabs(diag) + off);
          if (diag > 0 || off > a * (1 + 1e-12)) gersh[2] = 1;
          else gersh[1] = std::max(gersh[1], a);
        }
      }
    });
    PetscCall(ierr);
    }
    PetscFunctionReturn(0);
  }
  PetscErrorCode gershgorin(Spectrum *s) {
    PetscReal local[3] = {0, 0, 0}, global[3]; // max |diag| + off; max a; any disc not in the left disc
    PetscFunctionBeginUser;
    if (pattern_.empty()) PetscCall(find_pattern());
    PetscCall(assemble_rows(0, st_.u, nullptr, local));
    PetscCallMPI(MPI_Allreduce(local, global, 3, MPIU_REAL, MPI_MAX, grid_->comm()));
    *s = Spectrum();
    if (global[2] == 0 && global[1] > 0) { // every disc in {|z + a| <= a}: its boundary
      const PetscReal a = global[1];
      for (int k = 0; k < 64; ++k) {
        const PetscReal th = 2 * PETSC_PI * k / 64;
        s->samples.emplace_back(-a + a * std::cos(th), a * std::sin(th));
      }
    } else s->imag_radius = s->real_radius = global[0];
    PetscFunctionReturn(0);
  }

  static PetscErrorCode jmf_mult(Mat A, Vec x, Vec y) {
    PointwiseModel *m;
    PetscFunctionBeginUser;
    PetscCall(MatShellGetContext(A, &m));
    PetscCall(m->tangent(0, m->jac_, x, nullptr, y));
    PetscFunctionReturn(0);
  }
  static PetscErrorCode jmf_mult_transpose(Mat A, Vec x, Vec y) {
    PointwiseModel *m;
    PetscFunctionBeginUser;
    PetscCall(MatShellGetContext(A, &m));
    PetscCall(m->transpose(0, m->jac_, x, y, false, 1.0, nullptr, false));
    PetscFunctionReturn(0);
  }
  static PetscErrorCode jp_mult(Mat A, Vec dp, Vec y) {
    PointwiseModel *m;
    PetscFunctionBeginUser;
    PetscCall(MatShellGetContext(A, &m));
    PetscCall(m->tangent(m->jp_t_, m->jp_, nullptr, dp, y));
    PetscFunctionReturn(0);
  }
  static PetscErrorCode jp_mult_transpose(Mat A, Vec x, Vec mu) {
    PointwiseModel *m;
    PetscFunctionBeginUser;
    PetscCall(MatShellGetContext(A, &m));
    PetscCall(VecSet(mu, 0.0));
    PetscCall(m->transpose(m->jp_t_, m->jp_, x, nullptr, false, 1.0, mu, false));
    PetscFunctionReturn(0);
  }

  Eq eq_;
  const Grid *grid_ = nullptr;
  DM dm_ = nullptr;
  const Parameters *params_ = nullptr;
  PetscInt index_[NP > 0 ? NP : 1] = {};
  PetscReal fixed_[NP > 0 ? NP : 1] = {};
  OwnedDM param_dm_, matrix_dm_, aux_dm_, out_dm_;
  OwnedVec P_, dP_, Pg_, Xl_;
  LocalState st_, jac_, jp_; // the state of rhs and the adjoint sweeps, of the Jacobian, of dG/dp
  OwnedVec Ag_, dAl_, Zg_, Hg_, XHl_, field_, Yt_; // non-local maps: their fields and scratch
  PetscReal jp_t_ = 0;
  ParameterBounds bounds_;
  const PointSource *source_ = nullptr;
  pointwise::Frame frame_;
  std::vector<int> pattern_;
  std::vector<std::vector<PetscReal>> scalar_acc_;
  std::vector<PetscReal> scratch_scalar_[NP > 0 ? NP : 1];
  bool in_adjoint_ = false;
};

} // namespace flexipde
