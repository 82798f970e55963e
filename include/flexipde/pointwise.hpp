// The pointwise stencil layer: a model states G at one grid point, once; flexipde derives the rest.
//
// A model is a class `Eq` (see src/models/burgers.cpp and docs/adding_a_model.md) that says
//   static constexpr int dim, components, radius, parameters;   and optionally  shape (star/box),
//   linear (G linear in U), second_order_pairs (m: G_q = p, G_p = a(q) - sigma(x) p),
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
// Parameter vectors (Declarations::vector: one name, many entries, e.g. the weights of a learned
// flux) are held once per rank instead and read with pt.theta(e). Lanes per entry would make their
// transposes cost O(entries) per point; instead rhs() is evaluated at reverse-mode numbers
// (reverse.hpp) with the entries as the tape's inputs, point by point, and one backward pass gives
// sum_i x(i)^T dG(i)/dtheta for all entries at a cost independent of their number.
//
// A conservation law may be stated in flux form instead of rhs():
//   G_c = S_c - sum_d (div_d F_d)_c,   h_d (div_d F)_i = sum_k w_k F(i - n/2 + k + 1/2)   (k < n)
//   template <class P, int d> void flux(const P &pt, Direction<d>, typename P::Number *F) const;
//                                       F_d at the face between the point and its neighbour at +1 along d,
//                                       reading along d alone, the points i - n/2 + 1 ... i + n/2 ... of it
//   static constexpr std::array<double, n> divergence();   the weights w (the scheme's divergence)
//   template <class P> void source(const P &pt, typename P::Number *s) const;   S (optional)
//   static constexpr bool flux_form;   (optional: false leaves a model that also has rhs() on rhs())
// G is then that sum everywhere. The transposes gain most: a gather differentiates each face once per
// point it reads, (dF_f/dU(j))^T times the weights' combination of x at the points f enters, where
// the gather of G would form every face of G at each of the 2R + 1 points G(j - o).
//
// Ghost width: the transposes evaluate G at the neighbours of owned points, whose stencils reach
// 2 * radius from them; the state DM therefore has 2 * radius ghosts, the assembled Jacobian radius.
#pragma once
#include "flexipde/halo.hpp"
#include "flexipde/dual.hpp"
#include "flexipde/model.hpp"
#include "flexipde/leapfrog.hpp"
#include "flexipde/reverse.hpp"
#include "flexipde/survey.hpp"
#include <algorithm>
#include <array>
#include <cmath>
#include <deque>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

// The sweeps inline everything they call, the model's pointwise functions above all: only then do
// the zero lanes of seeds placed elsewhere fold away. FLEXIPDE_RUN marks the loop over the runs of
// points of one kind: a function of its own, so that each stays small enough for the compiler's
// passes (one function per sweep holding every kind of point took minutes to compile).
#define FLEXIPDE_SWEEP __attribute__((flatten))
#define FLEXIPDE_RUN __attribute__((flatten, noinline))

namespace flexipde {

enum class StencilShape { Star, Box };
// The direction d of a face flux (Eq::flux), known at compile time.
template <int d> using Direction = std::integral_constant<int, d>;
namespace pointwise {
template <class F, int... d> inline void each_direction(F &f, std::integer_sequence<int, d...>) { (f(Direction<d>()), ...); }
} // namespace pointwise
// f(Direction<0>()), ..., f(Direction<D - 1>()): a sum over directions whose index is a constant in
// each copy of the body. A model's rhs() writes its loops over directions with it, so that the sweeps
// see straight-line code whatever the body's size, and their point loops vectorise (a loop the
// compiler leaves rolled picks each neighbour by a branch on d).
template <int D, class F> inline void for_each_direction(F &&f) {
  pointwise::each_direction(f, std::make_integer_sequence<int, D>());
}

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
  // A parameter vector `name` with these defaults (its length). Returns the offset of its first entry:
  // rhs() and initial() read entry e as pt.theta(offset + e).
  PetscInt vector(const std::string &name, const std::vector<PetscReal> &initial, PetscReal lower = PETSC_NINFINITY) {
    const PetscInt offset = theta_count_;
    vectors_.push_back({params_.add_vector(name, initial, lower), offset, (PetscInt)initial.size()});
    theta_count_ += (PetscInt)initial.size();
    return offset;
  }
  struct VectorSlot {
    PetscInt index, offset, entries;
  };
  const std::vector<VectorSlot> &vectors() const { return vectors_; }
  PetscInt theta_count() const { return theta_count_; }

private:
  std::vector<VectorSlot> vectors_;
  PetscInt theta_count_ = 0;
  Parameters &params_;
  std::vector<PetscInt> index_;
  std::vector<PetscReal> fixed_;
};

namespace pointwise {

// Compile-time stencil offsets: entry e of a star or box stencil of the given radius in D dimensions.
template <int D, int R, StencilShape S>
struct Stencil {
  static constexpr int width = 2 * R + 1;
  static constexpr int size = S == StencilShape::Star ? 1 + 2 * R * D : (D == 1 ? width : D == 2 ? width * width : width * width * width);
  static constexpr std::array<int, 3> offset(int e) {
    if constexpr (S == StencilShape::Star) {
      if (e == 0) return {0, 0, 0};
      const int d = (e - 1) / (2 * R), k = (e - 1) % (2 * R), o = k < R ? k - R : k - R + 1;
      return {d == 0 ? o : 0, d == 1 ? o : 0, d == 2 ? o : 0};
    } else {
      return {e % width - R, D == 1 ? 0 : (e / width) % width - R, D == 3 ? e / (width * width) - R : 0};
    }
  }
  static constexpr int entry(int dx, int dy, int dz = 0) {
    for (int e = 0; e < size; ++e)
      if (offset(e)[0] == dx && offset(e)[1] == dy && offset(e)[2] == dz) return e;
    return -1;
  }
};

enum class Mode { Value, Tangent, Rows, Gather };

// Everything a sweep reads around one point (x fastest, components interleaved). The state and its
// direction are read in place from the owned block (index `own`, row length `syo`, plane size `szo`)
// and, beyond it, from ghosted arrays whose ghost entries alone are filled (index `at`, row length
// `sy`, plane size `sz`); parameters and auxiliary fields are ghosted arrays (index `at`).
struct Frame {
  const PetscScalar *U = nullptr;  // state, owned block
  const PetscScalar *Ug = nullptr; // state, ghosted (ghost entries)
  const PetscScalar *X = nullptr;  // direction of the state (Tangent), or the transpose's x (Gather); null: 0
  const PetscScalar *Xg = nullptr; // the same, ghosted (ghost entries)
  const PetscScalar *P = nullptr;  // parameters, `np` per point
  const PetscScalar *dP = nullptr; // direction of the parameters (Tangent; null: 0)
  const PetscScalar *A = nullptr;  // auxiliary fields a = L U, `na` per point (non-local linear maps of the state)
  const PetscScalar *dA = nullptr; // their direction L X (Tangent; null: 0)
  // Auxiliary fields of x alone (Eq::auxiliaries_from_column_sums; Point's KL): A and dA are lines,
  // K per grid column, indexed by the global i + line_pad.
  PetscInt line_pad = 0;
  const PetscReal *theta = nullptr, *dtheta = nullptr; // parameter vectors' entries, and their direction
  const PetscReal *pconst = nullptr; // the parameters' values when every one G reads is a constant (Point's SC)
  PetscInt np = 0, na = 0, sy = 0, syo = 0, sz = 0, szo = 0;
  PetscInt xs = 0, ys = 0, zs = 0, xm = 0, ym = 1, zm = 1; // the owned block
  PetscReal t = 0;
  PetscReal h[3] = {1, 1, 1}, ih[3] = {1, 1, 1}, x0[3] = {0, 0, 0};
  PetscInt n[3] = {1, 1, 1};
  bool periodic[3] = {false, false, false};
  // Beyond a wall the state is the odd reflection of the inside (u = 0 on the wall, fourth-order
  // stencils stay consistent next to it), else 0.
  bool odd[3] = {false, false, false};
  // Wall points are held (no equation, value 0): the stencils read them as 0 whatever the state holds.
  bool held = false;
  // For each position of the ghosted box: the ghosted index of the point whose value it holds (itself,
  // or its mirror image beyond an odd wall; -1: 0 there) and the sign it is read with. Checked points
  // read through it from ghosted arrays whose ghosts and edge strips are filled.
  const PetscInt *src = nullptr;
  const double *sgn = nullptr;
  int dim = 1;
  int coef0 = 0; // where the coefficient fields start among the `np` entries of P (after the parameters)
};

// The point view handed to a model's rhs() and initial(). Mode and seeds decide what a Number is:
//   Value    double;  Tangent  Dual<double, 1> in the direction (X, dP);
//   Rows     Dual<double, E * C>, lane e * C + c for state component c at stencil entry e;
//   Gather   Dual<double, C + K + NP>, lanes c for U_c, C + k for auxiliary field k and C + K + k for
//            parameter k, at offset (SX, SY, SZ) only.
// CK: the point is near a wall or the ghost band, and every read is checked: positions beyond a wall
// are reflected or zero, and (Gather) the seeded input is found by its position (ti, tj, tk) at run time.
// CS < C: the state arrays hold the first CS components alone (a second-order model's positions), and
// the others read as 0. NP: the parameters with a lane (those G reads: Eq::rhs_parameters, the first ones).
// KL: the auxiliary fields are lines (Frame::line_pad).
// WL: the point may lie on a wall (wall() is tested; else a compile-time false): every checked point,
// and the neighbours a gather evaluates G at from a point within R of a wall.
// SC: every parameter G reads is a scalar (or fixed): its value is a constant of the sweep (Frame::pconst),
// which the compiler keeps in a register and shares between the evaluations of a gather, and a gather
// differentiates it in the evaluation at the target point alone, with respect to its reads at every
// offset (the sum over the points of a scalar's gradient is all that is wanted).
// Offsets along y and z default to 0: a model's rhs() reads pt.u(c, dx), pt.u(c, dx, dy) or
// pt.u(c, dx, dy, dz) by its dimension.
template <int C, int K, int NP, class Sten, Mode M, int SX = 0, int SY = 0, bool CK = false, int CS = C, bool WL = CK,
          bool KL = false, bool SC = false, int SZ = 0>
class Point {
public:
  using Number = std::conditional_t<
      M == Mode::Value, double,
      std::conditional_t<M == Mode::Tangent, Dual<double, 1>,
                         std::conditional_t<M == Mode::Rows, Dual<double, Sten::size * C>, Dual<double, C + K + NP>>>>;
  Point(const Frame &f, PetscInt at, PetscInt own, PetscInt i, PetscInt j, PetscInt k, PetscInt ti = 0, PetscInt tj = 0,
        PetscInt tk = 0)
      : f_(f), at_(at), own_(own), i_(i), j_(j), k_(k), ti_(ti), tj_(tj), tk_(tk) {}

  // State component c at offset (dx, dy, dz) from the point.
  Number u(int c, int dx, int dy = 0, int dz = 0) const {
    if constexpr (CS < C)
      if (c >= CS) return unstored(c, dx, dy, dz);
    if constexpr (CK) return u_checked(c, dx, dy, dz);
    const PetscInt k = (own_ + dx + dy * f_.syo + dz * f_.szo) * CS + c;
    const double v = PetscRealPart(f_.U[k]);
    if constexpr (M == Mode::Value) return v;
    else if constexpr (M == Mode::Tangent) {
      Number r(v);
      r.d[0] = f_.X ? PetscRealPart(f_.X[k]) : 0.0;
      return r;
    } else if constexpr (M == Mode::Rows) return Number::seeded(v, Sten::entry(dx, dy, dz) * C + c);
    else return dx == SX && dy == SY && dz == SZ ? Number::seeded(v, c) : Number(v);
  }
  // Parameter k (a field's value at the offset; a scalar's value anywhere).
  Number param(int k, int dx = 0, int dy = 0, int dz = 0) const {
    if constexpr (SC && M == Mode::Value) return f_.pconst[k];
    else if constexpr (SC && M == Mode::Gather) {
      const bool seed = k < NP && (CK ? i_ == ti_ && j_ == tj_ && k_ == tk_ : SX == 0 && SY == 0 && SZ == 0);
      return seed ? Number::seeded(f_.pconst[k], C + K + k) : Number(f_.pconst[k]);
    } else return field(f_.P, f_.dP, f_.np, k, k < NP ? C + K + k : -1, dx, dy, dz);
  }
  // Coefficient field k (Eq::coefficients: fixed by the geometry, computed once) at the offset: a constant.
  Number coefficient(int k, int dx = 0, int dy = 0, int dz = 0) const {
    return field(f_.P, nullptr, f_.np, f_.coef0 + k, -1, dx, dy, dz);
  }
  // Auxiliary field k (Eq::auxiliaries: a = L U from the model's non-local linear maps) at the offset.
  Number aux(int k, int dx = 0, int dy = 0, int dz = 0) const {
    static_assert(M != Mode::Rows, "a model with auxiliary fields has no assembled Jacobian");
    if constexpr (KL) return line(k, dx);
    return field(f_.A, f_.dA, K, k, C + k, dx, dy, dz);
  }
  // Entry e of the parameter vectors (Declarations::vector). In Rows and Gather modes a constant: their
  // transposes come from the reverse sweep (ReversePoint).
  Number theta(int e) const {
    if constexpr (M == Mode::Tangent) {
      Number r(f_.theta[e]);
      r.d[0] = f_.dtheta ? f_.dtheta[e] : 0.0;
      return r;
    } else return Number(f_.theta[e]);
  }
  PetscReal t() const { return f_.t; }
  PetscInt index(int d = 0) const { return d == 0 ? i_ : d == 1 ? j_ : k_; }
  PetscReal h(int d = 0) const { return f_.h[d]; }
  PetscReal inv_h(int d = 0) const { return f_.ih[d]; } // 1/h: a product instead of a division per point
  PetscReal x(int d = 0) const { return f_.x0[d] + index(d) * f_.h[d]; }
  PetscInt points(int d = 0) const { return f_.n[d]; }
  // True on a non-periodic direction's first (side 0) or last (side 1) point.
  bool wall(int d, int side) const {
    if (!WL || f_.periodic[d]) return false;
    const PetscInt i = index(d);
    return side == 0 ? i == 0 : i == f_.n[d] - 1;
  }
  bool on_wall() const {
    return wall(0, 0) || wall(0, 1) || (f_.dim > 1 && (wall(1, 0) || wall(1, 1))) || (f_.dim > 2 && (wall(2, 0) || wall(2, 1)));
  }
  bool on_wall_at(int d, PetscInt g) const { return !f_.periodic[d] && (g == 0 || g == f_.n[d] - 1); }

private:
  // The ghosted index of the point at the offset.
  PetscInt ghosted(int dx, int dy, int dz) const { return at_ + dx + dy * f_.sy + dz * f_.sz; }
  // Whether the gather's seeded input is the point at this offset.
  bool target(int dx, int dy, int dz) const {
    if constexpr (CK) return i_ + dx == ti_ && j_ + dy == tj_ && k_ + dz == tk_;
    return dx == SX && dy == SY && dz == SZ;
  }
  // The ghosted index of the gather's seeded input (checked points).
  PetscInt target_at() const { return at_ + (ti_ - i_) + (tj_ - j_) * f_.sy + (tk_ - k_) * f_.sz; }
  // Entry k of a ghosted array with `stride` entries per point (a; its direction da in Tangent mode) at
  // the offset, 0 beyond a wall; in Gather mode seeded at `lane` (>= 0) when the offset is the seed's.
  Number field(const PetscScalar *a, const PetscScalar *da, PetscInt stride, int k, int lane, int dx, int dy, int dz) const {
    const PetscInt at = ghosted(dx, dy, dz) * stride + k;
    const double v = PetscRealPart(a[at]);
    if constexpr (M == Mode::Tangent) {
      Number r(v);
      r.d[0] = da ? PetscRealPart(da[at]) : 0.0;
      return r;
    } else if constexpr (M == Mode::Gather) {
      const bool seed = lane >= 0 && target(dx, dy, dz);
      return seed ? Number::seeded(v, lane) : Number(v);
    } else return v;
  }
  // Auxiliary line k at column i + dx (the padded line holds 0 beyond a wall). A gather seeds it at
  // the target in the point's own row, so that each read is counted once in the column sums of
  // (dG/da)^T x.
  Number line(int k, int dx) const {
    const PetscInt gi = i_ + dx;
    const PetscInt at = (gi + f_.line_pad) * K + k;
    const double v = PetscRealPart(f_.A[at]);
    if constexpr (M == Mode::Tangent) {
      Number r(v);
      r.d[0] = f_.dA ? PetscRealPart(f_.dA[at]) : 0.0;
      return r;
    } else if constexpr (M == Mode::Gather) {
      const bool seed = CK ? gi == ti_ && j_ == tj_ && k_ == tk_ : dx == SX && SY == 0 && SZ == 0;
      return seed ? Number::seeded(v, C + k) : Number(v);
    } else return v;
  }
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
  // A component the state arrays do not hold (G is linear in it, and its derivatives read nothing of
  // it): 0, with its derivative lane in Gather mode.
  Number unstored(int c, int dx, int dy, int dz) const {
    if constexpr (M == Mode::Gather) {
      if constexpr (CK) {
        const PetscInt p = ghosted(dx, dy, dz), s = f_.src[p];
        Number r(0.0);
        if (s >= 0 && s == target_at()) r.d[c] = f_.sgn[p];
        return r;
      } else return target(dx, dy, dz) ? Number::seeded(0.0, c) : Number(0.0);
    }
    return Number(0.0);
  }
  Number u_checked(int c, int dx, int dy, int dz) const {
    if constexpr (M != Mode::Rows) {
      const PetscInt p = ghosted(dx, dy, dz), s = f_.src[p];
      if (s < 0) return Number(0.0);
      const double sign = f_.sgn[p], v = sign * PetscRealPart(f_.Ug[s * CS + c]);
      if constexpr (M == Mode::Value) return v;
      else {
        Number r(v);
        if constexpr (M == Mode::Tangent) r.d[0] = f_.Xg ? sign * PetscRealPart(f_.Xg[s * CS + c]) : 0.0;
        else if (s == target_at()) r.d[c] = sign;
        return r;
      }
    }
    PetscInt gi = i_ + dx, gj = j_ + dy, gk = k_ + dz;
    double sign = 1;
    if (!fold(0, gi, sign) || !fold(1, gj, sign) || !fold(2, gk, sign)) return Number(0.0);
    if (f_.held && (on_wall_at(0, gi) || (f_.dim > 1 && on_wall_at(1, gj)) || (f_.dim > 2 && on_wall_at(2, gk))))
      return Number(0.0);
    const bool owned = gi >= f_.xs && gi < f_.xs + f_.xm && gj >= f_.ys && gj < f_.ys + f_.ym && gk >= f_.zs &&
                       gk < f_.zs + f_.zm;
    const PetscInt k = owned ? ((gk - f_.zs) * f_.szo + (gj - f_.ys) * f_.syo + gi - f_.xs) * CS + c
                             : ghosted((int)(gi - i_), (int)(gj - j_), (int)(gk - k_)) * CS + c;
    const double v = sign * PetscRealPart((owned ? f_.U : f_.Ug)[k]);
    if constexpr (M == Mode::Value) return v;
    else {
      Number r(v);
      if constexpr (M == Mode::Tangent) {
        const PetscScalar *x = owned ? f_.X : f_.Xg;
        r.d[0] = x ? sign * PetscRealPart(x[k]) : 0.0;
      }
      else if constexpr (M == Mode::Rows) r.d[Sten::entry((int)(gi - i_), (int)(gj - j_), (int)(gk - k_)) * C + c] = sign;
      else if (gi == ti_ && gj == tj_ && gk == tk_) r.d[c] = sign;
      return r;
    }
  }

  const Frame &f_;
  PetscInt at_, own_, i_, j_, k_, ti_, tj_, tk_;
};

// The point view of the reverse sweep: Rev numbers whose tape inputs are the parameter vectors'
// entries (input e: entry e); the state and the per-point parameters are constants.
template <int C, int K, int NP, class Sten, bool CK, int CS = C, bool KL = false>
class ReversePoint : public Point<C, K, NP, Sten, Mode::Value, 0, 0, CK, CS, CK, KL> {
  using Base = Point<C, K, NP, Sten, Mode::Value, 0, 0, CK, CS, CK, KL>;

public:
  using Number = Rev;
  using Base::Base;
  Number u(int c, int dx, int dy = 0, int dz = 0) const { return Base::u(c, dx, dy, dz); }
  Number param(int k, int dx = 0, int dy = 0, int dz = 0) const { return Base::param(k, dx, dy, dz); }
  Number aux(int k, int dx = 0, int dy = 0, int dz = 0) const { return Base::aux(k, dx, dy, dz); }
  Number coefficient(int k, int dx = 0, int dy = 0, int dz = 0) const { return Base::coefficient(k, dx, dy, dz); }
  Number theta(int e) const { return Rev::input(Base::theta(e), e); }
};

// The view of a face: point p's reads shifted by (SX, SY, SZ), so that a face flux is stated at its
// left point and evaluated at any face of a point's stencil.
template <class P, int SX, int SY, int SZ = 0> class Shifted {
  static constexpr int shift(int d) { return d == 0 ? SX : d == 1 ? SY : SZ; }

public:
  using Number = typename P::Number;
  explicit Shifted(const P &p) : p_(p) {}
  Number u(int c, int dx, int dy = 0, int dz = 0) const { return p_.u(c, dx + SX, dy + SY, dz + SZ); }
  Number param(int k, int dx = 0, int dy = 0, int dz = 0) const { return p_.param(k, dx + SX, dy + SY, dz + SZ); }
  Number coefficient(int k, int dx = 0, int dy = 0, int dz = 0) const { return p_.coefficient(k, dx + SX, dy + SY, dz + SZ); }
  Number theta(int e) const { return p_.theta(e); }
  PetscReal t() const { return p_.t(); }
  PetscInt index(int d = 0) const { return p_.index(d) + shift(d); }
  PetscReal h(int d = 0) const { return p_.h(d); }
  PetscReal inv_h(int d = 0) const { return p_.inv_h(d); }
  PetscReal x(int d = 0) const { return p_.x(d) + shift(d) * p_.h(d); }
  PetscInt points(int d = 0) const { return p_.points(d); }

private:
  const P &p_;
};

// The view of a face along x for its transposes, at its left point p: each read at offset dx
// (-RF < dx <= RF) is an input with lanes of its own, (dx + RF - 1) * S + c for state component c and
// ... + C + k for parameter k < NL (S = C + NL); other parameters, coefficients and parameter vectors
// are constants. One evaluation gives the face's derivatives with respect to every point it reads.
template <class P, int C, int NL, int RF> class FaceInputs {
public:
  static constexpr int S = C + NL;
  using Number = Dual<double, 2 * RF * S>;
  explicit FaceInputs(const P &p) : p_(p) {}
  Number u(int c, int dx, int dy = 0, int dz = 0) const { return Number::seeded(p_.u(c, dx, dy, dz), (dx + RF - 1) * S + c); }
  Number param(int k, int dx = 0, int dy = 0, int dz = 0) const {
    const double v = p_.param(k, dx, dy, dz);
    return k < NL ? Number::seeded(v, (dx + RF - 1) * S + C + k) : Number(v);
  }
  Number coefficient(int k, int dx = 0, int dy = 0, int dz = 0) const { return Number(p_.coefficient(k, dx, dy, dz)); }
  Number theta(int e) const { return Number(p_.theta(e)); }
  PetscReal t() const { return p_.t(); }
  PetscInt index(int d = 0) const { return p_.index(d); }
  PetscReal h(int d = 0) const { return p_.h(d); }
  PetscReal inv_h(int d = 0) const { return p_.inv_h(d); }
  PetscReal x(int d = 0) const { return p_.x(d); }
  PetscInt points(int d = 0) const { return p_.points(d); }

private:
  const P &p_;
};

template <class Eq, class = void> struct HasSource : std::false_type {};
template <class Eq>
struct HasSource<Eq, std::void_t<decltype(std::declval<const Eq &>().source(
                         std::declval<const Point<1, 0, 0, Stencil<1, 1, StencilShape::Star>, Mode::Value> &>(), (double *)nullptr))>>
    : std::true_type {};
template <class Eq, class = void> struct FluxFormOf : std::false_type {};
template <class Eq> struct FluxFormOf<Eq, std::void_t<decltype(Eq::divergence())>> : std::true_type {};
template <class Eq, class = void> struct FluxFlagOf : std::true_type {};
template <class Eq> struct FluxFlagOf<Eq, std::void_t<decltype(Eq::flux_form)>> : std::bool_constant<Eq::flux_form> {};

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
template <class Eq, class = void> struct HasHeldWalls : std::false_type {};
template <class Eq> struct HasHeldWalls<Eq, std::void_t<decltype(std::declval<const Eq &>().held_walls())>> : std::true_type {};
template <class Eq, class = void> struct HasForcing : std::false_type {};
template <class Eq> struct HasForcing<Eq, std::void_t<decltype(Eq::forced_component)>> : std::true_type {};
template <class Eq>
struct PairsOf<Eq, std::void_t<decltype(Eq::second_order_pairs)>> : std::integral_constant<int, Eq::second_order_pairs> {};
// Non-local couplings: `auxiliaries` fields a_k = L_k U read at points (pt.aux), and `outputs` fields h_m
// written by rhs after the C components, entering G through G += B_m h_m (L, B: the model's linear maps).
template <class Eq, class = void> struct AuxOf : std::integral_constant<int, 0> {};
template <class Eq> struct AuxOf<Eq, std::void_t<decltype(Eq::auxiliaries)>> : std::integral_constant<int, Eq::auxiliaries> {};
// Auxiliary fields of x alone, made from the sums of the state over y (the moments of a kinetic model):
// a_k = L_k s with s(i) = sum_j U(i, j), L_k a map between lines (Eq::auxiliaries_from_column_sums).
template <class Eq, class = void> struct AuxFromColumnSums : std::false_type {};
template <class Eq>
struct AuxFromColumnSums<Eq, std::void_t<decltype(Eq::auxiliaries_from_column_sums)>>
    : std::bool_constant<Eq::auxiliaries_from_column_sums> {};
template <class Eq, class = void> struct RhsParametersOf : std::integral_constant<int, Eq::parameters> {};
template <class Eq>
struct RhsParametersOf<Eq, std::void_t<decltype(Eq::rhs_parameters)>> : std::integral_constant<int, Eq::rhs_parameters> {};
// Coefficient fields: functions of the geometry alone that G reads at points (pt.coefficient(k)), from
// Eq::coefficient(k, pt) evaluated once, so that a sweep reads them instead of recomputing them.
template <class Eq, class = void> struct CoefficientsOf : std::integral_constant<int, 0> {};
template <class Eq>
struct CoefficientsOf<Eq, std::void_t<decltype(Eq::coefficients)>> : std::integral_constant<int, Eq::coefficients> {};
template <class Eq, class = void> struct OutputsOf : std::integral_constant<int, 0> {};
template <class Eq> struct OutputsOf<Eq, std::void_t<decltype(Eq::outputs)>> : std::integral_constant<int, Eq::outputs> {};
// Optional model statements for the initial condition and the forcing: the integrator's step
// (set_time_step(dt)), a check before U0 is made (check_initial(comm)), and the points a point source
// forces (forced(i, j, k), global indices; by default every point).
template <class Eq, class = void> struct HasTimeStep : std::false_type {};
template <class Eq>
struct HasTimeStep<Eq, std::void_t<decltype(std::declval<Eq &>().set_time_step(PetscReal()))>> : std::true_type {};
template <class Eq, class = void> struct HasCheckInitial : std::false_type {};
template <class Eq>
struct HasCheckInitial<Eq, std::void_t<decltype(std::declval<const Eq &>().check_initial(MPI_Comm()))>> : std::true_type {};
// A field parameter that G reads through a symmetric linear map M of it (advection's spectral D: its
// 2/3-rule truncation): maps_parameter(k) says which, map_parameter(k, f) applies f = M f in place (f on
// the grid's DM). The sweeps read M p_k, and its gradient is M g, g the pointwise one.
template <class Eq, class = void> struct HasParameterMap : std::false_type {};
template <class Eq>
struct HasParameterMap<Eq, std::void_t<decltype(std::declval<const Eq &>().map_parameter(0, Vec()))>> : std::true_type {};
template <class Eq, class = void> struct HasForcedPoints : std::false_type {};
template <class Eq>
struct HasForcedPoints<Eq, std::void_t<decltype(std::declval<const Eq &>().forced(PetscInt(), PetscInt(), PetscInt()))>> : std::true_type {};
// Optional named functionals of the state (Model::functional): `functional_names()` and
// `functional(name, U, value, dFdU)`, forwarded as the model states them.
template <class Eq, class = void> struct HasFunctionals : std::false_type {};
template <class Eq>
struct HasFunctionals<Eq, std::void_t<decltype(std::declval<const Eq &>().functional_names())>> : std::true_type {};
// Optional: the non-local maps all at once, for maps that share work (one forward transform for all
// the auxiliary fields): auxiliary_fields(U, a) (a[k] = L_k U), auxiliary_fields_transpose(z, y)
// (y += sum_k L_k^T z_k), output_fields(h, G) (G += sum_m B_m h_m) and output_fields_transpose(x, hx)
// (hx[m] = B_m^T x); each Vec one value per grid point. Without them the layer calls the per-field statements in turn.
template <class Eq, class = void> struct HasMapsAtOnce : std::false_type {};
template <class Eq>
struct HasMapsAtOnce<Eq, std::void_t<decltype(std::declval<const Eq &>().auxiliary_fields(Vec(), (const Vec *)nullptr))>>
    : std::true_type {};
// Optional, with the maps at once: the transposes of every auxiliary field's map applied to one x,
// auxiliary_fields_adjoint(x, w) (w[k] = L_k^T x, every k). When G is linear, its parameters are
// constants and it reads the auxiliary fields with coefficients that are the same at every point
// (G = g(U) + sum_k c_k a_k, found at run time), the layer applies sum_k c_k L_k^T x from these and
// forms the parameters' gradients from the pairings <L_k^T x, U>: the fields of U are then never
// formed in an adjoint, and x's transposes share one forward transform.
// Optional besides: a combination of the maps as one map, auxiliary_combination(r, x, y, transpose)
// (y = sum_k r_k L_k x, or sum_k r_k L_k^T x): one symbol for a spectral model, one forward and one
// backward transform, with the round-off of one map. The layer then applies G's coupling, its tangent
// and a transpose without gradient through it.
template <class Eq, class = void> struct HasAuxCombination : std::false_type {};
template <class Eq>
struct HasAuxCombination<Eq, std::void_t<decltype(std::declval<const Eq &>().auxiliary_combination(
                                  (const PetscScalar *)nullptr, Vec(), Vec(), false))>> : std::true_type {};
template <class Eq, class = void> struct HasAuxAdjoint : std::false_type {};
template <class Eq>
struct HasAuxAdjoint<Eq, std::void_t<decltype(std::declval<const Eq &>().auxiliary_fields_adjoint(Vec(), (const Vec *)nullptr))>>
    : std::true_type {};

} // namespace pointwise

// A Model made from pointwise equations: every product the integrators and adjoints ask for is a sweep
// of Eq::rhs at some number type.
template <class Eq>
class PointwiseModel final : public Model {
  static constexpr int D = Eq::dim, C = Eq::components, R = Eq::radius, NP = Eq::parameters;
  static constexpr int K = pointwise::AuxOf<Eq>::value, H = pointwise::OutputsOf<Eq>::value;
  // The auxiliary fields are lines (functions of x alone, from column sums), else fields on the grid.
  static constexpr bool KL = K > 0 && pointwise::AuxFromColumnSums<Eq>::value;
  static_assert(!KL || D == 2, "auxiliary fields from column sums need a 2D grid");
  // The parameters G reads (the first NG; the others enter U0 alone): the transposes carry lanes for those.
  static constexpr int NG = pointwise::RhsParametersOf<Eq>::value;
  static_assert(NG <= NP, "rhs_parameters: at most parameters");
  static constexpr bool Local = K == 0 && H == 0; // else dG/dU is applied, never assembled
  // G may be g(U) + sum_k c_k a_k with coefficients the same at every point (found when the parameters
  // are set: uniform_): pointwise::HasAuxAdjoint.
  static constexpr bool Coupling = C == 1 && K > 0 && !KL && H == 0 && pointwise::LinearOf<Eq>::value &&
                                   pointwise::HasMapsAtOnce<Eq>::value && pointwise::HasAuxAdjoint<Eq>::value;
  static constexpr int NF = pointwise::CoefficientsOf<Eq>::value; // held after the parameters in P_
  static constexpr StencilShape Shape = pointwise::ShapeOf<Eq>::value;
  using Sten = pointwise::Stencil<D, R, Shape>;
  // Flux form (Eq::divergence, Eq::flux): NFACE faces per point and direction, each reading the RF
  // points either side of it.
  static constexpr bool Flux = pointwise::FluxFormOf<Eq>::value && pointwise::FluxFlagOf<Eq>::value;
  template <class E = Eq> static constexpr auto divergence_of() {
    if constexpr (Flux) return E::divergence();
    else return std::array<double, 0>{};
  }
  static constexpr int NFACE = (int)divergence_of().size(), RF = R - NFACE / 2 + 1;
  static_assert(!Flux || (K == 0 && H == 0 && pointwise::PairsOf<Eq>::value == 0),
                "flux form: no auxiliary fields, outputs or second-order pairs");
  static_assert(NFACE % 2 == 0 && (!Flux || NFACE == 0 || RF >= 1), "flux form: faces symmetric about the point, within the radius");
  using Mode = pointwise::Mode;
  template <Mode M, int SX = 0, int SY = 0, bool CK = false, int CS = C, bool WL = CK, bool SC = false, int SZ = 0>
  using Pt = pointwise::Point<C, K, NG, Sten, M, SX, SY, CK, CS, WL, KL, SC, SZ>;
  template <bool CK> using PtInitial = pointwise::Point<C, 0, NP, Sten, Mode::Gather, 0, 0, CK>;
  template <bool CK> using Check = std::integral_constant<bool, CK>;
  // How a point of a sweep reads (for_points<true>): in place from the owned block (0, Check<false>),
  // through the fold table (1, Check<true>: the points on a wall), or (2, Edge) from the ghosted arrays,
  // whose ghosts and owned edge strips hold every value it reads, mirror images and held walls
  // included, so that it needs no check either.
  using Edge = std::integral_constant<int, 2>;
  // ... an Edge point within R of a wall: (gather) its neighbours beyond the wall have no equation, and
  // those on it their wall's.
  using EdgeNearWall = std::integral_constant<int, 3>;
  static_assert(D >= 1 && D <= 3, "the grid is 1D, 2D or 3D");
  static_assert(Local || pointwise::PairsOf<Eq>::value == 0, "the leapfrog kick handles local models only");
  // A state as the sweeps read it: ghosted, with its auxiliary fields (K per point, ghosted) if any.
  struct LocalState {
    Vec ref = nullptr;  // the state itself (global layout): `copy`, or a Vec the caller holds
    OwnedVec copy, g, a; // a kept copy; ghosted with the ghost entries filled; auxiliary fields
    std::vector<PetscReal> line; // auxiliary lines (KL), K per column over [-line_pad, n + line_pad)
  };
  // The arrays of a state for a sweep's frame.
  struct StateView {
    StateView(const LocalState &s) : u(s.ref), g(s.g), a(s.a), line(s.line.data()) {}
    PetscErrorCode error() const { return u.error() ? u.error() : (g.error() ? g.error() : a.error()); }
    ConstArray u, g, a;
    const PetscReal *line;
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
    if constexpr (pointwise::HasParameterMap<Eq>::value)
      for (int k = 0; k < NP; ++k) mapped_[k] = index_[k] >= 0 && params.info(index_[k]).kind == ParamKind::Field && eq_.maps_parameter(k);
    vector_slots_ = decl.vectors();
    theta_.assign(decl.theta_count(), 0.0), dtheta_ = theta_acc_ = theta_;
    bounds_.min.assign(NP, 0.0), bounds_.max.assign(NP, 0.0); // until parameters are set (a spectrum may be asked first)
    PetscCall(grid.create_dm(NP + NF, param_dm_.out()));
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
    if constexpr (KL) {
      const size_t n = (size_t)grid.n();
      for (auto *s : {&st_, &jac_, &jp_}) s->line.assign((n + 2 * line_pad) * K, 0.0);
      dline_ = st_.line;
      sums_.assign(n * C, 0.0), zline_.assign(n * K, 0.0), wline_.assign(n * C, 0.0), aline_.assign(n, 0.0);
    } else if constexpr (K > 0) {
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
    if constexpr (pointwise::HasMapsAtOnce<Eq>::value) {
      map_fields_.resize(std::max(K, H));
      for (auto &v : map_fields_) PetscCall(DMCreateGlobalVector(grid.dm(), v.out()));
      for (auto &v : map_fields_) map_vecs_.push_back(v);
    }
    if constexpr (Coupling) {
      PetscInt n;
      PetscCall(VecGetLocalSize(dAl_, &n));
      zero_aux_.assign((size_t)n, 0.0);
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
      if (accumulated(k)) scalar_acc_[k].assign(grid.local_points(), 0.0);
    {
      PetscInt gxs, gys, gzs, gxm, gym, gzm;
      ghost_corners(gxs, gys, gzs, gxm, gym, gzm);
      frame_.sy = D >= 2 ? gxm : 0, frame_.sz = D == 3 ? gxm * gym : 0;
    }
    for (int d = 0; d < 3; ++d) {
      frame_.h[d] = grid.h(d), frame_.ih[d] = 1 / grid.h(d), frame_.x0[d] = grid.lower(d);
      frame_.n[d] = grid.n(d), frame_.periodic[d] = grid.periodic(d);
      if constexpr (pointwise::HasOddWalls<Eq>::value) frame_.odd[d] = eq_.odd_walls();
    }
    if constexpr (pointwise::HasHeldWalls<Eq>::value) frame_.held = eq_.held_walls();
    strip_ = 4 * R + 2, forward_strip_ = 2 * R + 2;
    forcing_sorted_ = false;
    make_fold_table();
    frame_.np = NP + NF, frame_.coef0 = NP;
    frame_.na = K;
    frame_.line_pad = line_pad;
    frame_.syo = grid.xm(), frame_.szo = D == 3 ? grid.xm() * grid.ym() : 0;
    frame_.xs = grid.xs(), frame_.ys = grid.ys(), frame_.zs = grid.zs();
    frame_.xm = grid.xm(), frame_.ym = grid.ym(), frame_.zm = grid.zm();
    if constexpr (NF > 0) {
      coefficients_.assign((size_t)grid.local_points() * NF, 0.0);
      for_points(0, [&](PetscInt at, PetscInt own, PetscInt i, PetscInt j, PetscInt k, auto ck) {
        for (int q = 0; q < NF; ++q)
          coefficients_[own * NF + q] = eq_.coefficient(q, Pt<Mode::Value, 0, 0, decltype(ck)::value>(frame_, at, own, i, j, k));
      });
    }
    PetscCall(ghosts_.create(dm_));
    if constexpr (pointwise::PairsOf<Eq>::value > 0) {
      PetscCall(grid.create_dm(pointwise::PairsOf<Eq>::value, pos_dm_.out()));
      PetscCall(pos_ghosts_.create(pos_dm_));
      PetscCall(lambda_ghosts_.create(pos_dm_));
      PetscCall(DMCreateLocalVector(pos_dm_, pos_.g.out()));
      PetscCall(VecSet(pos_.g, 0.0));
      PetscCall(DMCreateLocalVector(pos_dm_, lam_g_.out()));
      PetscCall(VecSet(lam_g_, 0.0));
      PetscCall(DMCreateGlobalVector(pos_dm_, pos_rec_.out()));
      PetscCall(DMCreateGlobalVector(pos_dm_, pos_copy_.out()));
    }
    frame_.dim = D;
    frame_.theta = theta_.data();
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
      if (mapped_[k]) PetscCall(map_parameter(k, f));
      PetscCall(VecStrideScatter(f, k, Pg_, INSERT_VALUES));
    }
    if constexpr (NF > 0) {
      Array g(Pg_);
      PetscCall(g.error());
      for (size_t q = 0; q < coefficients_.size() / NF; ++q)
        for (int k = 0; k < NF; ++k) g.data()[q * (NP + NF) + NP + k] = coefficients_[q * NF + k];
    }
    PetscCall(DMGlobalToLocal(param_dm_, Pg_, INSERT_VALUES, P_));
    PetscCall(vectors_from(p, theta_));
    bounds_.min.assign(NP, 0.0), bounds_.max.assign(NP, 0.0);
    for (int k = 0; k < NP; ++k) {
      PetscCall(VecStrideMin(Pg_, k, nullptr, &bounds_.min[k]));
      PetscCall(VecStrideMax(Pg_, k, nullptr, &bounds_.max[k]));
    }
    // a scalar or fixed parameter reads its value everywhere, beyond walls too; when every one G reads
    // is such, the sweeps take them as constants
    constants_ = true;
    {
      Array pl(P_);
      PetscCall(pl.error());
      PetscInt n;
      PetscCall(VecGetLocalSize(P_, &n));
      for (int k = 0; k < NP; ++k) {
        if (k < NG) constants_ = constants_ && constant_slot(k);
        if (constant_slot(k)) fill_slot(pl.data(), n, k, bounds_.min[k]);
      }
    }
    frame_.pconst = bounds_.min.data(); // a constant's value is its minimum
    if constexpr (HasCheck<Eq>::value) PetscCall(eq_.check_parameters(bounds_, grid_->comm()));
    PetscCall(find_uniform_coupling());
    PetscFunctionReturn(0);
  }

  FLEXIPDE_SWEEP PetscErrorCode rhs(PetscReal t, Vec U, Vec G) override {
    PetscFunctionBeginUser;
    const bool coupled_only = uniform_ && !local_part_; // G = sum_k c_k L_k U (+ forcing)
    if (coupled_only) {
      PetscCall(apply_coupling(coupling_, U, G, 1.0, false, false));
      st_.ref = U; // (no ghosts or fields of U are read)
    } else PetscCall(load(U, st_, false, forward_strip_));
    {
      StateView sv(st_);
      ConstArray p(P_);
      Array g(G);
      PetscCall(sv.error());
      PetscCall(p.error());
      PetscCall(g.error());
      pointwise::Frame f = frame(t, sv, p.data());
      uncoupled(f);
      const pointwise::Frame fe = edge_frame(f);
      PetscScalar *out = g.data();
      PetscScalar *hout = nullptr;
      if constexpr (H > 0) PetscCall(VecGetArray(Hg_, &hout));
      if (!coupled_only) with_constants([&](auto sc) {
        with_model([&](const auto &eq) {
          const auto point = [=](PetscInt at, PetscInt own, PetscInt i, PetscInt j, PetscInt k, auto ck) {
            constexpr int where = decltype(ck)::value;
            double gv[C + H];
            rhs_of(eq, Pt<Mode::Value, 0, 0, where == 1, C, where == 1, decltype(sc)::value>(where >= 2 ? fe : f, at,
                                                                                             where >= 2 ? at : own, i, j, k),
                   gv);
            for (int c = 0; c < C; ++c) out[own * C + c] = gv[c];
            for (int m = 0; m < H; ++m) hout[own * H + m] = gv[C + m];
          };
          if constexpr (Flux && NFACE > 0) {
            const RunPlan &plan = runs(R, true, false);
            rhs_faces<decltype(sc)::value>(plan.kind[0], eq, f, out);
            run_kind(plan.kind[1], point, Check<true>());
            run_kind(plan.kind[2], point, Edge());
          } else for_points<true>(R, point);
        });
      });
      if constexpr (H > 0) PetscCall(VecRestoreArray(Hg_, &hout));
      if constexpr (pointwise::HasForcing<Eq>::value)
        if (source_) {
          const PetscReal wt = source_->wavelet(t);
          for (PetscInt k = 0; k < source_->stencil.n; ++k) {
            if (!forced_point(source_->stencil.local[k])) continue;
            out[source_->stencil.local[k] * C + Eq::forced_component] += source_->at_wavelet(k, wt);
          }
        }
    }
    PetscCall(add_outputs(G));
    if (uniform_ && !coupled_only) PetscCall(apply_coupling(coupling_, U, G, 1.0, true, false));
    PetscFunctionReturn(0);
  }

  // y = dG/dU x + dG/dp dp at state U (either direction may be null), one sweep of Tangent numbers.
  FLEXIPDE_SWEEP PetscErrorCode tangent(PetscReal t, const LocalState &s, Vec x, Vec dp, Vec y) {
    PetscFunctionBeginUser;
    if (x) PetscCall(fill_ghosts(x, Xl_));
    if (dp) PetscCall(params_to_local(dp, dP_));
    if constexpr (KL) {
      if (x) PetscCall(auxiliary_lines(x, dline_));
    } else if constexpr (K > 0)
      if (x && !uniform_) PetscCall(auxiliaries(x, dAl_));
    if (dp) PetscCall(vectors_from(dp, dtheta_));
    {
      StateView sv(s);
      ConstArray xo(x), xg(x ? Xl_.get() : nullptr), p(P_), dpa(dp ? dP_.get() : nullptr),
          da(K > 0 && !KL && x ? dAl_.get() : nullptr);
      Array ya(y);
      PetscCall(sv.error());
      PetscCall(ya.error());
      pointwise::Frame f = frame(t, sv, p.data());
      f.X = xo.data();
      f.Xg = xg.data();
      f.dP = dpa.data();
      f.dA = KL ? (x ? dline_.data() : nullptr) : da.data();
      f.dtheta = dp && !dtheta_.empty() ? dtheta_.data() : nullptr;
      uncoupled(f);
      const pointwise::Frame fe = edge_frame(f);
      PetscScalar *out = ya.data();
      PetscScalar *hout = nullptr;
      if constexpr (H > 0) PetscCall(VecGetArray(Hg_, &hout));
      if (uniform_ && !local_part_) std::fill(out, out + grid_->local_points() * C, 0.0);
      else with_model([&](const auto &eq) {
        for_points<true>(R, [=](PetscInt at, PetscInt own, PetscInt i, PetscInt j, PetscInt k, auto ck) {
          constexpr int where = decltype(ck)::value;
          typename Pt<Mode::Tangent>::Number gv[C + H];
          rhs_of(eq, Pt<Mode::Tangent, 0, 0, where == 1>(where >= 2 ? fe : f, at, where >= 2 ? at : own, i, j, k), gv);
          for (int c = 0; c < C; ++c) out[own * C + c] = gv[c].d[0];
          for (int m = 0; m < H; ++m) hout[own * H + m] = gv[C + m].d[0];
        });
      });
      if constexpr (H > 0) PetscCall(VecRestoreArray(Hg_, &hout));
    }
    PetscCall(add_outputs(y));
    if (uniform_ && x) PetscCall(apply_coupling(coupling_, x, y, 1.0, true, false)); // y += sum_k c_k L_k x
    if (uniform_ && dp) { // y += sum_k (sum_q dp_q dc_k/dp_q) L_k U
      PetscScalar r[K > 0 ? K : 1] = {};
      {
        ConstArray d(dP_);
        PetscCall(d.error());
        for (int k = 0; k < K; ++k)
          for (int q = 0; q < NG; ++q) r[k] += coupling_p_[k][q] * PetscRealPart(d.data()[q]);
      }
      PetscCall(apply_coupling(r, s.ref, y, 1.0, true, false));
    }
    PetscFunctionReturn(0);
  }

  // The transposes at state s: y = (dG/dU)^T x (y null: not formed) and, for every parameter k,
  // gk[j] += w sum (dG/dp_k(j))^T x (gk null: not wanted), in one gather sweep; xl is x ghosted and xh
  // the outputs' B^T x ghosted. Components of x outside [clo, chi) are taken as 0, and only y's
  // components in [ylo, yhi) are written (added, times w, if add_y): the leapfrog's kick is this with
  // x = lambda_p, y = lambda_q. z (auxiliary fields; null: none) gets the gather of (dG/da)^T x.
  // What is written is known at compile time (WY: y, ADDY: added, WG: gk), so the loop has no branch.
  // SPLIT: x holds the components [CLO, CHI) alone and y [YLO, YHI) alone, in arrays of their own.
  // drift (the leapfrog kick, SPLIT, held walls, 2D and 3D; 0: none): xd = x += drift y on the owned
  // points beyond strip_ of the block's edge (the caller drifted those within it) row by row just ahead
  // of the rows that read them, so that lambda passes through the cache once per time level.
  template <int CLO, int CHI, int YLO, int YHI, int CS, bool WY, bool ADDY, bool WG, bool SC, bool SPLIT>
  FLEXIPDE_SWEEP PetscErrorCode gather(PetscReal t, const LocalState &s, const PetscScalar *xo, const PetscScalar *xl,
                                       const PetscScalar *xh, PetscScalar *y, PetscReal w, PetscReal *const *gk,
                                       PetscScalar *z, PetscReal drift = 0, PetscScalar *xd = nullptr) {
    PetscFunctionBeginUser;
    PetscCheck(drift == 0 || (SPLIT && ADDY && D >= 2 && frame_.held && xd), grid_->comm(), PETSC_ERR_PLIB,
               "gather: a drift rides only on a leapfrog kick's row sweep with held walls in 2D or 3D");
    {
      StateView sv(s);
      ConstArray p(P_);
      PetscCall(sv.error());
      PetscCall(p.error());
      pointwise::Frame f = frame(t, sv, p.data());
      f.X = xo, f.Xg = xl;
      uncoupled(f);
      const pointwise::Frame fe = edge_frame(f);
      using Offsets = std::make_integer_sequence<int, Sten::size>;
      with_model([&](const auto &eq) {
      // the point's results into y, z and the gradient
      const auto store = [=](PetscInt own, PetscInt i, const double *yv, const double *zv, const double *gv) {
        if constexpr (WY)
          for (int c = YLO; c < YHI; ++c) {
            if constexpr (ADDY) y[x_at<YLO, YHI, SPLIT>(own, c)] += w * yv[c];
            else y[x_at<YLO, YHI, SPLIT>(own, c)] = yv[c];
          }
        if constexpr (KL && WY)
          for (int k = 0; k < K; ++k) z[i * K + k] += zv[k];
        else if constexpr (K > 0 && WY)
          for (int k = 0; k < K; ++k) z[own * K + k] = zv[k];
        if constexpr (WG)
          for (int k = 0; k < NG; ++k) gk[k][own] += w * gv[k];
      };
      const auto point = [=](PetscInt at, PetscInt own, PetscInt i, PetscInt j, PetscInt k, auto ck) {
        constexpr int where = decltype(ck)::value;
        double yv[C] = {};
        double zv[K > 0 ? K : 1] = {};
        double gv[NG > 0 ? NG : 1] = {};
        gather_offsets<CLO, CHI, where, CS, SC, true, SPLIT>(eq, where >= 2 ? fe : f, xh, at, where >= 2 ? at : own, i, j, k, yv, zv, gv,
                                                Offsets());
        store(own, i, yv, zv, gv);
      };
      // Face blocks when each face is read by 4 points or more, or has 2 lanes per point read at most:
      // with RF = 1 the gather point by point differentiates each face twice with half the lanes, and
      // the blocks' stored terms cost more than they save once lanes of parameters the flux does not
      // read (advection's velocities with a field D) are stored too.
      constexpr bool face_blocks = Flux && !SPLIT && CS == C && (RF >= 2 || C + (SC ? 0 : NG) <= 2);
      if constexpr (face_blocks) {
        const RunPlan &plan = runs(2 * R, true, true);
        gather_face_runs<CLO, CHI, SC>(plan.kind[0], eq, f, xh, store);
        run_kind(plan.kind[1], point, Check<true>());
        run_kind(plan.kind[2], point, Edge());
        run_kind(plan.kind[3], point, EdgeNearWall());
      } else if (frame_.held) {
        // G is 0 on held walls and x is 0 on and beyond them, so no neighbour needs a test, and the wall
        // points take the Edge path too. Their y is 0: every stencil reads a held wall as 0 whatever the
        // state holds (the Edge path would differentiate the reads); what they gather is dG/dp and dG/da.
        const auto wall_point = [=](PetscInt at, PetscInt own, PetscInt i, PetscInt j, PetscInt k, auto) {
          double yv[C] = {};
          double zv[K > 0 ? K : 1] = {};
          double gv[NG > 0 ? NG : 1] = {};
          gather_offsets<CLO, CHI, 2, CS, SC, true, SPLIT>(eq, fe, xh, at, at, i, j, k, yv, zv, gv, Offsets());
          for (int c = 0; c < C; ++c) yv[c] = 0.0;
          store(own, i, yv, zv, gv);
        };
        const RunPlan &plan = runs(2 * R, true, false);
        if (drift == 0) {
          run_kind(plan.kind[0], point, Check<false>());
          run_kind(plan.kind[1], wall_point, Edge());
          run_kind(plan.kind[2], point, Edge());
        } else if constexpr (SPLIT && ADDY && D >= 2) {
          constexpr int m = CS; // the kick's x = lambda_p and y = lambda_q: m components each
          RowCursor cursor(plan);
          for_rows_ahead(
              strip_, [&](PetscInt lo, PetscInt hi) { leapfrog_drift_transpose(xd, y, lo * m, hi * m, drift); },
              [&](PetscInt, PetscInt j, PetscInt k) {
                const auto k0 = cursor.take(0, j, k), k1 = cursor.take(1, j, k), k2 = cursor.take(2, j, k);
                run_kind(k0.first, k0.second, point, Check<false>());
                run_kind(k1.first, k1.second, wall_point, Edge());
                run_kind(k2.first, k2.second, point, Edge());
              });
        }
      } else for_points<true, true>(2 * R, point); // (equations on a wall test wall(): EdgeNearWall)
      // An owned point's mirror images beyond odd walls are read by the stencils next to the wall:
      // their gathers (inputs at the image, its sign) belong to the point.
      if constexpr (WY) {
        if constexpr (ImageRuns)
          gather_image_runs<CLO, CHI, YLO, YHI, CS, SC, SPLIT>(eq, fe, xh, y, (ADDY ? w : 1.0), std::make_integer_sequence<int, 2 * D * R>());
        for (const ImageRun &r : images_)
          for (PetscInt q = 0; q < r.n; ++q) {
            double yv[C] = {}, zv[K > 0 ? K : 1] = {}, gv[NG > 0 ? NG : 1] = {};
            gather_offsets<CLO, CHI, 3, CS, SC, true, SPLIT>(eq, fe, xh, r.at + q, r.at + q, r.i0 + q, r.j, r.k, yv, zv, gv, Offsets());
            for (int c = YLO; c < YHI; ++c) y[x_at<YLO, YHI, SPLIT>(r.own + q, c)] += (ADDY ? w : 1.0) * r.sign * yv[c];
          }
      }
      });
    }
    PetscFunctionReturn(0);
  }

  // The gather of x at the state s into y (null: none) and, unless mu is null, mu += w (dG/dp)^T x: a
  // field's entries in place, a scalar's pointwise terms into its accumulator if `defer` (the
  // integrators' own sweeps during an adjoint solve; end_adjoint sums them), else summed now
  // (collective; the shells, whose products PETSc scales after the fact). The non-local maps enter
  // as B^T x before the sweep and L^T z after it.
  // ADDY: y += w (dG/dU)^T x (the leapfrog kick), else y = (dG/dU)^T x. GRAD: y is formed and so is the
  // gradient, a null mu's into scratch: one compiled sweep where the gradient costs little next to y.
  // SPLIT (the leapfrog kick): x = lambda_p and y = lambda_q, m per point each, x ghosted in lam_g_.
  template <int CLO = 0, int CHI = C, int YLO = 0, int YHI = C, int CS = C, bool ADDY = false, bool GRAD = ADDY, bool SPLIT = false>
  // x_ghosts: Xl_ already holds x ghosted (the caller filled it). drift: the gather's (the leapfrog kick).
  PetscErrorCode transpose(PetscReal t, const LocalState &s, Vec x, Vec y, PetscReal w, Vec mu, bool defer,
                           bool x_ghosts = false, PetscReal drift = 0) {
    PetscFunctionBeginUser;
    static_assert(!SPLIT || (Local && ADDY && CHI - CLO == YHI - YLO), "split arrays: the leapfrog kick of a local model");
    PetscCheck(!SPLIT || x_ghosts, grid_->comm(), PETSC_ERR_PLIB, "transpose: split arrays come ghosted");
    if (!x_ghosts) PetscCall(fill_ghosts(x, Xl_, true));
    if constexpr (Coupling)
      if (uniform_ && mu) PetscCall(eq_.auxiliary_fields_adjoint(x, map_vecs_.data())); // L_k^T x
    if constexpr (H > 0) {
      if constexpr (pointwise::HasMapsAtOnce<Eq>::value) {
        PetscCall(eq_.output_fields_transpose(x, map_vecs_.data()));
        PetscCall(VecStrideScatterAll(map_vecs_.data(), Hg_, INSERT_VALUES));
      } else
        for (int m = 0; m < H; ++m) {
          PetscCall(eq_.output_transpose(m, x, field_));
          PetscCall(VecStrideScatter(field_, m, Hg_, INSERT_VALUES));
        }
      PetscCall(DMGlobalToLocal(out_dm_, Hg_, INSERT_VALUES, XHl_));
    }
    {
      ConstArray xg(SPLIT ? lam_g_.get() : Xl_.get()), xha(XHl_);
      PetscScalar *ya = nullptr, *m = nullptr, *za = nullptr, *xd = nullptr;
      const PetscScalar *xo;
      if (y) PetscCall(VecGetArray(y, &ya));
      if (SPLIT && drift != 0) { // the drift writes x
        PetscCall(VecGetArray(x, &xd));
        xo = xd;
      } else PetscCall(VecGetArrayRead(x, &xo));
      if (mu) PetscCall(VecGetArray(mu, &m));
      if (KL && y) std::fill(zline_.begin(), zline_.end(), 0.0), za = zline_.data();
      else if (K > 0 && y) PetscCall(VecGetArray(Zg_, &za));
      PetscReal *gk[NP > 0 ? NP : 1] = {};
      if (mu) fill_gradient_targets(m, defer, gk, true);
      else if (GRAD) scratch_targets(gk);
      auto run = [&](auto wy, auto wg) {
        PetscErrorCode ierr = 0;
        with_constants([&](auto sc) {
          ierr = gather<CLO, CHI, YLO, YHI, CS, decltype(wy)::value, ADDY, decltype(wg)::value, decltype(sc)::value, SPLIT>(
              t, s, xo, xg.data(), xha.data(), ya, w, gk, za, drift, xd);
        });
        return ierr;
      };
      using T = std::true_type;
      using F = std::false_type;
      if constexpr (ADDY || GRAD) {
        PetscCheck(y, grid_->comm(), PETSC_ERR_PLIB, "transpose: y is formed");
        PetscCall(run(T(), T()));
      } else if (!y) PetscCall(mu ? run(F(), T()) : 0);
      else if (!(uniform_ && !local_part_)) PetscCall(mu ? run(T(), T()) : run(T(), F()));
      if (uniform_ && mu) PetscCall(add_coupling_gradient(s, w, gk));
      if (mu && !theta_.empty()) {
        if (!defer) std::fill(dtheta_.begin(), dtheta_.end(), 0.0);
        PetscCall((theta_gather<CLO, CHI, CS, SPLIT>(t, s, xo, w, defer ? theta_acc_.data() : dtheta_.data())));
      }
      if (xd) PetscCall(VecRestoreArray(x, &xd));
      else PetscCall(VecRestoreArrayRead(x, &xo));
      if (za && !KL) PetscCall(VecRestoreArray(Zg_, &za));
      if (mu) PetscCall(VecRestoreArray(mu, &m));
      if (y) PetscCall(VecRestoreArray(y, &ya));
    }
    if constexpr (KL) {
      if (y) PetscCall(add_auxiliary_lines_transpose(y, ADDY ? w : 1.0));
    } else if constexpr (K > 0) {
      if (y && uniform_) { // y (+)= w sum_k c_k L_k^T x (with mu: from the L_k^T x at hand)
        const PetscReal wy = ADDY ? w : 1.0;
        const bool add = ADDY || local_part_;
        if (mu) PetscCall(add_combination(y, coupling_, wy, add));
        else PetscCall(apply_coupling(coupling_, x, y, wy, add, true));
      } else if (y) PetscCall(add_auxiliary_transposes(y, ADDY ? w : 1.0));
    }
    if (mu && !defer) PetscCall(flush_scratch_scalars(mu));
    if (mu && !defer) PetscCall(add_vector_sums(mu, dtheta_));
    PetscFunctionReturn(0);
  }
  // y += w sum_k L_k^T z_k, z the gather's (dG/da)^T x (in Zg_).
  PetscErrorCode add_auxiliary_transposes(Vec y, PetscReal w) {
    PetscFunctionBeginUser;
    if constexpr (K > 0 && !KL) {
      PetscCall(VecSet(Yt_, 0.0));
      if constexpr (pointwise::HasMapsAtOnce<Eq>::value) {
        PetscCall(VecStrideGatherAll(Zg_, map_vecs_.data(), INSERT_VALUES));
        PetscCall(eq_.auxiliary_fields_transpose(map_vecs_.data(), Yt_));
      } else
        for (int k = 0; k < K; ++k) {
          PetscCall(VecStrideGather(Zg_, k, field_, INSERT_VALUES));
          PetscCall(eq_.auxiliary_transpose(k, field_, Yt_));
        }
      PetscCall(VecAXPY(y, w, Yt_));
    }
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
  // entries structurally nonzero (pattern_, found once at random inputs) are in the matrix. The values
  // go in with one MatSetValuesCOO, in the order of a coordinate list made when a matrix is first
  // filled, and again when a linear G's zeros move (row by row, MatSetValuesStencil's index
  // translations and searches cost more than evaluating the rows).
  PetscErrorCode rhs_jacobian(PetscReal t, Vec U, Mat J) override {
    PetscFunctionBeginUser;
    PetscCall(load(U, jac_, true));
    if constexpr (Local) {
      PetscCall(assemble_rows(t, jac_, &coo_v_, &coo_used_next_));
      PetscInt64 id;
      PetscCall(PetscObjectGetId((PetscObject)J, &id));
      if (id != coo_mat_ || coo_used_next_ != coo_used_) {
        std::vector<PetscInt> rows, cols;
        coo_used_.swap(coo_used_next_);
        PetscCall(assemble_rows(t, jac_, &coo_v_, nullptr, nullptr, &rows, &cols));
        for (size_t k = 0; k < rows.size(); ++k)
          if (!coo_used_[k]) rows[k] = cols[k] = -1; // (MatSetValuesCOO skips these values)
        PetscCall(MatSetPreallocationCOOLocal(J, (PetscCount)rows.size(), rows.data(), cols.data()));
        coo_mat_ = id;
      }
      PetscCall(MatSetValuesCOO(J, coo_v_.data(), INSERT_VALUES));
    } else {
      PetscCall(MatAssemblyBegin(J, MAT_FINAL_ASSEMBLY));
      PetscCall(MatAssemblyEnd(J, MAT_FINAL_ASSEMBLY));
    }
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
    PetscCall(load(U, jp_, true));
    jp_t_ = t;
    PetscCall(MatAssemblyBegin(Jp, MAT_FINAL_ASSEMBLY)); // resets the scaling a theta adjoint applied last time
    PetscCall(MatAssemblyEnd(Jp, MAT_FINAL_ASSEMBLY));
    PetscFunctionReturn(0);
  }

  // Explicit RK adjoint stage: y = (dG/dU)^T x and mu += (dG/dp)^T x, one sweep.
  bool has_stage_adjoint() const override { return true; }
  PetscErrorCode stage_adjoint(PetscReal t, Vec U, const PetscScalar *record, Vec x, Vec y, Vec mu) override {
    constexpr int m = pointwise::PairsOf<Eq>::value;
    PetscFunctionBeginUser;
    if constexpr (m > 0)
      if (record) { // the stage's positions alone
        PetscCall(VecPlaceArray(pos_rec_, record));
        pos_.ref = pos_rec_;
        PetscCall(fill_ghosts<m>(pos_rec_, pos_.g, pos_ghosts_));
        PetscCall((transpose<0, C, 0, C, m, false, true>(t, pos_, x, y, 1.0, mu, in_adjoint_)));
        PetscCall(VecResetArray(pos_rec_));
        PetscFunctionReturn(0);
      }
    if constexpr (KL)
      if (record) { // the stage's auxiliary lines
        st_.ref = U;
        PetscCall(fill_ghosts(U, st_.g));
        pad_lines(record, st_.line);
        PetscCall(transpose(t, st_, x, y, 1.0, mu, in_adjoint_));
        PetscFunctionReturn(0);
      }
    PetscCall(load(U, st_));
    PetscCall(transpose(t, st_, x, y, 1.0, mu, in_adjoint_));
    PetscFunctionReturn(0);
  }
  // An explicit RK's stored stages: the positions alone of a second-order model (m per point) when the
  // transposes read nothing else of the state, which a probe at random inputs finds once (their
  // products at two states that differ in the other components alone are the same); or, besides the
  // stage, its auxiliary lines (K per column), which the adjoint would otherwise form again.
  PetscInt stage_record_size() const override {
    if constexpr (KL) return grid_->n() * K;
    return positions_suffice() ? grid_->local_points() * pointwise::PairsOf<Eq>::value : 0;
  }
  bool stage_record_replaces_state() const override { return !KL && stage_record_size() > 0; }
  PetscErrorCode rhs_record(PetscReal t, Vec U, Vec G, PetscScalar *record) override {
    constexpr int m = pointwise::PairsOf<Eq>::value;
    PetscFunctionBeginUser;
    PetscCall(rhs(t, U, G));
    if constexpr (m > 0) PetscCall(positions_of(U, record));
    if constexpr (KL) std::copy(st_.line.begin() + line_pad * K, st_.line.end() - line_pad * K, record);
    PetscFunctionReturn(0);
  }
  // q = the positions of the state U (its first m components at every owned point, m per point).
  PetscErrorCode positions_of(Vec U, PetscScalar *q) const {
    constexpr int m = pointwise::PairsOf<Eq>::value;
    ConstArray u(U);
    PetscFunctionBeginUser;
    PetscCall(u.error());
    for (PetscInt i = 0; i < grid_->local_points(); ++i)
      for (int c = 0; c < m; ++c) q[i * m + c] = u.data()[i * C + c];
    PetscFunctionReturn(0);
  }

  // Leapfrog kick at one time level, lambda_q and lambda_p in arrays of their own (m per point):
  // lambda_p += drift lambda_q, then lambda_q += w (dG_p/dq)^T lambda_p and mu += w (dG_p/dp)^T lambda_p,
  // the transposes in one gather sweep that reads lambda_p in whole vectors.
  // U may be the positions alone (m per point; G_p reads nothing else), which is all a trajectory then
  // stores.
  bool has_second_order_adjoint() const override { return pointwise::PairsOf<Eq>::value > 0; }
  PetscErrorCode second_order_adjoint(PetscReal t, Vec U, Vec lambda_q, Vec lambda_p, PetscReal w, Vec mu, PetscReal drift,
                                      const PetscScalar *next) override {
    constexpr int m = pointwise::PairsOf<Eq>::value;
    PetscFunctionBeginUser;
    if constexpr (m > 0) {
      leapfrog_prefetch(next, grid_->local_points() * m); // the positions a later kick reads, on their way during this one
      PetscInt n;
      PetscCall(VecGetLocalSize(U, &n));
      pos_.ref = U;
      if (n != grid_->local_points() * m) { // a whole state: its positions are all the kick reads
        Array q(pos_copy_);
        PetscCall(q.error());
        PetscCall(positions_of(U, q.data()));
        pos_.ref = pos_copy_;
      }
      // the ghosts of the positions and of lambda_p (after the drift) travel at once
      PetscCall(pos_ghosts_.begin(pos_.ref, pos_.g));
      // The drift's transpose: with held walls in 2D and 3D on the block's edge strips now (their ghosts
      // and copies are read from the start) and on the rest within the gather, rows just ahead of the
      // rows that read them (one pass over lambda); else in a pass of its own.
      const bool in_gather = drift != 0 && D >= 2 && frame_.held;
      if (drift != 0) {
        Array lp(lambda_p);
        ConstArray lq(lambda_q);
        PetscCall(lp.error());
        PetscCall(lq.error());
        if (in_gather)
          for_edge_strips(strip_, [&](PetscInt lo, PetscInt hi) { leapfrog_drift_transpose(lp.data(), lq.data(), lo * m, hi * m, drift); });
        else leapfrog_drift_transpose(lp.data(), lq.data(), 0, grid_->local_points() * m, drift);
      }
      PetscCall(lambda_ghosts_.begin(lambda_p, lam_g_));
      PetscCall(fill_ghosts<m>(pos_.ref, pos_.g, pos_ghosts_, false, true));
      PetscCall(fill_ghosts<m>(lambda_p, lam_g_, lambda_ghosts_, true, true));
      PetscCall((transpose<m, 2 * m, 0, m, m, true, true, true>(t, pos_, lambda_p, lambda_q, w, mu, in_adjoint_, true,
                                                                 in_gather ? drift : 0.0)));
    }
    PetscFunctionReturn(0);
  }
  // A whole leapfrog step in one sweep (Model::second_order_step), 2D and 3D: the kick and drift of the
  // points within forward_strip_ of the owned block's edge, then their ghosts (all that the points near
  // the edge read, as for G), then row by row (the rows (j, k) in memory order): the kick and drift of
  // the inner points of the rows G on this row will read (R rows ahead in 2D, R planes in 3D), G's
  // velocity rows (the accelerations) on the row as rhs() evaluates them, the row's forcing, and the
  // second kick. The rows a point reads are in the cache from the kick and drift a little earlier: one
  // pass over the state from memory instead of three.
  static constexpr bool FusedStep = pointwise::PairsOf<Eq>::value > 0 && D >= 2 && K == 0 && H == 0 && !Flux;
  bool has_second_order_step() const override { return FusedStep && second_order_pairs() > 0; }
  FLEXIPDE_SWEEP PetscErrorCode second_order_step(PetscReal t, Vec U, PetscScalar *accel, const LeapfrogStepParts &parts) override {
    PetscFunctionBeginUser;
    if constexpr (FusedStep) {
      const PetscInt xm = grid_->xm(), ym = grid_->ym(), zm = grid_->zm(), B = forward_strip_, rows = ym * zm;
      {
        Array u(U);
        PetscCall(u.error());
        for_edge_strips(B, [&](PetscInt lo, PetscInt hi) { parts.kick_drift(u.data(), accel, lo, hi); });
      }
      PetscCall(load(U, st_, false, forward_strip_));
      sort_forcing();
      StateView sv(st_);
      ConstArray p(P_);
      Array u(U);
      PetscCall(sv.error());
      PetscCall(p.error());
      PetscCall(u.error());
      pointwise::Frame f = frame(t, sv, p.data());
      uncoupled(f);
      const pointwise::Frame fe = edge_frame(f);
      constexpr int m = pointwise::PairsOf<Eq>::value; // G's velocity rows are components m..2m-1
      PetscScalar *out = accel, *ud = u.data();
      with_constants([&](auto sc) {
        with_model([&](const auto &eq) {
          const auto point = [=](PetscInt at, PetscInt own, PetscInt i, PetscInt j, PetscInt k, auto ck) {
            constexpr int where = decltype(ck)::value;
            double gv[C];
            rhs_of(eq, Pt<Mode::Value, 0, 0, where == 1, C, where == 1, decltype(sc)::value>(where >= 2 ? fe : f, at,
                                                                                             where >= 2 ? at : own, i, j, k),
                   gv);
            for (int c = 0; c < m; ++c) out[own * m + c] = gv[m + c];
          };
          RowCursor cursor(runs(R, true, false));
          size_t next_force = 0;
          const PetscReal wt = forcing_order_.empty() ? 0.0 : source_->wavelet(t);
          // Rows [0, kicked) have had their second kick, one row behind G, so that G never loads
          // entries whose stores are still on their way to the cache.
          PetscInt kicked = 0;
          for_rows_ahead(
              B, [&](PetscInt lo, PetscInt hi) { parts.kick_drift(ud, out, lo, hi); },
              [&](PetscInt r, PetscInt j, PetscInt k) {
                const auto k0 = cursor.take(0, j, k), k1 = cursor.take(1, j, k), k2 = cursor.take(2, j, k);
                run_kind(k0.first, k0.second, point, Check<false>());
                run_kind(k1.first, k1.second, point, Check<true>());
                run_kind(k2.first, k2.second, point, Edge());
                if constexpr (pointwise::HasForcing<Eq>::value)
                  for (; next_force < forcing_order_.size(); ++next_force) {
                    const PetscInt e = forcing_order_[next_force], own = source_->stencil.local[e];
                    if (own >= (r + 1) * xm) break;
                    out[own * m + Eq::forced_component - m] += source_->at_wavelet(e, wt);
                  }
                for (; kicked < r; ++kicked) parts.kick(ud, out, kicked * xm, (kicked + 1) * xm);
              });
          for (; kicked < rows; ++kicked) parts.kick(ud, out, kicked * xm, (kicked + 1) * xm);
        });
      });
    }
    PetscFunctionReturn(0);
  }
  // The leapfrog's split step (Model::second_order_split_step), 2D and 3D: the ghosts of the positions
  // q_k and copies of those within forward_strip_ of the owned block's edge (all that the points near the
  // edge read), then row by row (the rows (j, k) in memory order): a = G_p on the row as rhs() evaluates
  // it at the positions (the velocities read as 0) and the kick with it at each point, v = keep v + w inv a
  // (LeapfrogSplitParts::point_kick), the row's forcing, and the drift of the rows the stencils read no
  // more (R rows behind in 2D, R planes and R rows in 3D). The positions and velocities pass through the
  // cache once.
  FLEXIPDE_SWEEP PetscErrorCode second_order_split_step(PetscReal t, Vec Q, PetscScalar *v,
                                                        const LeapfrogSplitParts &parts) override {
    PetscFunctionBeginUser;
    if constexpr (FusedStep) {
      constexpr int m = pointwise::PairsOf<Eq>::value;
      const PetscInt xm = grid_->xm(), ym = grid_->ym(), rows = ym * grid_->zm();
      const PetscInt behind = D == 3 ? R * ym + R : R; // the furthest row after it that reads a row
      PetscCall(fill_ghosts<m>(Q, pos_.g, pos_ghosts_, false, false, forward_strip_));
      sort_forcing();
      Array q(Q);
      ConstArray g(pos_.g), p(P_);
      PetscCall(q.error());
      PetscCall(g.error());
      PetscCall(p.error());
      pointwise::Frame f = frame_;
      f.t = t, f.U = q.data(), f.Ug = g.data(), f.P = p.data();
      uncoupled(f);
      const pointwise::Frame fe = edge_frame(f);
      const LeapfrogSplitParts::PointKick kick = parts.point_kick();
      PetscScalar *qd = q.data();
      // Damped: v = keep v + w inv a, else v += w a.
      const auto sweep = [&](auto damped) {
        constexpr bool Damped = decltype(damped)::value;
        const PetscReal w = kick.w;
        const PetscScalar *inv = kick.inv, *keep = kick.keep;
        with_constants([&](auto sc) {
          with_model([&](const auto &eq) {
            RowCursor cursor(runs(R, true, false));
            size_t next_force = 0;
            const PetscReal wt = forcing_order_.empty() ? 0.0 : source_->wavelet(t);
            PetscInt drifted = 0; // rows [0, drifted) hold q_{k+1}
            const auto point = [=](PetscInt at, PetscInt own, PetscInt i, PetscInt j, PetscInt k, auto ck) {
              constexpr int where = decltype(ck)::value;
              double gv[C];
              rhs_of(eq, Pt<Mode::Value, 0, 0, where == 1, m, where == 1, decltype(sc)::value>(where >= 2 ? fe : f, at,
                                                                                             where >= 2 ? at : own, i, j, k),
                     gv);
              for (int c = 0; c < m; ++c) {
                const PetscInt o = own * m + c;
                if constexpr (Damped) v[o] = keep[o] * v[o] + w * inv[o] * gv[m + c];
                else v[o] += w * gv[m + c];
              }
            };
            for (PetscInt r = 0; r < rows; ++r) {
              const PetscInt j = grid_->ys() + r % ym, k = grid_->zs() + r / ym, first = r * xm;
              const auto k0 = cursor.take(0, j, k), k1 = cursor.take(1, j, k), k2 = cursor.take(2, j, k);
              run_kind(k0.first, k0.second, point, Check<false>());
              run_kind(k1.first, k1.second, point, Check<true>());
              run_kind(k2.first, k2.second, point, Edge());
              if constexpr (pointwise::HasForcing<Eq>::value)
                for (; next_force < forcing_order_.size(); ++next_force) {
                  const PetscInt e = forcing_order_[next_force], own = source_->stencil.local[e];
                  if (own >= first + xm) break;
                  const PetscInt o = own * m + Eq::forced_component - m;
                  v[o] += w * (Damped ? inv[o] : 1.0) * source_->at_wavelet(e, wt);
                }
              for (; drifted + behind <= r; ++drifted) parts.drift(qd, v, drifted * xm, (drifted + 1) * xm);
            }
            for (; drifted < rows; ++drifted) parts.drift(qd, v, drifted * xm, (drifted + 1) * xm);
          });
        });
      };
      if (kick.inv) sweep(std::true_type());
      else sweep(std::false_type());
    }
    PetscFunctionReturn(0);
  }
  // The forcing's points in row order (stable: a point's terms add in rhs()'s order), once per source.
  void sort_forcing() {
    if (forcing_sorted_) return;
    forcing_sorted_ = true;
    forcing_order_.clear();
    if constexpr (pointwise::HasForcing<Eq>::value)
      if (source_) {
        for (PetscInt k = 0; k < source_->stencil.n; ++k)
          if (forced_point(source_->stencil.local[k])) forcing_order_.push_back(k);
        std::stable_sort(forcing_order_.begin(), forcing_order_.end(),
                         [&](PetscInt a, PetscInt b) { return source_->stencil.local[a] < source_->stencil.local[b]; });
      }
  }
  bool positions_suffice() const {
    if (positions_probe_ < 0) {
      bool ok = false;
      if (const_cast<PointwiseModel *>(this)->probe_positions(&ok)) ok = false;
      positions_probe_ = ok;
    }
    return positions_probe_ == 1;
  }
  PetscErrorCode probe_positions(bool *ok) {
    constexpr int m = pointwise::PairsOf<Eq>::value;
    PetscFunctionBeginUser;
    *ok = false;
    if constexpr (m > 0 && Local) {
      LocalState a, b;
      OwnedVec x, ya, yb, ma, mb, saved;
      PetscRandom rnd;
      PetscCall(create_state(a));
      PetscCall(create_state(b));
      PetscCall(VecDuplicate(a.copy, x.out()));
      PetscCall(VecDuplicate(a.copy, ya.out()));
      PetscCall(VecDuplicate(a.copy, yb.out()));
      PetscCall(params_->create_vec(ma.out()));
      PetscCall(VecDuplicate(ma, mb.out()));
      PetscCall(VecDuplicate(P_, saved.out()));
      PetscCall(VecCopy(P_, saved));
      PetscCall(PetscRandomCreate(PETSC_COMM_SELF, &rnd));
      PetscCall(PetscRandomSetInterval(rnd, 0.5, 1.5));
      PetscCall(VecSetRandom(a.copy, rnd));
      PetscCall(VecSetRandom(b.copy, rnd));
      PetscCall(VecSetRandom(x, rnd));
      PetscCall(VecSetRandom(P_, rnd));
      {
        ConstArray ua(a.copy);
        Array ub(b.copy);
        for (PetscInt q = 0; q < grid_->local_points(); ++q)
          for (int c = 0; c < m; ++c) ub.data()[q * C + c] = ua.data()[q * C + c];
      }
      PetscCall(PetscRandomDestroy(&rnd));
      PetscCall(load(a.copy, a));
      PetscCall(load(b.copy, b));
      PetscCall(VecSet(ma, 0.0));
      PetscCall(VecSet(mb, 0.0));
      PetscCall(transpose(0.5, a, x, ya, 1.0, ma, false));
      PetscCall(transpose(0.5, b, x, yb, 1.0, mb, false));
      PetscCall(VecCopy(saved, P_));
      PetscReal dy, dm, ny, nm;
      PetscCall(VecAXPY(yb, -1.0, ya));
      PetscCall(VecAXPY(mb, -1.0, ma));
      PetscCall(VecNorm(yb, NORM_INFINITY, &dy));
      PetscCall(VecNorm(mb, NORM_INFINITY, &dm));
      PetscCall(VecNorm(ya, NORM_INFINITY, &ny));
      PetscCall(VecNorm(ma, NORM_INFINITY, &nm));
      *ok = dy <= 1e-13 * ny && dm <= 1e-13 * nm;
    }
    PetscFunctionReturn(0);
  }
  // Within one adjoint solve a scalar's pointwise terms accumulate, summed once at the end.
  void begin_adjoint() override {
    in_adjoint_ = true;
    std::fill(theta_acc_.begin(), theta_acc_.end(), 0.0);
    for (auto &a : scalar_acc_) std::fill(a.begin(), a.end(), 0.0);
  }
  PetscErrorCode end_adjoint(Vec mu) override {
    PetscFunctionBeginUser;
    const bool was = in_adjoint_;
    in_adjoint_ = false;
    if (!was || !mu) PetscFunctionReturn(0);
    for (int k = 0; k < NP; ++k)
      if (!scalar_acc_[k].empty()) PetscCall(add_accumulated(mu, k, scalar_acc_[k]));
    PetscCall(add_vector_sums(mu, theta_acc_));
    PetscFunctionReturn(0);
  }

  // Point sources (survey.hpp) add their forcing density to component Eq::forced_component.
  bool accepts_point_source() const override { return pointwise::HasForcing<Eq>::value; }
  PetscErrorCode set_point_source(const PointSource *s) override {
    source_ = s;
    forcing_sorted_ = false;
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

  // The integrator's fixed step, for a model whose U0 is defined through the scheme (Eq::set_time_step).
  void set_time_step(PetscReal dt) override {
    if constexpr (pointwise::HasTimeStep<Eq>::value) eq_.set_time_step(dt);
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
    if constexpr (pointwise::HasCheckInitial<Eq>::value) PetscCall(eq_.check_initial(grid_->comm()));
    {
      ConstArray pa(P_);
      Array u(U0);
      PetscCall(u.error());
      pointwise::Frame f = frame_;
      f.P = pa.data();
      PetscScalar *out = u.data();
      for_points(0, [&](PetscInt at, PetscInt own, PetscInt i, PetscInt j, PetscInt k, auto ck) {
        double uv[C];
        eq_.initial(Pt<Mode::Value, 0, 0, decltype(ck)::value>(f, at, own, i, j, k), uv);
        for (int c = 0; c < C; ++c) out[own * C + c] = uv[c];
      });
    }
    PetscCall(load(U0, jac_, true)); // the state the default spectrum is taken at
    PetscFunctionReturn(0);
  }
  FLEXIPDE_SWEEP PetscErrorCode initial_condition_transpose(Vec p, Vec lambda0, Vec grad) override {
    PetscFunctionBeginUser;
    if (NP == 0 && theta_.empty()) PetscFunctionReturn(0);
    if (!theta_.empty()) PetscCall(theta_initial_gather(lambda0, grad));
    if (NP == 0) PetscFunctionReturn(0);
    {
      ConstArray pa(P_), l(lambda0);
      PetscScalar *g;
      PetscCall(VecGetArray(grad, &g));
      PetscReal *gk[NP > 0 ? NP : 1] = {};
      fill_gradient_targets(g, false, gk);
      pointwise::Frame f = frame_;
      f.P = pa.data();
      const PetscScalar *lam = l.data();
      for_points(0, [&](PetscInt at, PetscInt own, PetscInt i, PetscInt j, PetscInt k, auto ck) {
        typename PtInitial<false>::Number uv[C];
        eq_.initial(PtInitial<decltype(ck)::value>(f, at, own, i, j, k, i, j, k), uv);
        for (int q = 0; q < NP; ++q)
          if (gk[q]) {
            double s = 0;
            for (int c = 0; c < C; ++c) s += uv[c].d[C + q] * PetscRealPart(lam[own * C + c]);
            gk[q][own] += s;
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

  // The parameter vectors' entries of a parameter-shaped Vec, on every rank (collective).
  PetscErrorCode vectors_from(Vec p, std::vector<PetscReal> &theta) const {
    std::vector<PetscReal> v;
    PetscFunctionBeginUser;
    for (const auto &s : vector_slots_) {
      PetscCall(params_->vector_values(p, s.index, v));
      std::copy(v.begin(), v.end(), theta.begin() + s.offset);
    }
    PetscFunctionReturn(0);
  }
  // mu[vectors] += the sums over ranks of the per-rank terms in acc (collective).
  PetscErrorCode add_vector_sums(Vec mu, const std::vector<PetscReal> &acc) const {
    PetscFunctionBeginUser;
    for (const auto &s : vector_slots_) PetscCall(params_->add_local_sums(mu, s.index, acc.data() + s.offset));
    PetscFunctionReturn(0);
  }
  // acc[e] += w sum_i sum_{c in [CLO, CHI)} x_c(i) dG_c(i)/dtheta_e over the owned points i: G(i) taped
  // at Rev numbers and swept backward once per point.
  template <int CLO, int CHI, int CS, bool SPLIT = false>
  FLEXIPDE_SWEEP PetscErrorCode theta_gather(PetscReal t, const LocalState &s, const PetscScalar *xo, PetscReal w,
                                             PetscReal *acc) const {
    PetscFunctionBeginUser;
    StateView sv(s);
    ConstArray p(P_);
    PetscCall(sv.error());
    const pointwise::Frame f = frame(t, sv, p.data());
    Tape &tape = active_tape();
    const int ne = (int)theta_.size();
    for_points(R, [&](PetscInt at, PetscInt own, PetscInt i, PetscInt j, PetscInt k, auto ck) {
      Rev g[C + H];
      tape.begin(ne);
      rhs_of(eq_, pointwise::ReversePoint<C, K, NG, Sten, decltype(ck)::value, CS, KL>(f, at, own, i, j, k), g);
      tape.begin_seeding();
      for (int c = CLO; c < CHI; ++c) {
        const PetscInt xi = x_at<CLO, CHI, SPLIT>(own, c);
        tape.seed(g[c].i, w * PetscRealPart(xo[xi]));
      }
      tape.backward();
      for (int e = 0; e < ne; ++e) acc[e] += tape.adjoint(e);
    });
    PetscFunctionReturn(0);
  }
  // grad[vectors] += (dU0/dtheta)^T lambda0, the same way from initial().
  PetscErrorCode theta_initial_gather(Vec lambda0, Vec grad) {
    PetscFunctionBeginUser;
    std::fill(dtheta_.begin(), dtheta_.end(), 0.0);
    {
      ConstArray pa(P_), l(lambda0);
      PetscCall(l.error());
      pointwise::Frame f = frame_;
      f.P = pa.data();
      Tape &tape = active_tape();
      const int ne = (int)theta_.size();
      for_points(0, [&](PetscInt at, PetscInt own, PetscInt i, PetscInt j, PetscInt k, auto ck) {
        Rev uv[C];
        tape.begin(ne);
        eq_.initial(pointwise::ReversePoint<C, K, NG, Sten, decltype(ck)::value>(f, at, own, i, j, k), uv);
        tape.begin_seeding();
        for (int c = 0; c < C; ++c) tape.seed(uv[c].i, PetscRealPart(l[own * C + c]));
        tape.backward();
        for (int e = 0; e < ne; ++e) dtheta_[e] += tape.adjoint(e);
      });
    }
    PetscCall(add_vector_sums(grad, dtheta_));
    PetscFunctionReturn(0);
  }
  // Whether the point source forces owned point `own` (its index in the owned block).
  bool forced_point(PetscInt own) const {
    if constexpr (pointwise::HasForcedPoints<Eq>::value) {
      const PetscInt xm = grid_->xm(), ym = grid_->ym();
      return eq_.forced(grid_->xs() + own % xm, grid_->ys() + (own / xm) % ym, grid_->zs() + own / (xm * ym));
    }
    return true;
  }
  // A frame of the uniform coupling's sweeps: they read the auxiliary fields as 0 (g(U) alone).
  void uncoupled(pointwise::Frame &f) const {
    if constexpr (Coupling)
      if (uniform_) f.A = zero_aux_.data();
  }
  // y = (add ? y : 0) + w sum_k r_k L_k x (or L_k^T): the model's combination of its maps, else its
  // fields of x combined.
  PetscErrorCode apply_coupling(const PetscScalar *r, Vec x, Vec y, PetscReal w, bool add, bool transpose) {
    PetscFunctionBeginUser;
    if constexpr (Coupling) {
      if constexpr (pointwise::HasAuxCombination<Eq>::value) {
        if (!add && w == 1.0) PetscCall(eq_.auxiliary_combination(r, x, y, transpose));
        else {
          PetscCall(eq_.auxiliary_combination(r, x, field_, transpose));
          if (add) PetscCall(VecAXPY(y, w, field_));
          else PetscCall(VecAXPBY(y, w, 0.0, field_));
        }
      } else {
        if (transpose) PetscCall(eq_.auxiliary_fields_adjoint(x, map_vecs_.data()));
        else PetscCall(eq_.auxiliary_fields(x, map_vecs_.data()));
        PetscCall(add_combination(y, r, w, add));
      }
    }
    PetscFunctionReturn(0);
  }
  // y = (add ? y : 0) + w sum_k r_k f_k, f the fields in map_vecs_: one pass.
  PetscErrorCode add_combination(Vec y, const PetscScalar *r, PetscReal w, bool add) {
    PetscFunctionBeginUser;
    if constexpr (Coupling) {
      const PetscScalar *f[K];
      PetscScalar wr[K];
      for (int k = 0; k < K; ++k) {
        PetscCall(VecGetArrayRead(map_vecs_[k], &f[k]));
        wr[k] = w * r[k];
      }
      {
        Array ya(y);
        PetscCall(ya.error());
        PetscScalar *o = ya.data();
        const PetscInt n = grid_->local_points();
        for (PetscInt i = 0; i < n; ++i) {
          PetscScalar v = add ? o[i] : 0.0;
          for (int k = 0; k < K; ++k) v += wr[k] * f[k][i];
          o[i] = v;
        }
      }
      for (int k = 0; k < K; ++k) PetscCall(VecRestoreArrayRead(map_vecs_[k], &f[k]));
    }
    PetscFunctionReturn(0);
  }
  // gk[q] += w sum_k (dc_k/dp_q) <L_k^T x, U> (L_k^T x in map_vecs_): a constant's gradient, this rank's
  // part (the targets are summed over the points and ranks).
  PetscErrorCode add_coupling_gradient(const LocalState &s, PetscReal w, PetscReal *const *gk) {
    PetscFunctionBeginUser;
    if constexpr (Coupling) {
      PetscReal pair[K] = {};
      ConstArray u(s.ref);
      PetscCall(u.error());
      const PetscInt n = grid_->local_points();
      for (int k = 0; k < K; ++k) {
        ConstArray a(map_vecs_[k]);
        PetscCall(a.error());
        for (PetscInt i = 0; i < n; ++i) pair[k] += PetscRealPart(a.data()[i]) * PetscRealPart(u.data()[i]);
      }
      for (int q = 0; q < NG; ++q) {
        PetscReal g = 0;
        for (int k = 0; k < K; ++k) g += coupling_p_[k][q] * pair[k];
        if (gk[q]) gk[q][0] += w * g;
      }
    }
    PetscFunctionReturn(0);
  }
  // Whether G = g(U) + sum_k c_k a_k with c_k and dc_k/dp_q the same at every point (a linear G whose
  // parameters are constants, no parameter vectors), and their values: Tangent evaluations at U = 0 in
  // the direction a = e_k (c_k), and in the direction p_q at a = e_k less the same at a = 0. Collective.
  PetscErrorCode find_uniform_coupling() {
    PetscFunctionBeginUser;
    uniform_ = false;
    if constexpr (Coupling) {
      if (!constants_ || !theta_.empty()) PetscFunctionReturn(0);
      constexpr int nq = K + K * NG; // c_k, then dc_k/dp_q at K + k NG + q
      const PetscInt na = (PetscInt)zero_aux_.size(), ng = na / K, n = grid_->local_points(), npp = NP + NF;
      std::vector<PetscScalar> ek((size_t)na), dq((size_t)(ng * npp)), zu((size_t)(ng * C), 0.0);
      std::vector<double> v0((size_t)n), v1((size_t)n), lo(nq, PETSC_MAX_REAL), hi(nq, PETSC_MIN_REAL);
      ConstArray p(P_);
      PetscCall(p.error());
      pointwise::Frame f = frame_;
      f.U = f.Ug = zu.data(), f.X = f.Xg = nullptr, f.P = p.data();
      PetscInt local_part = 0; // g(U) is not 0: found by the evaluations at a = 0 below
      auto sweep = [&](std::vector<double> &v, bool at_zero = false) {
        const pointwise::Frame fe = edge_frame(f);
        for_points<true>(R, [&](PetscInt at, PetscInt own, PetscInt i, PetscInt j, PetscInt k, auto ck) {
          constexpr int where = decltype(ck)::value;
          typename Pt<Mode::Tangent>::Number gv[C];
          rhs_of(eq_, Pt<Mode::Tangent, 0, 0, where == 1>(where >= 2 ? fe : f, at, where >= 2 ? at : own, i, j, k), gv);
          v[own] = gv[0].d[0];
          if (at_zero) local_part = local_part || gv[0].v != 0.0 || gv[0].d[0] != 0.0;
        });
      };
      auto range = [&](int slot, const std::vector<double> &v) {
        for (double x : v) lo[slot] = std::min(lo[slot], x), hi[slot] = std::max(hi[slot], x);
      };
      auto unit = [&](std::vector<PetscScalar> &a, int stride, int k) {
        for (size_t q = 0; q < a.size(); ++q) a[q] = (int)(q % stride) == k ? 1.0 : 0.0;
      };
      for (int k = 0; k < K; ++k) {
        unit(ek, K, k);
        f.A = zero_aux_.data(), f.dA = ek.data(), f.dP = nullptr;
        sweep(v0);
        range(k, v0);
      }
      for (int q = 0; q < NG; ++q) {
        unit(dq, npp, q);
        f.dA = nullptr, f.dP = dq.data(), f.A = zero_aux_.data();
        sweep(v0, true);
        for (int k = 0; k < K; ++k) {
          unit(ek, K, k);
          f.A = ek.data();
          sweep(v1);
          for (PetscInt i = 0; i < n; ++i) v1[i] -= v0[i];
          range(K + k * NG + q, v1);
        }
      }
      PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, lo.data(), nq, MPI_DOUBLE, MPI_MIN, grid_->comm()));
      PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, hi.data(), nq, MPI_DOUBLE, MPI_MAX, grid_->comm()));
      { // ... and in a random direction of U
        std::vector<PetscScalar> xr((size_t)(ng * C));
        PetscRandom rnd;
        PetscCall(PetscRandomCreate(PETSC_COMM_SELF, &rnd));
        PetscCall(PetscRandomSetInterval(rnd, 0.5, 1.5));
        for (auto &v : xr) PetscCall(PetscRandomGetValue(rnd, &v));
        PetscCall(PetscRandomDestroy(&rnd));
        f.A = zero_aux_.data(), f.dA = nullptr, f.dP = nullptr, f.X = f.Xg = xr.data();
        sweep(v0, true);
      }
      PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &local_part, 1, MPIU_INT, MPI_MAX, grid_->comm()));
      bool same = true;
      for (int q = 0; q < nq; ++q) same = same && lo[q] == hi[q];
      if (!same) PetscFunctionReturn(0);
      local_part_ = local_part != 0;
      for (int k = 0; k < K; ++k) {
        coupling_[k] = lo[k];
        for (int q = 0; q < NG; ++q) coupling_p_[k][q] = lo[K + k * NG + q];
      }
      uniform_ = true;
    }
    PetscFunctionReturn(0);
  }
  // f(std::true_type) when every parameter G reads is a constant (Point's SC), else f(std::false_type).
  template <class F> void with_constants(F &&f) const {
    if constexpr (NG > 0)
      if (constants_) return f(std::true_type());
    f(std::false_type());
  }
  // The model as the sweeps read it: a copy when it can be copied (the point loops copy it again with
  // the rest of what they capture), so that the compiler knows no store of a sweep changes its
  // members: it keeps them in registers, hoists the branches on them out of the loop over points, and
  // vectorises. (A model holds what is costly to copy, such as FFT plans, through a shared pointer.)
  template <class F> void with_model(F &&f) const {
    if constexpr (std::is_copy_constructible_v<Eq>) {
      const Eq eq = eq_;
      f(eq);
    } else f(ModelView{&eq_});
  }
  // ... else a view of it, which the point loops copy in place of the model.
  struct ModelView {
    const Eq *eq;
    template <class P, class G> void rhs(const P &pt, G *g) const { eq->rhs(pt, g); }
    template <class P, class G> void source(const P &pt, G *g) const { eq->source(pt, g); }
    template <class P, int d, class G> void flux(const P &pt, Direction<d> dir, G *g) const { eq->flux(pt, dir, g); }
  };

  // G at one point: rhs(), or in flux form S - sum_d div_d F_d with each face's flux from a shifted view.
  template <class E, class P, class G> static void rhs_of(const E &eq, const P &pt, G *g) {
    if constexpr (Flux) {
      if constexpr (pointwise::HasSource<Eq>::value) eq.source(pt, g);
      else
        for (int c = 0; c < C; ++c) g[c] = G(0.0);
      if constexpr (NFACE > 0) {
        add_faces<0>(eq, pt, g, std::make_integer_sequence<int, NFACE>());
        if constexpr (D >= 2) add_faces<1>(eq, pt, g, std::make_integer_sequence<int, NFACE>());
        if constexpr (D == 3) add_faces<2>(eq, pt, g, std::make_integer_sequence<int, NFACE>());
      }
    } else eq.rhs(pt, g);
  }
  template <int d, class E, class P, class G, int... k>
  static void add_faces(const E &eq, const P &pt, G *g, std::integer_sequence<int, k...>) {
    constexpr auto w = divergence_of();
    const double ih = pt.inv_h(d);
    (add_face<d, k - NFACE / 2>(eq, pt, g, -w[k] * ih), ...);
  }
  template <int d, int s, class E, class P, class G> static void add_face(const E &eq, const P &pt, G *g, double wk) {
    G F[C];
    eq.flux(pointwise::Shifted<P, d == 0 ? s : 0, d == 1 ? s : 0, d == 2 ? s : 0>(pt), Direction<d>(), F);
    for (int c = 0; c < C; ++c) g[c] += wk * F[c];
  }

  pointwise::Frame frame(PetscReal t, const StateView &s, const PetscScalar *P) const {
    pointwise::Frame f = frame_;
    f.t = t, f.U = s.u.data(), f.Ug = s.g.data(), f.A = KL ? s.line : s.a.data(), f.P = P;
    return f;
  }
  // The frame of the Edge points: the state and its direction read from their ghosted arrays.
  static pointwise::Frame edge_frame(const pointwise::Frame &f) {
    pointwise::Frame e = f;
    e.U = f.Ug, e.X = f.Xg, e.syo = f.sy, e.szo = f.sz;
    return e;
  }
  // Every owned point: its index in the ghosted arrays, in the owned block, its grid indices, and
  // Check<true> when it lies within `margin` of the owned block's edge (its reads are checked: they
  // may reach ghosts or beyond a wall), else Check<false>.
  // With Edges, only the points on a wall are checked; the others within `margin` of the block's edge
  // are Edge points.
  // NearWall: tell EdgeNearWall points from Edge ones (the gather alone needs to: other sweeps take them
  // alike, with one copy of their code fewer).
  // The points are visited kind by kind (run_kind), each kind's runs in row order.
  template <bool Edges = false, bool NearWall = false, class F> void for_points(PetscInt margin, F &&body) const {
    const RunPlan &plan = runs(margin, Edges, NearWall);
    run_kind(plan.kind[0], body, Check<false>());
    run_kind(plan.kind[1], body, Check<true>());
    if constexpr (Edges) run_kind(plan.kind[2], body, Edge());
    if constexpr (NearWall) run_kind(plan.kind[3], body, EdgeNearWall());
  }
  // Points i0 .. i0 + n - 1 of row (j, k), the first at ghosted index `at` and owned index `own`.
  struct Run {
    PetscInt at, own, i0, n, j, k;
  };
  struct RunPlan {
    std::vector<Run> kind[4]; // Check<false>, Check<true>, Edge, EdgeNearWall
  };
  // A plan's runs row by row (rows (j, k) in memory order, each kind's runs in that order).
  struct RowCursor {
    explicit RowCursor(const RunPlan &p) : plan(p) {}
    std::pair<const Run *, const Run *> take(int kind, PetscInt j, PetscInt k) { // the runs of one kind in row (j, k)
      const std::vector<Run> &v = plan.kind[kind];
      const size_t a = next[kind];
      while (next[kind] < v.size() && v[next[kind]].j == j && v[next[kind]].k == k) ++next[kind];
      return {v.data() + a, v.data() + next[kind]};
    }
    const RunPlan &plan;
    size_t next[4] = {0, 0, 0, 0};
  };
  // Whether owned row r (rows (j, k) in memory order) has points B or more points (and rows, planes)
  // from the block's edge: its inner points, [r xm + B, r xm + xm - B).
  bool inner_row(PetscInt B, PetscInt r) const {
    const PetscInt xm = grid_->xm(), ym = grid_->ym(), zm = grid_->zm(), j = r % ym, k = r / ym;
    return xm > 2 * B && j >= B && j < ym - B && (D < 3 || (k >= B && k < zm - B));
  }
  // fn(lo, hi) on the owned points within B of the block's edge, ranges [lo, hi) of points in memory order.
  template <class Fn> void for_edge_strips(PetscInt B, Fn &&fn) const {
    const PetscInt xm = grid_->xm(), rows = grid_->ym() * grid_->zm();
    for (PetscInt r = 0; r < rows; ++r) {
      const PetscInt row = r * xm;
      if (!inner_row(B, r)) fn(row, row + xm);
      else fn(row, row + B), fn(row + xm - B, row + xm);
    }
  }
  // The owned rows (j, k) in memory order, row(r, j, k) on each, and inner(lo, hi) on the inner points
  // of every inner row up to two rows beyond the reach of row r's stencils (R rows in 2D, R planes in
  // 3D) before it: what row r reads has had its inner() a little earlier, so it is still in the cache,
  // and none of it has stores still on their way there. (The leapfrog's fused step and kick.)
  template <class Inner, class Row> void for_rows_ahead(PetscInt B, Inner &&inner, Row &&row) const {
    const PetscInt xm = grid_->xm(), ym = grid_->ym(), rows = ym * grid_->zm();
    const PetscInt ahead = (D == 3 ? R * ym : R) + 2;
    for (PetscInt r = 0, done = 0; r < rows; ++r) {
      for (; done < rows && done <= r + ahead; ++done)
        if (inner_row(B, done)) inner(done * xm + B, done * xm + xm - B);
      row(r, grid_->ys() + r % ym, grid_->zs() + r / ym);
    }
  }
  // All runs of one kind: one function per kind and sweep, whose loops the compiler vectorises. It
  // works on its own copy of the sweep's point function, so that what that captures by value (the
  // model, the frame) is known to no store. (A sweep writes the point's own entries alone and reads
  // none that it writes (the leapfrog kick writes lambda_q and reads lambda_p of one array): no
  // iteration depends on another.)
  template <class F, class Kind> void run_kind(const std::vector<Run> &runs, const F &body, Kind ck) const {
    run_kind(runs.data(), runs.data() + runs.size(), body, ck);
  }
  template <class F, class Kind> FLEXIPDE_RUN void run_kind(const Run *first, const Run *last, const F &body, Kind ck) const {
    if (first == last) return;
    const auto point = body;
    for (const Run *it = first; it != last; ++it) {
      const Run &r = *it;
      const PetscInt at = r.at, own = r.own, i0 = r.i0, j = r.j, k = r.k;
#pragma GCC ivdep
      for (PetscInt q = 0; q < r.n; ++q) point(at + q, own + q, i0 + q, j, k, ck);
    }
  }
  // G in flux form on runs of unchecked points, with each face along x formed once: a block's faces
  // into a small array, then the block's G from it. (G point by point forms each face at every one
  // of the NFACE points it enters.) The same operations in the same order as rhs_of.
  template <bool SC, class E>
  FLEXIPDE_RUN void rhs_faces(const std::vector<Run> &runs, const E &model, const pointwise::Frame &frame_in,
                              PetscScalar *out) const {
    if (runs.empty()) return;
    const E eq = model;
    const pointwise::Frame f = frame_in;
    using P = Pt<Mode::Value, 0, 0, false, C, false, SC>;
    constexpr int B = 256, L = NFACE / 2;
    constexpr auto w = divergence_of();
    double wk[NFACE];
    for (int k = 0; k < NFACE; ++k) wk[k] = -w[k] * f.ih[0];
    // face q of a block (0 <= q < m + NFACE - 1) has its left point at q - L
    double F[(B + NFACE - 1) * C];
    for (const Run &r : runs)
      for (PetscInt b0 = 0; b0 < r.n; b0 += B) {
        const PetscInt m = std::min<PetscInt>(B, r.n - b0), at = r.at + b0, own = r.own + b0, i0 = r.i0 + b0, j = r.j, k = r.k;
        // (a face's reads lie within R of the run's points, in the owned block: its left point reads unchecked)
#pragma GCC ivdep
        for (PetscInt q = 0; q < m + NFACE - 1; ++q)
          eq.flux(P(f, at + q - L, own + q - L, i0 + q - L, j, k), Direction<0>(), F + q * C);
#pragma GCC ivdep
        for (PetscInt q = 0; q < m; ++q) {
          const P pt(f, at + q, own + q, i0 + q, j, k);
          double g[C];
          if constexpr (pointwise::HasSource<Eq>::value) eq.source(pt, g);
          else
            for (int c = 0; c < C; ++c) g[c] = 0.0;
          for (int e = 0; e < NFACE; ++e)
            for (int c = 0; c < C; ++c) g[c] += wk[e] * F[(q + e) * C + c];
          if constexpr (D >= 2) add_faces<1>(eq, pt, g, std::make_integer_sequence<int, NFACE>());
          if constexpr (D == 3) add_faces<2>(eq, pt, g, std::make_integer_sequence<int, NFACE>());
          for (int c = 0; c < C; ++c) out[(own + q) * C + c] = g[c];
        }
      }
  }

  // The gather on runs of unchecked points in flux form, with each face along x differentiated once:
  // for a block of points, every face that reads one of them, with respect to all its inputs at once
  // (FaceInputs), times its weights' combination of x, added to the points it reads; then each point's
  // source and faces along y and z as gather_offsets, and `store`. (The gather point by point differentiates
  // a face at every one of the 2 RF points it reads.)
  template <int CLO, int CHI, bool SC, class E, class Store>
  FLEXIPDE_RUN void gather_face_runs(const std::vector<Run> &runs, const E &model, const pointwise::Frame &frame_in,
                                     const PetscScalar *xh, const Store &put) const {
    if (runs.empty()) return;
    const E eq = model;
    const pointwise::Frame f = frame_in;
    const Store store = put;
    constexpr int NL = SC ? 0 : NG, L = NFACE / 2, B = 128, S = C + NL, PAD = 2 * RF - 1;
    using P = Pt<Mode::Value, 0, 0, false, C, false, SC>;
    using FP = pointwise::FaceInputs<P, C, NL, RF>;
    constexpr auto w = divergence_of();
    // face q of a block (0 <= q < m + PAD) has its left point at q - RF and reads the point q - PAD + e
    // at e (0 <= e < 2 RF); T[e][s][q] is its term for input s of that point (q fastest: both loops
    // below run over q with unit stride, and vectorise)
    constexpr int NB = B + PAD;
    double T[NB * 2 * RF * S];
    for (const Run &r : runs)
      for (PetscInt b0 = 0; b0 < r.n; b0 += B) {
        const PetscInt m = std::min<PetscInt>(B, r.n - b0), at = r.at + b0, own = r.own + b0, i0 = r.i0 + b0, j = r.j, k = r.k;
#pragma GCC ivdep
        for (PetscInt q = 0; q < m + PAD; ++q) {
          const PetscInt l = q - RF;
          double xw[C] = {};
          for (int c = CLO; c < CHI; ++c) {
            double s = 0;
            for (int e = 0; e < NFACE; ++e) s += w[e] * PetscRealPart(f.X[(own + l + L - e) * C + c]);
            xw[c] = s * -f.ih[0];
          }
          typename FP::Number F[C];
          eq.flux(FP(P(f, at + l, own + l, i0 + l, j, k)), Direction<0>(), F);
          for (int e = 0; e < 2 * RF * S; ++e) {
            double s = 0;
            for (int c = CLO; c < CHI; ++c) s += F[c].d[e] * xw[c];
            T[e * NB + q] = s;
          }
        }
#pragma GCC ivdep
        for (PetscInt q = 0; q < m; ++q) {
          double yv[C] = {}, zv[K > 0 ? K : 1] = {}, gv[NG > 0 ? NG : 1] = {};
          for (int e = 0; e < 2 * RF; ++e) {
            const double *t = T + e * S * NB + q + PAD - e;
            for (int c = 0; c < C; ++c) yv[c] += t[c * NB];
            for (int p = 0; p < NL; ++p) gv[p] += t[(C + p) * NB];
          }
          gather_offsets<CLO, CHI, 0, C, SC, false>(eq, f, xh, at + q, own + q, i0 + q, j, k, yv, zv, gv,
                                                   std::make_integer_sequence<int, Sten::size>());
          store(own + q, i0 + q, yv, zv, gv);
        }
      }
  }
  // The runs of each kind of point for a sweep with this margin (made once per margin and flags).
  const RunPlan &runs(PetscInt margin, bool with_edges, bool near_wall) const {
    const PetscInt key = 4 * margin + 2 * with_edges + near_wall;
    for (const auto &p : plans_)
      if (p.first == key) return p.second;
    plans_.emplace_back(key, RunPlan());
    RunPlan &plan = plans_.back().second;
    PetscInt gxs, gys, gzs, gxm, gym, gzm;
    ghost_corners(gxs, gys, gzs, gxm, gym, gzm);
    const PetscInt xs = grid_->xs(), xm = grid_->xm(), ys = grid_->ys(), ym = grid_->ym(), zs = grid_->zs(), zm = grid_->zm();
    const PetscInt xe = xs + xm;
    margin = std::max<PetscInt>(margin, 1); // wall points are never Inside: their G may test wall()
    // with held walls an unchecked point's stencil stops short of them: one more checked point there
    const bool held = frame_.held;
    const auto wall_lo = [&](int d) -> PetscInt { return held && d < D && !grid_->periodic(d) && grid_->start(d) == 0; };
    const auto wall_hi = [&](int d) -> PetscInt {
      return held && d < D && !grid_->periodic(d) && grid_->start(d) + grid_->owned(d) == grid_->n(d);
    };
    const PetscInt lo = std::min(xs + margin + wall_lo(0), xe), hi = std::max(lo, xe - margin - wall_hi(0));
    const PetscInt nx = grid_->n(), ny = grid_->ny(), nz = grid_->nz();
    const bool wx = !grid_->periodic(), wy = D > 1 && !grid_->periodic_y(), wz = D > 2 && !grid_->periodic_z();
    enum { Inside, Checked, EdgeKind, NearKind };
    auto run = [&](PetscInt j, PetscInt k, PetscInt i0, PetscInt i1, int kind) {
      if (i1 > i0)
        plan.kind[kind].push_back(
            {((k - gzs) * gym + (j - gys)) * gxm - gxs + i0, ((k - zs) * ym + (j - ys)) * xm - xs + i0, i0, i1 - i0, j, k});
    };
    // The points of row (j, k) in [i0, i1) outside the unchecked interior: checked on a wall, else Edge,
    // or EdgeNearWall within R of a wall (the gather's neighbours there may lie beyond it or on it).
    // With walls beyond which the state is 0 (neither odd nor held) the gather takes a wall point as
    // EdgeNearWall too: the ghosted arrays hold those zeros, and no point has an image to find.
    const bool zero_walls = near_wall && !frame_.odd[0] && !frame_.odd[1] && !frame_.odd[2] && !held;
    const int wall_kind = zero_walls ? NearKind : Checked, cw = zero_walls ? 0 : 1;
    auto edges = [&](PetscInt j, PetscInt k, PetscInt i0, PetscInt i1) {
      if (!with_edges) return run(j, k, i0, i1, Checked);
      const bool wall_row = (wy && (j == 0 || j == ny - 1)) || (wz && (k == 0 || k == nz - 1));
      const bool near_row = (wy && (j <= R || j >= ny - 1 - R)) || (wz && (k <= R || k >= nz - 1 - R));
      if (wall_row) return run(j, k, i0, i1, wall_kind);
      // columns: [0] the wall, [1, R] near it, then the free run, [nx - 1 - R, nx - 2] near, [nx - 1] the wall
      const PetscInt a0 = wx ? std::clamp<PetscInt>(cw, i0, i1) : i0, a1 = wx ? std::clamp<PetscInt>(R + 1, i0, i1) : i0;
      const PetscInt b1 = wx ? std::clamp<PetscInt>(nx - cw, a1, i1) : i1, b0 = wx ? std::clamp<PetscInt>(nx - 1 - R, a1, b1) : i1;
      const int near = near_wall ? NearKind : EdgeKind;
      run(j, k, i0, a0, Checked);
      run(j, k, a0, a1, near);
      run(j, k, a1, b0, near_row ? near : EdgeKind);
      run(j, k, b0, b1, near);
      run(j, k, b1, i1, Checked);
    };
    for (PetscInt k = zs; k < zs + zm; ++k) {
      const bool inside_z = D < 3 || (k >= zs + margin + wall_lo(2) && k < zs + zm - margin - wall_hi(2));
      for (PetscInt j = ys; j < ys + ym; ++j) {
        const bool inside = D == 1 || (inside_z && j >= ys + margin + wall_lo(1) && j < ys + ym - margin - wall_hi(1));
        if (!inside) {
          edges(j, k, xs, xe);
          continue;
        }
        edges(j, k, xs, lo);
        run(j, k, lo, hi, Inside);
        edges(j, k, hi, xe);
      }
    }
    return plan;
  }
  // The state DM's ghosted box (its y and z extents 1 in the dimensions the grid lacks).
  void ghost_corners(PetscInt &gxs, PetscInt &gys, PetscInt &gzs, PetscInt &gxm, PetscInt &gym, PetscInt &gzm) const {
    DMDAGetGhostCorners(dm_, &gxs, &gys, &gzs, &gxm, &gym, &gzm);
    if (D < 2) gys = 0, gym = 1;
    if (D < 3) gzs = 0, gzm = 1;
  }

  PetscErrorCode to_local(Vec g, Vec l) const {
    PetscFunctionBeginUser;
    PetscCall(DMGlobalToLocal(dm_, g, INSERT_VALUES, l));
    PetscFunctionReturn(0);
  }
  PetscErrorCode create_state(LocalState &s) const {
    PetscFunctionBeginUser;
    PetscCall(DMCreateLocalVector(dm_, s.g.out()));
    PetscCall(VecSet(s.g, 0.0)); // beyond a wall: never written
    PetscCall(DMCreateGlobalVector(dm_, s.copy.out()));
    PetscCall(VecSet(s.copy, 0.0));
    s.ref = s.copy;
    PetscFunctionReturn(0);
  }
  // The ghosted `local` from the global x, NC components per point: its ghosts and the owned points within
  // `strip` (strip_ unless given) of the block's edge (all a checked or Edge point reads), then the positions the fold table
  // maps elsewhere: mirror images beyond odd walls (their sign times the point's value) and 0 on held
  // walls and beyond other walls, or, for a cotangent (the x of a transpose, whose entries are per
  // equation), 0 at all of them: beyond a wall and on a held wall there is no equation.
  // begun: the caller has begun the scatter (to have two arrays' ghosts on their way at once). NC is known
  // at compile time so that a fold's NC stores are inline, not a call per position.
  template <int NC = C>
  PetscErrorCode fill_ghosts(Vec x, Vec local, const GhostExchange &ex, bool cotangent = false, bool begun = false,
                             PetscInt strip = 0) const {
    PetscFunctionBeginUser;
    if (!begun) PetscCall(ex.begin(x, local));
    {
      ConstArray o(x);
      Array g(local);
      PetscCall(o.error());
      PetscCall(g.error());
      PetscInt gxs, gys, gzs, gxm, gym, gzm;
      ghost_corners(gxs, gys, gzs, gxm, gym, gzm);
      const PetscInt xs = grid_->xs(), xm = grid_->xm(), ys = grid_->ys(), ym = grid_->ym(), zs = grid_->zs(), zm = grid_->zm();
      const PetscInt w = strip > 0 ? strip : strip_;
      auto copy = [&](PetscInt j, PetscInt k, PetscInt i0, PetscInt i1) {
        copy_entries(o.data() + (((k - zs) * ym + j - ys) * xm + i0 - xs) * NC, (i1 - i0) * NC,
                     g.data() + (((k - gzs) * gym + j - gys) * gxm + i0 - gxs) * NC);
      };
      for (PetscInt k = zs; k < zs + zm; ++k) {
        const bool edge_plane = D > 2 && (k < zs + w || k >= zs + zm - w);
        for (PetscInt j = ys; j < ys + ym; ++j) {
          if (edge_plane || (D > 1 && (j < ys + w || j >= ys + ym - w)) || xm <= 2 * w) copy(j, k, xs, xs + xm);
          else copy(j, k, xs, xs + w), copy(j, k, xs + xm - w, xs + xm);
        }
      }
      ex.copy_own(o.data(), g.data());
    }
    PetscCall(ex.end(x, local));
    if (!folded_.empty()) {
      Array g(local);
      PetscCall(g.error());
      PetscScalar *a = g.data();
      for (const auto &e : folded_)
        for (int c = 0; c < NC; ++c) a[e.at * NC + c] = cotangent || e.src < 0 ? 0.0 : e.sign * a[e.src * NC + c];
    }
    PetscFunctionReturn(0);
  }
  PetscErrorCode fill_ghosts(Vec x, Vec local, bool cotangent = false) const {
    return fill_ghosts(x, local, ghosts_, cotangent);
  }
  // The ghosted box's sources and signs (Frame::src, Frame::sgn).
  void make_fold_table() {
    PetscInt gxs, gys, gzs, gxm, gym, gzm;
    ghost_corners(gxs, gys, gzs, gxm, gym, gzm);
    src_.assign(gxm * gym * gzm, -1), sgn_.assign(gxm * gym * gzm, 1.0);
    const bool odd = frame_.odd[0], held = frame_.held;
    auto fold = [&](int d, PetscInt &g, double &sign) {
      const PetscInt n = grid_->n(d);
      const bool periodic = grid_->periodic(d);
      if (periodic || (g >= 0 && g < n)) return !(held && !periodic && (g == 0 || g == n - 1));
      if (!odd) return false;
      g = g < 0 ? -g : 2 * (n - 1) - g, sign = -sign;
      return !(held && (g == 0 || g == n - 1));
    };
    for (PetscInt c = 0; c < gzm; ++c)
      for (PetscInt b = 0; b < gym; ++b)
        for (PetscInt a = 0; a < gxm; ++a) {
          PetscInt gi = gxs + a, gj = gys + b, gk = gzs + c;
          double sign = 1;
          if (!fold(0, gi, sign) || (D > 1 && !fold(1, gj, sign)) || (D > 2 && !fold(2, gk, sign))) continue;
          const PetscInt p = (c * gym + b) * gxm + a;
          src_[p] = ((gk - gzs) * gym + (gj - gys)) * gxm + (gi - gxs), sgn_[p] = sign;
        }
    frame_.src = src_.data(), frame_.sgn = sgn_.data();
    // The positions that hold another point's image or 0, and the images of owned points that a real
    // point's stencil reaches (within R beyond the walls) whose point is not on a wall itself (a wall
    // point is checked: its gather finds its images through the table).
    folded_.clear(), images_.clear();
    for (auto &runs : image_runs_) runs.clear();
    const PetscInt xs = grid_->xs(), xm = grid_->xm(), ys = grid_->ys(), ym = grid_->ym(), zs = grid_->zs(), zm = grid_->zm();
    const PetscInt nx = grid_->n(), ny = grid_->ny(), nz = grid_->nz();
    const bool wx = !grid_->periodic(), wy = D > 1 && !grid_->periodic_y(), wz = D > 2 && !grid_->periodic_z();
    for (PetscInt c = 0; c < gzm; ++c)
      for (PetscInt b = 0; b < gym; ++b)
        for (PetscInt a = 0; a < gxm; ++a) {
          const PetscInt p = (c * gym + b) * gxm + a, gi = gxs + a, gj = gys + b, gk = gzs + c, s = src_[p];
          if (s == p) continue;
          folded_.push_back({p, s, sgn_[p]});
          if (s < 0) continue;
          const PetscInt si = gxs + s % gxm, sj = gys + (s / gxm) % gym, sk = gzs + s / (gxm * gym);
          const bool reach = (gi >= -R && gi < nx + R) && (D == 1 || (gj >= -R && gj < ny + R)) && (D < 3 || (gk >= -R && gk < nz + R));
          const bool owned = si >= xs && si < xs + xm && sj >= ys && sj < ys + ym && sk >= zs && sk < zs + zm;
          const bool on_wall =
              (wx && (si == 0 || si == nx - 1)) || (wy && (sj == 0 || sj == ny - 1)) || (wz && (sk == 0 || sk == nz - 1));
          const bool bx = wx && (gi < 0 || gi >= nx), by = wy && (gj < 0 || gj >= ny), bz = wz && (gk < 0 || gk >= nz);
          if (!((bx || by || bz) && reach && owned && !on_wall)) continue;
          const PetscInt own = ((sk - zs) * ym + (sj - ys)) * xm + (si - xs);
          // beyond one wall, whose readers (R or fewer points in) are not on the other wall: into its
          // bucket, extending the last run when it continues it along x
          const int d = bx ? 0 : by ? 1 : 2;
          if (ImageRuns && frame_.held && int(bx) + int(by) + int(bz) == 1 && grid_->n(d) >= R + 2) {
            const PetscInt n = grid_->n(d), g = d == 0 ? gi : d == 1 ? gj : gk;
            const int side = g < 0 ? 0 : 1, depth = int(g < 0 ? -g : g - (n - 1));
            auto &runs = image_runs_[(2 * d + side) * R + depth - 1];
            if (!runs.empty()) {
              ImageRun &r = runs.back();
              if (r.j == gj && r.k == gk && r.at + r.n == p && r.own + r.n == own && r.i0 + r.n == gi && r.sign == sgn_[p]) {
                ++r.n;
                continue;
              }
            }
            runs.push_back({p, own, gi, 1, gj, gk, sgn_[p]});
          } else images_.push_back({p, own, gi, 1, gj, gk, sgn_[p]});
        }
  }
  // The state U for the sweeps: read in place (the caller keeps U unchanged while s is used) or, if
  // `keep`, from a copy (for products applied later); its ghosts and auxiliary fields.
  // strip: the owned edge strips to copy (fill_ghosts; 0: the gather's).
  PetscErrorCode load(Vec U, LocalState &s, bool keep = false, PetscInt strip = 0) {
    PetscFunctionBeginUser;
    if (keep) PetscCall(VecCopy(U, s.copy));
    s.ref = keep ? s.copy.get() : U;
    PetscCall(fill_ghosts(s.ref, s.g, ghosts_, false, false, strip));
    if constexpr (KL) PetscCall(auxiliary_lines(s.ref, s.line));
    else if constexpr (K > 0)
      if (!uniform_) PetscCall(auxiliaries(s.ref, s.a)); // (uniform coupling: the sweeps read a = 0)
    PetscFunctionReturn(0);
  }
  // The auxiliary lines a_k = L_k s of U, s its column sums (over all ranks; collective), K per column,
  // padded (pad_lines).
  PetscErrorCode auxiliary_lines(Vec U, std::vector<PetscReal> &line) {
    const PetscInt n = grid_->n(), xs = grid_->xs(), xm = grid_->xm(), ym = grid_->ym();
    PetscFunctionBeginUser;
    if constexpr (KL) {
      std::fill(sums_.begin(), sums_.end(), 0.0);
      {
        ConstArray u(U);
        PetscCall(u.error());
        const PetscScalar *a = u.data();
        PetscReal *sum = sums_.data() + xs * C;
        for (PetscInt j = 0; j < ym; ++j)
          for (PetscInt q = 0; q < xm * C; ++q) sum[q] += PetscRealPart(a[j * xm * C + q]);
      }
      PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, sums_.data(), (PetscMPIInt)(n * C), MPIU_REAL, MPI_SUM, grid_->comm()));
      for (int k = 0; k < K; ++k) {
        PetscCall(eq_.auxiliary(k, sums_.data(), aline_.data()));
        for (PetscInt i = 0; i < n; ++i) line[(i + line_pad) * K + k] = aline_[i];
      }
      pad_lines(line.data() + line_pad * K, line);
    }
    PetscFunctionReturn(0);
  }
  // line = the lines a (K per column, n columns; may be line's own middle) padded by line_pad columns
  // each side: periodic images, or 0 beyond walls.
  void pad_lines(const PetscScalar *a, std::vector<PetscReal> &line) const {
    const PetscInt n = grid_->n();
    const bool periodic = grid_->periodic();
    if (a != line.data() + line_pad * K) std::copy(a, a + n * K, line.begin() + line_pad * K);
    for (PetscInt i = -line_pad; i < n + line_pad; ++i) {
      if (i >= 0 && i < n) continue;
      const PetscInt src = periodic ? (i % n + n) % n : -1;
      for (int k = 0; k < K; ++k) line[(i + line_pad) * K + k] = src >= 0 ? line[(src + line_pad) * K + k] : 0.0;
    }
  }
  // y += w R sum_k L_k^T z_k, z_k the column sums of the gather's (dG/da_k)^T x (in zline_, this
  // rank's share; summed here, collective) and R the copy of a line to every row.
  PetscErrorCode add_auxiliary_lines_transpose(Vec y, PetscReal w) {
    const PetscInt n = grid_->n(), xs = grid_->xs(), xm = grid_->xm(), ym = grid_->ym();
    PetscFunctionBeginUser;
    if constexpr (KL) {
      PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, zline_.data(), (PetscMPIInt)(n * K), MPIU_REAL, MPI_SUM, grid_->comm()));
      std::fill(wline_.begin(), wline_.end(), 0.0);
      for (int k = 0; k < K; ++k) {
        for (PetscInt i = 0; i < n; ++i) aline_[i] = zline_[i * K + k];
        PetscCall(eq_.auxiliary_transpose(k, aline_.data(), wline_.data()));
      }
      Array ya(y);
      PetscCall(ya.error());
      PetscScalar *out = ya.data();
      const PetscReal *wl = wline_.data() + xs * C;
      for (PetscInt j = 0; j < ym; ++j)
        for (PetscInt q = 0; q < xm * C; ++q) out[j * xm * C + q] += w * wl[q];
    }
    PetscFunctionReturn(0);
  }
  // a_k = L_k U for every k, ghosted into `local` (K per point).
  PetscErrorCode auxiliaries(Vec U, Vec local) {
    PetscFunctionBeginUser;
    if constexpr (K > 0 && !KL) {
      if constexpr (pointwise::HasMapsAtOnce<Eq>::value) {
        PetscCall(eq_.auxiliary_fields(U, map_vecs_.data()));
        PetscCall(VecStrideScatterAll(map_vecs_.data(), Ag_, INSERT_VALUES));
      } else
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
    if constexpr (H > 0 && pointwise::HasMapsAtOnce<Eq>::value) {
      PetscCall(VecStrideGatherAll(Hg_, map_vecs_.data(), INSERT_VALUES));
      PetscCall(eq_.output_fields(map_vecs_.data(), G));
    } else if constexpr (H > 0)
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
      if (mapped_[k]) PetscCall(map_parameter(k, f));
      PetscCall(VecStrideScatter(f, k, Pg_, INSERT_VALUES));
    }
    PetscCall(DMGlobalToLocal(param_dm_, Pg_, INSERT_VALUES, l));
    // a scalar's direction, like its value (set_parameters), everywhere: beyond walls too
    // (a fixed slot's direction is 0 everywhere already)
    PetscReal value[NP > 0 ? NP : 1] = {};
    for (int k = 0; k < NP; ++k)
      if (index_[k] >= 0 && constant_slot(k)) PetscCall(VecStrideMin(Pg_, k, nullptr, &value[k]));
    Array la(l);
    PetscInt n;
    PetscCall(la.error());
    PetscCall(VecGetLocalSize(l, &n));
    for (int k = 0; k < NP; ++k)
      if (index_[k] >= 0 && constant_slot(k)) fill_slot(la.data(), n, k, value[k]);
    PetscFunctionReturn(0);
  }
  // Slot k holds one value, read everywhere: a scalar parameter, or a slot fixed by the scene.
  bool constant_slot(int k) const {
    return index_[k] < 0 || (params_->info(index_[k]).kind == ParamKind::Scalar && !mapped_[k]);
  }
  // Slot k of the ghosted per-point parameter array a (n entries) set to v at every position.
  static void fill_slot(PetscScalar *a, PetscInt n, int k, PetscReal v) {
    for (PetscInt q = 0; q < n / (NP + NF); ++q) a[q * (NP + NF) + k] = v;
  }
  // Where parameter k's pointwise gradient goes: a field's entries of the packed array m, a scalar's
  // accumulator during an adjoint, else a scratch array summed by flush_scratch_scalars.
  // With `dummy`, a slot that is not a parameter gets a scratch target instead of null (one per slot:
  // the sweeps add to every target without a branch, and no two targets overlap).
  void fill_gradient_targets(PetscScalar *m, bool in_adjoint, PetscReal **gk, bool dummy = false) {
    for (int k = 0; k < NP; ++k) {
      gk[k] = nullptr;
      if (index_[k] < 0) {
        if (dummy) gk[k] = scratch_target(k);
        continue;
      }
      const ParamInfo &pi = params_->info(index_[k]);
      if (pi.kind == ParamKind::Field && !mapped_[k]) gk[k] = reinterpret_cast<PetscReal *>(m + pi.local_offset);
      else if (in_adjoint) gk[k] = scalar_acc_[k].data();
      else {
        scratch_scalar_[k].assign(grid_->local_points(), 0.0);
        gk[k] = scratch_scalar_[k].data();
      }
    }
  }
  // Every parameter's pointwise gradient into scratch (a sweep that forms it when no one asked).
  void scratch_targets(PetscReal **gk) {
    for (int k = 0; k < NP; ++k) gk[k] = scratch_target(k);
  }
  // Slot k's scratch target: one per slot, so that no two targets overlap.
  PetscReal *scratch_target(int k) {
    if (dummy_target_[k].size() != (size_t)grid_->local_points()) dummy_target_[k].assign(grid_->local_points(), 0.0);
    return dummy_target_[k].data();
  }
  PetscErrorCode flush_scratch_scalars(Vec mu) {
    PetscFunctionBeginUser;
    for (int k = 0; k < NP; ++k)
      if (accumulated(k) && !scratch_scalar_[k].empty()) {
        PetscCall(add_accumulated(mu, k, scratch_scalar_[k]));
        scratch_scalar_[k].clear();
      }
    PetscFunctionReturn(0);
  }
  // Whether parameter k's pointwise gradient is accumulated apart and added at once (add_accumulated): a
  // scalar's (summed) and a mapped field's (M applied), else written into the gradient in place.
  bool accumulated(int k) const {
    return index_[k] >= 0 && (params_->info(index_[k]).kind == ParamKind::Scalar || mapped_[k]);
  }
  // mu[k] += the accumulated pointwise gradient g: a scalar's sum over the points and ranks, or a mapped
  // field's M g (collective).
  PetscErrorCode add_accumulated(Vec mu, int k, std::vector<PetscReal> &g) {
    PetscFunctionBeginUser;
    if (!mapped_[k]) {
      PetscCall(params_->add_local_sum(mu, index_[k], sum(g)));
      PetscFunctionReturn(0);
    }
    OwnedVec f;
    PetscCall(DMCreateGlobalVector(grid_->dm(), f.out()));
    {
      Array a(f);
      PetscCall(a.error());
      std::copy(g.begin(), g.end(), a.data());
    }
    PetscCall(map_parameter(k, f));
    {
      ConstArray a(f);
      PetscCall(a.error());
      std::copy(a.data(), a.data() + g.size(), g.begin());
    }
    PetscCall(params_->add_pointwise(mu, index_[k], g));
    PetscFunctionReturn(0);
  }
  PetscErrorCode map_parameter(int k, Vec f) const {
    if constexpr (pointwise::HasParameterMap<Eq>::value) return eq_.map_parameter(k, f);
    return 0;
  }
  static PetscReal sum(const std::vector<PetscReal> &a) {
    PetscReal s[4] = {0, 0, 0, 0};
    size_t i = 0;
    for (; i + 4 <= a.size(); i += 4) s[0] += a[i], s[1] += a[i + 1], s[2] += a[i + 2], s[3] += a[i + 3];
    for (; i < a.size(); ++i) s[0] += a[i];
    return (s[0] + s[1]) + (s[2] + s[3]);
  }

  // The gather at owned point (i, j, k): for each stencil offset o, G at the point - o (when it exists)
  // differentiated with respect to the inputs at the point, contracted with x there.
  // In flux form, away from walls: the source's gather so, and each face that reads the point once.
  // XF: with the faces along x (else the caller has them: gather_face_runs).
  template <int CLO, int CHI, int W, int CS, bool SC, bool XF = true, bool SPLIT = false, class M, int... E>
  static void gather_offsets(const M &eq, const pointwise::Frame &f, const PetscScalar *xh, PetscInt at, PetscInt own, PetscInt i,
                             PetscInt j, PetscInt k, double *yv, double *zv, double *gv, std::integer_sequence<int, E...>) {
    static_assert(!(SPLIT && Flux), "split arrays: the leapfrog's models, never in flux form");
    if constexpr (Flux && (W == 0 || W == 2)) {
      if constexpr (pointwise::HasSource<Eq>::value)
        (gather_one<Sten::offset(E)[0], Sten::offset(E)[1], Sten::offset(E)[2], CLO, CHI, W, CS, SC, 1, SPLIT>(eq, f, xh, at, own, i, j, k,
                                                                                                      yv, zv, gv), ...);
      // constant parameters: dG(j)/dp x(j) from G at the point, as the points that take the gather of G
      // count them (per face, the faces between the two kinds of point would be missed or counted twice)
      if constexpr (SC && NG > 0) gather_one<0, 0, 0, CLO, CHI, W, CS, SC, 2, SPLIT>(eq, f, xh, at, own, i, j, k, yv, zv, gv);
      if constexpr (NFACE > 0) {
        using Faces = std::make_integer_sequence<int, 2 * RF>;
        if constexpr (XF) gather_faces<0, CLO, CHI, SC>(eq, f, at, own, i, j, k, yv, gv, Faces());
        if constexpr (D >= 2) gather_faces<1, CLO, CHI, SC>(eq, f, at, own, i, j, k, yv, gv, Faces());
        if constexpr (D == 3) gather_faces<2, CLO, CHI, SC>(eq, f, at, own, i, j, k, yv, gv, Faces());
      }
    } else
      (gather_one<Sten::offset(E)[0], Sten::offset(E)[1], Sten::offset(E)[2], CLO, CHI, W, CS, SC, 0, SPLIT>(eq, f, xh, at, own, i, j,
                                                                                                            k, yv, zv, gv),
       ...);
  }
  // The images beyond one held wall, gathered as runs (image_runs_). Bucket b = (2 d + side) R + depth - 1
  // holds the images at that depth beyond the low (side 0) or high (side 1) wall along d; only G at the
  // points depth + 1 .. R inside the wall along d reads them (G on the wall is 0, beyond it there is
  // none), so their gather takes those offsets alone, unchecked: the entries of the star stencil at
  // -s e_d (low wall) or +s e_d (high wall), s = depth + 1 .. R, in entry order.
  template <int b> static constexpr int image_offset_count() { return R - (b % R + 1); }
  template <int b, int q> static constexpr int image_offset_entry() {
    constexpr int d = b / (2 * R), side = (b / R) % 2, depth = b % R + 1;
    // the star's entries along d are 1 + 2 R d + k, at offset k - R (k < R) or k - R + 1 (k >= R)
    return side == 0 ? 1 + 2 * R * d + q : 1 + 2 * R * d + R + depth + q;
  }
  template <int b, int... q> static constexpr auto image_offsets(std::integer_sequence<int, q...>) {
    return std::integer_sequence<int, image_offset_entry<b, q>()...>();
  }
  template <int CLO, int CHI, int YLO, int YHI, int CS, bool SC, bool SPLIT, class M, int... b>
  void gather_image_runs(const M &eq, const pointwise::Frame &fe, const PetscScalar *xh, PetscScalar *y, PetscReal w,
                         std::integer_sequence<int, b...>) const {
    (gather_image_bucket<b, CLO, CHI, YLO, YHI, CS, SC, SPLIT>(eq, fe, xh, y, w), ...);
  }
  template <int b, int CLO, int CHI, int YLO, int YHI, int CS, bool SC, bool SPLIT, class M>
  FLEXIPDE_RUN void gather_image_bucket(const M &model, const pointwise::Frame &frame_in, const PetscScalar *xh, PetscScalar *y,
                                        PetscReal w) const {
    if constexpr (image_offset_count<b>() > 0) {
      const std::vector<ImageRun> &runs = image_runs_[b];
      if (runs.empty()) return;
      const M eq = model;
      const pointwise::Frame f = frame_in;
      using Sub = decltype(image_offsets<b>(std::make_integer_sequence<int, image_offset_count<b>()>()));
      for (const ImageRun &r : runs) {
        const double ws = w * r.sign;
#pragma GCC ivdep
        for (PetscInt q = 0; q < r.n; ++q) {
          double yv[C] = {}, zv[K > 0 ? K : 1] = {}, gv[NG > 0 ? NG : 1] = {};
          gather_offsets<CLO, CHI, 2, CS, SC, true, SPLIT>(eq, f, xh, r.at + q, r.at + q, r.i0 + q, r.j, r.k, yv, zv, gv, Sub());
          for (int c = YLO; c < YHI; ++c) y[x_at<YLO, YHI, SPLIT>(r.own + q, c)] += ws * yv[c];
        }
      }
    }
  }
  // Where x's component c at a point is: interleaved (C per point) or, SPLIT, in an array of the
  // components [CLO, CHI) alone (the leapfrog adjoint's lambda_p; its lambda_q likewise for y).
  template <int LO, int HI, bool SPLIT> static constexpr PetscInt x_at(PetscInt point, int c) {
    return SPLIT ? point * (HI - LO) + c - LO : point * C + c;
  }
  template <int d, int CLO, int CHI, bool SC, class M, int... q>
  static void gather_faces(const M &eq, const pointwise::Frame &f, PetscInt at, PetscInt own, PetscInt i, PetscInt j, PetscInt k,
                           double *yv, double *gv, std::integer_sequence<int, q...>) {
    (gather_face<d, q + 1 - RF, CLO, CHI, SC>(eq, f, at, own, i, j, k, yv, gv), ...);
  }
  // The face whose left point lies at -o along d from the target reads it at offset o: its flux,
  // differentiated there, times -ih sum_k w_k x at the points it enters (G(L + NFACE/2 - k), L the left point).
  template <int d, int o, int CLO, int CHI, bool SC, class M>
  static void gather_face(const M &eq, const pointwise::Frame &f, PetscInt at, PetscInt own, PetscInt i, PetscInt j, PetscInt k,
                          double *yv, double *gv) {
    constexpr int OX = d == 0 ? o : 0, OY = d == 1 ? o : 0, OZ = d == 2 ? o : 0;
    const PetscInt sat = at - OX - OY * f.sy - OZ * f.sz, sown = own - OX - OY * f.syo - OZ * f.szo;
    using P = Pt<Mode::Gather, OX, OY, false, C, false, SC, OZ>;
    typename P::Number F[C];
    eq.flux(P(f, sat, sown, i - OX, j - OY, k - OZ, i, j, k), Direction<d>(), F);
    constexpr auto w = divergence_of();
    const PetscInt so = d == 0 ? 1 : d == 1 ? f.syo : f.szo;
    for (int c = CLO; c < CHI; ++c) {
      double xw = 0;
      for (int q = 0; q < NFACE; ++q) xw += w[q] * PetscRealPart(f.X[(own + (NFACE / 2 - q - o) * so) * C + c]);
      xw *= -f.ih[d];
      for (int cc = 0; cc < C; ++cc) yv[cc] += F[c].d[cc] * xw;
      if constexpr (!SC)
        for (int q = 0; q < NG; ++q) gv[q] += F[c].d[C + K + q] * xw;
    }
  }
  // W: how the point reads (for_points<true>); G exists at real points alone: near a wall (W = 1, 3) the
  // gather skips the others. (Beyond it the transpose's x reads 0, so that an Edge point's neighbours
  // there would add nothing; but their stencils would reach beyond the ghosted box.)
  // PART: 0 G, 1 the source term S alone (flux form), 2 G for the parameters' lanes alone.
  template <int OX, int OY, int OZ, int CLO, int CHI, int W, int CS, bool SC, int PART = 0, bool SPLIT = false, class M>
  static void gather_one(const M &eq, const pointwise::Frame &f, const PetscScalar *xh, PetscInt at, PetscInt own, PetscInt i,
                         PetscInt j, PetscInt k, double *yv, double *zv, double *gv) {
    constexpr bool CK = W == 1;
    const PetscInt si = i - OX, sj = j - OY, sk = k - OZ;
    if constexpr (W == 1 || W == 3) {
      if (!f.periodic[0] && (si < 0 || si >= f.n[0])) return;
      if (D >= 2 && !f.periodic[1] && (sj < 0 || sj >= f.n[1])) return;
      if (D == 3 && !f.periodic[2] && (sk < 0 || sk >= f.n[2])) return;
    }
    const PetscInt sat = at - OX - OY * f.sy - OZ * f.sz, sown = own - OX - OY * f.syo - OZ * f.szo;
    using P = Pt<Mode::Gather, OX, OY, CK, CS, W == 1 || W == 3, SC, OZ>; // (an Edge point's neighbours are never on a wall)
    typename P::Number gd[C + H];
    if constexpr (PART == 1) eq.source(P(f, sat, sown, si, sj, sk, i, j, k), gd);
    else rhs_of(eq, P(f, sat, sown, si, sj, sk, i, j, k), gd);
    auto contract = [&](const auto &g, double xc) {
      if constexpr (PART != 2)
        for (int cc = 0; cc < C; ++cc) yv[cc] += g.d[cc] * xc;
      for (int q = 0; q < K; ++q) zv[q] += g.d[C + q] * xc;
      if constexpr (!(PART == 1 && SC)) // (constant parameters: PART 2)
        for (int q = 0; q < NG; ++q) gv[q] += g.d[C + K + q] * xc;
    };
    for (int c = CLO; c < CHI; ++c) {
      const PetscInt xi = CK ? x_at<CLO, CHI, SPLIT>(sat, c) : x_at<CLO, CHI, SPLIT>(sown, c);
      contract(gd[c], PetscRealPart(CK ? f.Xg[xi] : f.X[xi]));
    }
    for (int m = 0; m < H; ++m) contract(gd[C + m], PetscRealPart(xh[sat * H + m]));
  }

  // The structurally nonzero entries of a row block (stencil entry, output, input component): those
  // nonzero at random state and parameters at any owned point, or at any point on any rank.
  FLEXIPDE_SWEEP PetscErrorCode find_pattern() {
    OwnedVec Pr;
    LocalState Ur;
    PetscFunctionBeginUser;
    if constexpr (!Local) PetscFunctionReturn(0);
    else {
    PetscCall(create_state(Ur));
    PetscCall(VecDuplicate(P_, Pr.out()));
    std::vector<PetscReal> theta_r(theta_.size()); // random parameter vectors too (the pattern is found before any are set)
    {
      PetscRandom rnd;
      PetscCall(PetscRandomCreate(PETSC_COMM_SELF, &rnd));
      PetscCall(PetscRandomSetInterval(rnd, 0.5, 1.5));
      PetscCall(VecSetRandom(Ur.copy, rnd));
      PetscCall(VecSetRandom(Ur.g, rnd));
      PetscCall(VecSetRandom(Pr, rnd));
      for (auto &v : theta_r) PetscCall(PetscRandomGetValueReal(rnd, &v));
      PetscCall(PetscRandomDestroy(&rnd));
    }
    std::vector<int> local(Sten::size * C * C, 0);
    // At states and at parameters of either sign: an upwind flux reads one side's values for one sign
    // of its state (Burgers) or of its velocity (advection) only.
    for (int pass = 0; pass < 4; ++pass) {
      if (pass == 1 || pass == 3) {
        PetscCall(VecScale(Ur.copy, -1.0));
        PetscCall(VecScale(Ur.g, -1.0));
      }
      if (pass == 2) PetscCall(VecScale(Pr, -1.0));
      StateView u(Ur);
      ConstArray p(Pr);
      pointwise::Frame f = frame(0.5, u, p.data());
      f.theta = theta_r.data();
      for_points(R, [&](PetscInt at, PetscInt own, PetscInt i, PetscInt j, PetscInt k, auto ck) {
        typename Pt<Mode::Rows>::Number gd[C];
        rhs_of(eq_, Pt<Mode::Rows, 0, 0, decltype(ck)::value>(f, at, own, i, j, k), gd);
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
  // The rows of dG/dU, every entry of pattern_ and the diagonal at every owned point in one fixed order: into vals (0
  // beyond a wall), whether the matrix holds it into used (not beyond a wall; for a linear G, not a 0
  // off the diagonal, so that a factorisation fills as for an upwind stencil's side in use), its local
  // row and column into rows and cols, and the Gershgorin discs' bounds into gersh.
  FLEXIPDE_SWEEP PetscErrorCode assemble_rows(PetscReal t, const LocalState &s, std::vector<PetscScalar> *vals,
                                              std::vector<char> *used, PetscReal *gersh = nullptr,
                                              std::vector<PetscInt> *rows = nullptr, std::vector<PetscInt> *cols = nullptr) {
    PetscFunctionBeginUser;
    if constexpr (!Local) PetscFunctionReturn(0);
    else {
    StateView u(s);
    ConstArray p(P_);
    PetscCall(u.error());
    const pointwise::Frame f = frame(t, u, p.data());
    int per_point = 0; // the pattern's entries and the diagonal, which implicit integrators shift
    for (int e = 0; e < Sten::size; ++e)
      for (int c = 0; c < C; ++c)
        for (int cc = 0; cc < C; ++cc) per_point += pattern_[e * C * C + c * C + cc] || (e == 0 && cc == c);
    const size_t n = (size_t)grid_->local_points() * per_point;
    if (vals) vals->resize(n);
    if (used) used->resize(n);
    if (rows) rows->resize(n), cols->resize(n);
    PetscInt gxs = 0, gys = 0, gzs = 0, gxm = 0, gym = 0, gzm = 0;
    if (rows) PetscCall(DMDAGetGhostCorners(matrix_dm_, &gxs, &gys, &gzs, &gxm, &gym, &gzm));
    if (D < 2) gys = 0, gym = 1;
    if (D < 3) gzs = 0;
    const auto local_index = [&](PetscInt i, PetscInt j, PetscInt k, int c) {
      return (((k - gzs) * gym + (j - gys)) * gxm + (i - gxs)) * C + c;
    };
    size_t n_set = 0; // entries set so far
    for_points(R, [&](PetscInt at, PetscInt own, PetscInt i, PetscInt j, PetscInt k, auto ck) {
      typename Pt<Mode::Rows>::Number gd[C];
      rhs_of(eq_, Pt<Mode::Rows, 0, 0, decltype(ck)::value>(f, at, own, i, j, k), gd);
      for (int c = 0; c < C; ++c) {
        double diag = 0, off = 0;
        for (int e = 0; e < Sten::size; ++e) {
          const auto o = Sten::offset(e);
          const PetscInt ci = i + o[0], cj = j + o[1], cz = k + o[2];
          const bool outside = (!f.periodic[0] && (ci < 0 || ci >= f.n[0])) || (D >= 2 && !f.periodic[1] && (cj < 0 || cj >= f.n[1])) ||
                               (D == 3 && !f.periodic[2] && (cz < 0 || cz >= f.n[2]));
          for (int cc = 0; cc < C; ++cc) {
            const bool on_diagonal = e == 0 && cc == c;
            if (!pattern_[e * C * C + c * C + cc] && !on_diagonal) continue;
            const double v = outside ? 0.0 : gd[c].d[e * C + cc];
            if (vals) (*vals)[n_set] = v;
            if (used) (*used)[n_set] = !outside && (!pointwise::LinearOf<Eq>::value || v != 0.0 || on_diagonal);
            if (rows) (*rows)[n_set] = local_index(i, j, k, c), (*cols)[n_set] = local_index(ci, cj, cz, cc);
            ++n_set;
            if (on_diagonal) diag += v;
            else off += std::fabs(v);
          }
        }
        if (gersh) { // the disc {|z - diag| <= off} inside {|z + a| <= a} when diag <= 0 and off <= -diag
          const double a = -diag;
          gersh[0] = std::max(gersh[0], std::fabs(diag) + off);
          if (diag > 0 || off > a * (1 + 1e-12)) gersh[2] = 1;
          else gersh[1] = std::max(gersh[1], a);
        }
      }
    });
    }
    PetscFunctionReturn(0);
  }
  PetscErrorCode gershgorin(Spectrum *s) {
    PetscReal local[3] = {0, 0, 0}, global[3]; // max |diag| + off; max a; any disc not in the left disc
    PetscFunctionBeginUser;
    if (pattern_.empty()) PetscCall(find_pattern());
    PetscCall(assemble_rows(0, jac_, nullptr, nullptr, local));
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
    PetscCall(m->transpose(0, m->jac_, x, y, 1.0, nullptr, false));
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
    PetscCall(m->transpose(m->jp_t_, m->jp_, x, nullptr, 1.0, mu, false));
    PetscFunctionReturn(0);
  }

  Eq eq_;
  const Grid *grid_ = nullptr;
  DM dm_ = nullptr;
  const Parameters *params_ = nullptr;
  PetscInt index_[NP > 0 ? NP : 1] = {};
  PetscReal fixed_[NP > 0 ? NP : 1] = {};
  bool mapped_[NP > 0 ? NP : 1] = {}; // field parameters read through the model's map (HasParameterMap)
  bool constants_ = false; // every parameter G reads is a constant (its value: bounds_.min)
  // G = g(U) + sum_k c_k a_k with c_k = coupling_[k] and dc_k/dp_q = coupling_p_[k][q] the same at every
  // point (Coupling); the sweeps then read a = 0 (zero_aux_) and the maps are applied whole.
  bool uniform_ = false;
  bool local_part_ = true; // g(U) is not 0
  PetscScalar coupling_[K > 0 ? K : 1] = {};
  PetscReal coupling_p_[K > 0 ? K : 1][NG > 0 ? NG : 1] = {};
  std::vector<PetscScalar> zero_aux_;
  OwnedDM param_dm_, matrix_dm_, aux_dm_, out_dm_;
  OwnedVec P_, dP_, Pg_, Xl_;
  LocalState st_, jac_, jp_; // the state of rhs and the adjoint sweeps, of the Jacobian, of dG/dp
  GhostExchange ghosts_; // global -> the ghost entries of a ghosted Vec
  std::vector<PetscReal> coefficients_; // Eq::coefficient at the owned points, NF per point
  std::vector<PetscInt> src_;  // Frame::src, Frame::sgn
  struct Folded {
    PetscInt at, src; // a position of the ghosted box and the one whose value it holds (-1: 0)
    double sign;
  };
  std::vector<Folded> folded_;
  // Mirror images beyond walls (ghosted index, grid indices) of owned points, n of them in a row along
  // x from index at (of the owned points from own).
  struct ImageRun {
    PetscInt at, own, i0, n, j, k;
    double sign;
  };
  std::vector<ImageRun> images_; // those ImageRuns does not cover, one per record, checked point by point
  // A star stencil's images beyond one held wall, gathered on compile-time offsets (gather_image_runs).
  static constexpr bool ImageRuns = Shape == StencilShape::Star && !Flux && pointwise::HasHeldWalls<Eq>::value;
  std::array<std::vector<ImageRun>, 2 * D * R> image_runs_;
  std::vector<PetscInt> forcing_order_; // the leapfrog steps' forced points in row order
  mutable std::deque<std::pair<PetscInt, RunPlan>> plans_; // for_points' runs, per margin and flags
  std::vector<double> sgn_;
  PetscInt strip_ = 1;         // the owned edge strips fill_ghosts copies into a ghosted array (the gather's),
  PetscInt forward_strip_ = 1; // ... and those G's sweeps read (their Edge points lie within R + 1 of the edge)
  OwnedDM pos_dm_;             // second-order models: the positions alone,
  LocalState pos_;             // as the leapfrog's trajectory stores them
  GhostExchange pos_ghosts_;
  GhostExchange lambda_ghosts_; // the leapfrog adjoint's lambda_p, ghosted in lam_g_ (m per point)
  OwnedVec lam_g_;
  OwnedVec pos_rec_;           // an explicit RK's stored positions of a stage, placed (stage_adjoint)
  OwnedVec pos_copy_;          // the positions copied out of a whole state
  mutable int positions_probe_ = -1; // positions_suffice: unknown, no, yes
  OwnedVec Ag_, dAl_, Zg_, Hg_, XHl_, field_, Yt_; // non-local maps: their fields and scratch
  // Auxiliary lines (KL): the direction's lines, the state's column sums, the gather's column sums
  // of (dG/da)^T x, L^T of them, one line.
  static constexpr PetscInt line_pad = 2 * R;
  std::vector<PetscReal> dline_, sums_, zline_, wline_, aline_;
  std::vector<OwnedVec> map_fields_; // the maps at once (HasMapsAtOnce): max(K, H) fields, one value per point
  std::vector<Vec> map_vecs_;
  PetscReal jp_t_ = 0;
  ParameterBounds bounds_;
  const PointSource *source_ = nullptr;
  bool forcing_sorted_ = false; // forcing_order_ holds source_'s points on this grid
  pointwise::Frame frame_;
  std::vector<int> pattern_;
  std::vector<PetscScalar> coo_v_;              // assemble_rows' values, in the matrix's coordinate list order
  std::vector<char> coo_used_, coo_used_next_;  // which of them the list holds (else index -1)
  PetscInt64 coo_mat_ = -1;                     // the matrix (PetscObjectGetId) the list was set on
  std::vector<std::vector<PetscReal>> scalar_acc_; // scalars' and mapped fields' gradients during an adjoint
  std::vector<PetscReal> scratch_scalar_[NP > 0 ? NP : 1], dummy_target_[NP > 0 ? NP : 1];
  bool in_adjoint_ = false;
  // Parameter vectors: their slots, the entries (every rank), a direction or scratch gradient, and the
  // per-rank gradient accumulated during an adjoint solve (summed over ranks by end_adjoint).
  std::vector<Declarations::VectorSlot> vector_slots_;
  std::vector<PetscReal> theta_, dtheta_, theta_acc_;
};

} // namespace flexipde
