// Acoustic wave equation with a spatially varying speed, written as a first-order system.
//
//   u_t = v,   v_t = c(x)^2 u_xx   on [x0, x1],   u = v = 0 at both walls (Dirichlet),
//
// Boundary (-wave_boundary, non-periodic grids): "walls" (default) holds the two end points at
// u = v = 0 and gives them no equation (D2 with the odd reflection beyond them); "zero_outside"
// updates all n points and takes the values outside the grid as 0 (D2's stencil cut at the ends:
// SecondDerivative::Closure::ZeroOutside), as a loop over all points with zero neighbours does. Both
// D2 are symmetric, so every transpose below is the same sweep; "walls" below means the walls of the
// first treatment (the second has none).
//
// U = (u, v) interleaved per grid point; u_xx by the centred finite differences of
// SecondDerivative (-fd_order 2|4). The parameter c is one scalar (-wave_c_field 0) or a field with
// one value per grid point (-wave_c_field 1), distributed like the grid.
//
//   G(U; c)    = [v ; c^2 D2 u]           dG/dU = [0 I ; diag(c^2) D2 0]  (assembled, constant in U)
//   dG/dc_i    = 2 c_i (D2 u)_i e_{v,i}   (field)   dG/dc = 2 c [0 ; D2 u]  (scalar)
//
// G and D2 u are matrix-free stencil sweeps (owned values read in place, only the ghost values of u
// exchanged, halo.hpp); the assembled dG/dU serves implicit integrators and PETSc's RK/theta
// adjoints. dG/dc is a MatShell: its transpose is a pointwise product, so a gradient with respect
// to a million-entry field costs the same as one with respect to a scalar. For the leapfrog the
// model also offers its fused adjoint (Model::second_order_adjoint): one sweep gives both
// lambda_u += w D2 (c^2 lambda_v) (D2 is symmetric on the interior points, walls excluded) and
// mu += w 2 c (D2 u) lambda_v.
//
// Initial condition (-wave_ic travelling|rest|zero|two_level): u0 = P(x) = exp(-((x - x_c)/w)^2)
// (-wave_ic_center, -wave_ic_width); "travelling" sets v0 = -c u0', a pulse moving right (the
// continuous form of the start u1 = u0(x - c dt)), so U0 depends on c and dU0/dc enters the gradient;
// "rest" sets v0 = 0; "zero" starts at rest with u0 = 0, for waves made by point sources only.
// "two_level" is the two-level start of the recurrence u^{k+1} = 2 u^k - u^{k-1} + dt^2 c^2 D2 u^k from
// u^0 = P(x) and u^1 = P(x - c dt) (pointwise in c for a field): with the integrator's step dt
// (Model::set_time_step) it sets
//   v0 = (u^1 - u^0)/dt - (dt/2) c^2 D2 u^0,
// the velocity whose first Stormer-Verlet step (-ts_type leapfrog) lands on u^1, so that the leapfrog
// reproduces that recurrence from its second level on. dv0_i/dc_i = -P'(x_i - c_i dt) - dt c_i (D2 u^0)_i
// (pointwise) enters the gradient.
//
// Point sources (survey.hpp, -objective_type receivers): v_t = c^2 u_xx + w(t) delta_h(x - x_s),
// a forcing independent of U and c, so dG/dU and dG/dc are unchanged and the second-order form
// (G_u = v, G_v independent of v) is kept.
//
//   mpiexec -n 2 ./flexipde -task gradient -wave_c_field 1 -wave_c 0.9
//   mpiexec -n 2 ./flexipde -task taylor -wave_c_field 1 -wave_c 0.9 -true_wave_c 1.0 -wave_ic zero
//           -objective_type receivers -survey_sources_x 0.3,0.7 -survey_receivers_spread 0.05,0.95,10 -ts_max_time 1
//   (one command line)
#include "flexipde/differentiator.hpp"
#include "flexipde/halo.hpp"
#include "flexipde/leapfrog.hpp"
#include "flexipde/sweep_support.hpp"
#include "flexipde/model.hpp"
#include "flexipde/survey.hpp"
#include <petsc/private/petscimpl.h> // PetscObjectStateGet
#include <algorithm>
#include <cmath>
#include <vector>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace flexipde {
namespace {

// The gradient field (dG/dc)^T x = 2 c (D2 u) x_v computed by the transpose of dG/dU from the same x in
// its sweep, for the dG/dc transpose that an explicit RK adjoint stage applies next to that unchanged
// Vec. Valid only for that Vec (id) in that state, at the same recorded stage (serial).
struct FusedGradient : ProductTag {
  std::vector<PetscReal> g;
};

// J^T x = [D2 (c^2 x_v) ; x_u] and g = 2 c (D2 u) x_v on the plain interior points [lo, hi), in one
// sweep over x and the stage u (interleaved (u, v) arrays); ADD: g is added to (a field's gradient).
// REC: u is the stage's record D2 u itself (rhs_record), else a whole (u, v) state.
template <int HW, bool ADD = false, bool REC = false>
void fused_transpose_interior(PetscInt lo, PetscInt hi, const PetscReal *__restrict wt, const PetscScalar *__restrict x,
                              const PetscScalar *__restrict u, const PetscReal *__restrict c2,
                              const PetscReal *__restrict dg, PetscScalar *__restrict y, PetscReal *__restrict g) {
  for (PetscInt i = lo; i < hi; ++i) {
    PetscReal du = 0, dz = 0;
#pragma GCC unroll 8
    for (int k = -HW; k <= HW; ++k) {
      if (!REC) du += wt[k + HW] * PetscRealPart(u[2 * (i + k)]);
      dz += wt[k + HW] * c2[i + k] * PetscRealPart(x[2 * (i + k) + 1]);
    }
    if (REC) du = PetscRealPart(u[i]);
    y[2 * i] = dz;
    y[2 * i + 1] = x[2 * i];
    if (ADD) g[i] += dg[i] * du * PetscRealPart(x[2 * i + 1]);
    else g[i] = dg[i] * du * PetscRealPart(x[2 * i + 1]);
  }
}

// The fused leapfrog kick on the plain interior points [lo, hi) (all neighbours owned, no wall):
//   lambda_u[i] += w sum_k W_k c2[i+k] lambda_v[i+k]     and   out[i] (+)= s dg[i] (sum_k W_k u[i+k]) lambda_v[i]
// with out = the gradient field (ADD: s = w, added) or a scratch array (s = 1, overwritten) whose sum
// is a scalar's gradient. Interleaved (u, v) arrays; restrict pointers and fixed widths so that the
// compiler vectorises it.
// u is read with stride SU: 2 in a whole (u, v) state, 1 in the stored positions alone.
template <int HW, bool ADD, int SU>
void fused_kick_interior(PetscInt lo, PetscInt hi, const PetscReal *__restrict wt, const PetscScalar *__restrict u,
                         PetscScalar *__restrict L, const PetscReal *__restrict c2, const PetscReal *__restrict dg,
                         PetscReal *__restrict out, PetscReal w) {
  for (PetscInt i = lo; i < hi; ++i) {
    PetscReal du = 0, dz = 0;
#pragma GCC unroll 8
    for (int k = -HW; k <= HW; ++k) {
      du += wt[k + HW] * PetscRealPart(u[SU * (i + k)]);
      dz += wt[k + HW] * c2[i + k] * PetscRealPart(L[2 * (i + k) + 1]);
    }
    const PetscReal gi = dg[i] * du * PetscRealPart(L[2 * i + 1]);
    L[2 * i] += w * dz;
    if (ADD) out[i] += w * gi;
    else out[i] = gi;
  }
}

#if defined(__SSE2__) && !defined(PETSC_USE_COMPLEX) && defined(PETSC_USE_REAL_DOUBLE)
// The leapfrog's adjoint drift lambda_v += s lambda_q and then fused_kick_interior<1, ADD, 1>, in one sweep
// over [lo, k), two points per step: each point's (q, v) pair is loaded once, drifted in registers with
// its q from before the kick, and stored with the kicked q; a point's neighbours come from the vectors
// of the steps before and after (shuffles), not from overlapping loads. The same operations in the same
// order as the drift pass followed by the scalar loop: bitwise the same result. On entry point lo - 1 is
// drifted already; returns k (k + 3 <= hi: the sweep reads two points ahead): points [k, hi) are neither
// drifted nor kicked, point k - 1 is both. pf (null: none): the next level's positions, one cache line
// prefetched every eight points, spread over the sweep.
template <bool ADD>
PetscInt drift_kick_pairs(PetscInt lo, PetscInt hi, const PetscReal *wt, const PetscScalar *__restrict u,
                          PetscScalar *__restrict L, const PetscReal *__restrict c2, const PetscReal *__restrict dg,
                          PetscReal *__restrict out, PetscReal w, PetscReal s, const PetscScalar *pf) {
  PetscInt i = lo;
  if (hi - lo < 5) return lo;
  const __m128d w0 = _mm_set1_pd(wt[0]), w1 = _mm_set1_pd(wt[1]), w2 = _mm_set1_pd(wt[2]), ws = _mm_set1_pd(w);
  const __m128d ss = _mm_set1_pd(s), zero = _mm_setzero_pd();
  // the previous pair's vectors: their high lanes hold point i - 1
  __m128d up = _mm_loadh_pd(zero, u + i - 1), cp = _mm_loadh_pd(zero, c2 + i - 1), vp = _mm_loadh_pd(zero, L + 2 * i - 1);
  __m128d uc = _mm_loadu_pd(u + i), cc = _mm_loadu_pd(c2 + i);
  __m128d p0 = _mm_loadu_pd(L + 2 * i), p1 = _mm_loadu_pd(L + 2 * i + 2);
  __m128d q = _mm_unpacklo_pd(p0, p1), v = _mm_add_pd(_mm_unpackhi_pd(p0, p1), _mm_mul_pd(ss, q));
  for (; i + 3 <= hi; i += 2) {
    if (pf && (i & 7) < 2) _mm_prefetch(reinterpret_cast<const char *>(pf + (i & ~(PetscInt)7)), _MM_HINT_T0);
    const __m128d un = _mm_loadu_pd(u + i + 2), cn = _mm_loadu_pd(c2 + i + 2);
    const __m128d p2 = _mm_loadu_pd(L + 2 * i + 4), p3 = _mm_loadu_pd(L + 2 * i + 6);
    const __m128d qn = _mm_unpacklo_pd(p2, p3), vn = _mm_add_pd(_mm_unpackhi_pd(p2, p3), _mm_mul_pd(ss, qn));
    const __m128d ul = _mm_shuffle_pd(up, uc, 1), ur = _mm_shuffle_pd(uc, un, 1);
    const __m128d cl = _mm_shuffle_pd(cp, cc, 1), cr = _mm_shuffle_pd(cc, cn, 1);
    const __m128d vl = _mm_shuffle_pd(vp, v, 1), vr = _mm_shuffle_pd(v, vn, 1);
    __m128d du = _mm_add_pd(zero, _mm_mul_pd(w0, ul));
    du = _mm_add_pd(du, _mm_mul_pd(w1, uc));
    du = _mm_add_pd(du, _mm_mul_pd(w2, ur));
    __m128d dz = _mm_add_pd(zero, _mm_mul_pd(_mm_mul_pd(w0, cl), vl));
    dz = _mm_add_pd(dz, _mm_mul_pd(_mm_mul_pd(w1, cc), v));
    dz = _mm_add_pd(dz, _mm_mul_pd(_mm_mul_pd(w2, cr), vr));
    const __m128d gi = _mm_mul_pd(_mm_mul_pd(_mm_loadu_pd(dg + i), du), v);
    const __m128d qk = _mm_add_pd(q, _mm_mul_pd(ws, dz));
    if (ADD) _mm_storeu_pd(out + i, _mm_add_pd(_mm_loadu_pd(out + i), _mm_mul_pd(ws, gi)));
    else _mm_storeu_pd(out + i, gi);
    _mm_storeu_pd(L + 2 * i, _mm_unpacklo_pd(qk, v));
    _mm_storeu_pd(L + 2 * i + 2, _mm_unpackhi_pd(qk, v));
    up = uc, uc = un, cp = cc, cc = cn, vp = v, v = vn, q = qn;
  }
  return i;
}
#define FLEXIPDE_WAVE_DRIFT_KICK 1
#endif

class WaveModel final : public LinearModel {
public:
  const char *name() const override { return "wave"; }
  PetscInt dof() const override { return 2; }
  const char *component_name(PetscInt c) const override { return c == 0 ? "u" : "v"; }
  PetscInt second_order_pairs() const override { return 1; } // u_t = v, v_t = c^2 u_xx
  PetscInt stencil_width(MPI_Comm comm) const override {
    SecondDerivative d;
    if (SecondDerivative::from_options(comm, nullptr, 2, d)) return 1;
    return d.half_width();
  }

  PetscErrorCode setup(const Grid &grid, DM state_dm, Parameters &params) override {
    const char *ics[] = {"travelling", "rest", "zero", "two_level"};
    const char *boundaries[] = {"walls", "zero_outside"};
    PetscFunctionBeginUser;
    grid_ = &grid;
    dm_ = state_dm;
    params_ = &params;
    PetscCall(SecondDerivative::from_options(grid.comm(), nullptr, 2, d2_));
    PetscOptionsBegin(grid.comm(), nullptr, "Acoustic wave model u_tt = c(x)^2 u_xx", "Wave");
    PetscCall(PetscOptionsBool("-wave_c_field", "Speed c is a field (one value per grid point), else one scalar",
                               "Wave", c_field_, &c_field_, nullptr));
    PetscCall(PetscOptionsEList("-wave_ic", "Initial condition (two_level: u^0 = pulse, u^1 = pulse(x - c dt), the "
                                "leapfrog's first step lands on u^1)", "Wave", ics, 4, ics[ic_], &ic_, nullptr));
    PetscCall(PetscOptionsEList("-wave_boundary", "Ends of a non-periodic grid: walls (the end points held at 0) or "
                                "zero_outside (all points updated, values outside the grid 0)", "Wave", boundaries, 2,
                                boundaries[boundary_], &boundary_, nullptr));
    PetscCall(PetscOptionsReal("-wave_ic_center", "Centre of the initial Gaussian pulse", "Wave", center_, &center_,
                               nullptr));
    PetscCall(PetscOptionsReal("-wave_ic_width", "Width w of the pulse exp(-((x-x_c)/w)^2)", "Wave", width_, &width_,
                               nullptr));
    PetscCall(PetscOptionsReal("-wave_c_min", "Smallest admissible speed: optimisers never go below it", "Wave", c_min_,
                               &c_min_, nullptr));
    PetscOptionsEnd();
    PetscCheck(c_min_ > 0, grid.comm(), PETSC_ERR_ARG_OUTOFRANGE, "-wave_c_min must be positive, got %g", (double)c_min_);
    PetscCheck(width_ > 0, grid.comm(), PETSC_ERR_ARG_OUTOFRANGE, "-wave_ic_width must be positive, got %g",
               (double)width_);
    PetscCheck(!(boundary_ == ZeroOutside && grid.periodic()), grid.comm(), PETSC_ERR_ARG_WRONG,
               "-wave_boundary zero_outside needs a non-periodic grid (-grid_periodic 0)");
    if (boundary_ == ZeroOutside) d2_.set_closure(SecondDerivative::Closure::ZeroOutside);
    c_index_ = params.add("wave_c", c_field_ ? ParamKind::Field : ParamKind::Scalar, c_min_);
    PetscCall(DMCreateGlobalVector(grid.dm(), c_.out()));
    PetscCall(create_operator(dm_));
    dgdc_.assign(grid.xm(), 0.0);
    c2_.assign(grid.xm(), 0.0);
    gbuf_.assign(grid.xm(), 0.0);
    gacc_.assign(grid.xm(), 0.0);
    fused_.g.assign(grid.xm(), 0.0);
    hw_ = d2_.half_width();
    PetscCall(halo_u_.setup(grid, dm_, 0, hw_));
    PetscCall(halo_v_.setup(grid, dm_, 1, hw_));
    PetscCall(pair_.setup_packed(grid, hw_, 2));
    PetscCall(halo_c_.setup(grid, grid.dm(), 0, hw_));
    // Owned points whose D2 row is the plain centred stencil with every point it reads owned and off
    // the walls (inside the grid): swept without any test; the few others (walls, next to them or to
    // the ends, next to another rank) go through SecondDerivative::row and the halo.
    const PetscInt xs = grid.xs(), xm = grid.xm(), n = grid.n();
    lo_ = hw_;
    hi_ = xm - hw_;
    if (!grid.periodic()) {
      const PetscInt end = boundary_ == ZeroOutside ? 0 : 1; // end points the plain stencil must not read (walls)
      lo_ = std::max(lo_, hw_ + end - xs);
      hi_ = std::min(hi_, n - end - hw_ - xs);
    }
    lo_ = std::min(lo_, xm);
    hi_ = std::max(hi_, lo_);
    const PetscReal ih2 = 1.0 / (grid.h() * grid.h());
    if (hw_ == 1) {
      wt_[0] = wt_[2] = ih2;
      wt_[1] = -2 * ih2;
    } else {
      wt_[0] = wt_[4] = -ih2 / 12;
      wt_[1] = wt_[3] = 16 * ih2 / 12;
      wt_[2] = -30 * ih2 / 12;
    }
    if (ic_ == TwoLevel) PetscCall(pulse_d2());
    PetscFunctionReturn(0);
  }

  bool has_second_order_adjoint() const override { return true; }
  bool second_order_adjoint_takes_positions() const override { return true; }
  // lambda_v += drift lambda_u, then lambda_u += w D2 (c^2 lambda_v) and mu += w 2 c (D2 u) lambda_v, in
  // one sweep (wall rows of lambda_u untouched: the walls' columns are not in D2). U is a whole state or
  // u alone. The drift is folded into the interior sweep for the second-order stencil on stored
  // positions (drift_kick_pairs), else applied in a pass of its own first.
  PetscErrorCode second_order_adjoint(PetscReal, Vec U, const PetscScalar *record, Vec lambda, PetscReal w, Vec mu,
                                      PetscReal drift, const PetscScalar *prefetch) override {
    const ParamInfo &pi = params_->info(c_index_);
    PetscReal local[4] = {0, 0, 0, 0}; // four partial sums: no single dependency chain through the sweep
    PetscInt su = 2;
    PetscFunctionBeginUser;
    PetscCheck(!record, grid_->comm(), PETSC_ERR_PLIB, "wave: the kick takes no record");
    PetscCall(u_layout(U, &su));
    {
      ConstArray u(U);
      Array l(lambda);
      PetscCall(u.error());
      PetscCall(l.error());
      const PetscInt xm = grid_->xm();
      bool fold = false; // the drift folded into the interior sweep
#if defined(FLEXIPDE_WAVE_DRIFT_KICK)
      fold = drift != 0 && hw_ == 1 && su == 1;
#endif
      // the drift where the sweep does not apply it: everywhere, or the points outside the plain interior
      // (among them those whose lambda_v the neighbours receive as ghosts, so they get it drifted)
      if (drift != 0) {
        leapfrog_drift_transpose(l.data(), 0, fold ? lo_ : xm, 1, drift);
        if (fold) leapfrog_drift_transpose(l.data(), hi_, xm, 1, drift);
      }
      // the next level's positions: spread over the folded sweep (its interior lines; the few lines
      // around them here), else all at once
      const PetscScalar *spread = fold ? prefetch : nullptr;
      if (spread) {
        const PetscInt tail = std::max(hi_ - 8, lo_);
        leapfrog_prefetch(prefetch, std::min(lo_ + 8, xm));
        leapfrog_prefetch(prefetch + tail, xm - tail);
      } else leapfrog_prefetch(prefetch, xm);
      // (the sweep changes lambda_v only where it folds the drift in: not at the points sent as ghosts)
      PetscCall(begin_pair(u.data(), su, l.data()));
      PetscScalar *g = nullptr;
      if (mu && c_field_) PetscCall(VecGetArray(mu, &g));
      // where the pointwise terms accumulate: a field's gradient in place; a scalar's pointwise sums
      // during an adjoint solve (summed once, end_adjoint); else none (a scalar's local sum, below)
      PetscReal *acc = g ? g + pi.local_offset : mu && scalar_pointwise_ ? gacc_.data() : nullptr;
      const PetscReal *c2 = c2_.data(), *dg = two_c_.data();
      PetscScalar *L = l.data();
      const PetscScalar *ua = u.data();
      auto body = [&](PetscInt il, PetscReal du, PetscReal dz) {
        L[2 * il] += w * dz;
        const PetscReal gi = dg[il] * du * PetscRealPart(L[2 * il + 1]);
        if (acc) acc[il] += w * gi;
        else local[il & 3] += gi;
      };
      // the interior: added to acc, or through the scratch array gbuf_ into the local sums
      PetscReal *out = acc ? acc : gbuf_.data();
      if (fold) drift_kick_interior(ua, L, c2, dg, out, w, acc != nullptr, drift, spread);
      else if (su == 1) kick_interior<1>(ua, L, c2, dg, out, w, acc != nullptr);
      else kick_interior<2>(ua, L, c2, dg, out, w, acc != nullptr);
      if (!acc)
        sum4(out, lo_, hi_, local);
      PetscCall(pair_.end());
      for_edge_points([&](PetscInt il, const std::array<StencilEntry, 5> &st, PetscInt m) {
        PetscReal du, dz;
        edge_sums(st, m, ua, su, L, &du, &dz);
        body(il, du, dz);
      });
      if (g) PetscCall(VecRestoreArray(mu, &g));
    }
    if (mu && !c_field_ && !scalar_pointwise_)
      PetscCall(params_->add_local_sum(mu, c_index_, w * (local[0] + local[1] + local[2] + local[3])));
    PetscFunctionReturn(0);
  }

  // A scalar c during one adjoint solve: the kicks and RK stages add their pointwise terms to gacc_, as a
  // field's gradient would be added to, and end_adjoint sums it once, instead of every kick or stage
  // writing a scratch array and summing it (the sum is linear: the same gradient up to round-off).
  void begin_adjoint() override {
    scalar_pointwise_ = !c_field_;
    if (scalar_pointwise_) std::fill(gacc_.begin(), gacc_.end(), 0.0);
  }
  PetscErrorCode end_adjoint(Vec mu) override {
    PetscFunctionBeginUser;
    const bool pending = scalar_pointwise_;
    scalar_pointwise_ = false;
    if (!pending || !mu) PetscFunctionReturn(0);
    PetscReal s[4] = {0, 0, 0, 0};
    sum4(gacc_.data(), 0, grid_->xm(), s);
    PetscCall(params_->add_local_sum(mu, c_index_, s[0] + s[1] + s[2] + s[3]));
    PetscFunctionReturn(0);
  }

  bool has_stage_adjoint() const override { return true; }
  // dG/dU is constant and dG/dc reads D2 u alone: the RHS evaluations at the stages record D2 u (0 at
  // the walls) and full storage keeps those records instead of the stages (half the memory), from which
  // the adjoint stage forms mu without a second stencil.
  PetscInt stage_record_size() const override { return grid_->xm(); }
  bool stage_record_replaces_state() const override { return true; }
  PetscErrorCode rhs_record(PetscReal t, Vec U, Vec G, PetscScalar *record) override {
    return rhs_sweep<true>(t, U, G, record);
  }
  // An explicit RK adjoint stage at state U (whole), or from its record D2 u: y = J^T x = [D2 (c^2 x_v) ;
  // x_u] (walls 0) and mu += 2 c (D2 u) x_v, in one sweep; a scalar c's local sum goes to the Parameters
  // (deferred there by the Simulation to one reduction per adjoint).
  PetscErrorCode stage_adjoint(PetscReal, Vec U, const PetscScalar *record, Vec x, Vec y, Vec mu) override {
    const ParamInfo &pi = params_->info(c_index_);
    PetscReal local[4] = {0, 0, 0, 0};
    PetscFunctionBeginUser;
    if (mu && c_field_) { // a field's gradient added in place
      PetscScalar *gm;
      PetscCall(VecGetArray(mu, &gm));
      PetscCall(transpose_sweep(U, record, x, y, gm + pi.local_offset, true, nullptr));
      PetscCall(VecRestoreArray(mu, &gm));
    } else if (mu && scalar_pointwise_) PetscCall(transpose_sweep(U, record, x, y, gacc_.data(), true, nullptr)); // begin_adjoint
    else PetscCall(transpose_sweep(U, record, x, y, gbuf_.data(), false, mu ? local : nullptr));
    if (mu && !c_field_ && !scalar_pointwise_)
      PetscCall(params_->add_local_sum(mu, c_index_, local[0] + local[1] + local[2] + local[3]));
    PetscFunctionReturn(0);
  }

  // y = J^T x = [D2 (c^2 x_v) ; x_u] (walls 0) and the pointwise 2 c (D2 u) x_v at the whole state U, or
  // from the record D2 u (U unread), in one sweep: added to g (add), or written to g (walls 0); local,
  // when given, gets the pointwise terms' sum (four partial sums).
  PetscErrorCode transpose_sweep(Vec U, const PetscScalar *record, Vec x, Vec y, PetscReal *g, bool add, PetscReal *local) {
    const bool rec = record != nullptr;
    PetscFunctionBeginUser;
    {
      ConstArray xa(x), ua(rec ? nullptr : U);
      Array ya(y);
      PetscCall(xa.error());
      PetscCall(ua.error());
      PetscCall(ya.error());
      const PetscScalar *X = xa.data(), *u = rec ? record : ua.data();
      PetscCall(begin_pair(u, rec ? 1 : 2, X)); // (a record's ghosts travel unread)
      PetscScalar *Y = ya.data();
      const PetscInt xm = grid_->xm();
      for (PetscInt il : {(PetscInt)0, xm - 1}) // the walls (no gradient there: 2c = 0)
        if (xm > 0 && wall(grid_->xs() + il)) {
          Y[2 * il] = Y[2 * il + 1] = 0;
          if (!add) g[il] = 0;
        }
      const PetscReal *c2 = c2_.data(), *dg = two_c_.data();
      if (add && rec) stage_interior<true, true>(X, u, c2, dg, Y, g);
      else if (add) stage_interior<true, false>(X, u, c2, dg, Y, g);
      else if (rec) stage_interior<false, true>(X, u, c2, dg, Y, g);
      else stage_interior<false, false>(X, u, c2, dg, Y, g);
      if (local) sum4(g, lo_, hi_, local);
      PetscCall(pair_.end());
      for_edge_points([&](PetscInt il, const std::array<StencilEntry, 5> &st, PetscInt m) {
        PetscReal du, dz;
        edge_sums(st, m, u, rec ? 1 : 2, X, &du, &dz);
        if (rec) du = PetscRealPart(u[il]);
        Y[2 * il] = dz;
        Y[2 * il + 1] = X[2 * il];
        const PetscReal gi = two_c_[il] * du * PetscRealPart(X[2 * il + 1]);
        if (add) g[il] += gi;
        else g[il] = gi;
        if (local) local[il & 3] += gi;
      });
    }
    PetscFunctionReturn(0);
  }

  PetscErrorCode create_jacobian_matrix_free(Mat *J) override {
    const PetscInt nstate = grid_->xm() * dof();
    PetscFunctionBeginUser;
    PetscCall(MatCreateShell(grid_->comm(), nstate, nstate, PETSC_DETERMINE, PETSC_DETERMINE, this, J));
    PetscCall(MatShellSetOperation(*J, MATOP_MULT, (void (*)(void))jmf_apply<false>));
    PetscCall(MatShellSetOperation(*J, MATOP_MULT_TRANSPOSE, (void (*)(void))jmf_apply<true>));
    PetscFunctionReturn(0);
  }

  PetscErrorCode create_jacobian_p(Mat *Jp) override {
    const PetscInt nstate = grid_->xm() * dof();
    PetscFunctionBeginUser;
    PetscCall(MatCreateShell(grid_->comm(), nstate, params_->local_size(), PETSC_DETERMINE, PETSC_DETERMINE, this, Jp));
    PetscCall(MatShellSetOperation(*Jp, MATOP_MULT, (void (*)(void))jp_mult));
    PetscCall(MatShellSetOperation(*Jp, MATOP_MULT_TRANSPOSE, (void (*)(void))jp_mult_transpose));
    PetscFunctionReturn(0);
  }

  PetscErrorCode set_parameters(Vec p) override {
    PetscFunctionBeginUser;
    PetscCall(params_->as_field(p, c_index_, c_));
    PetscReal cmin;
    PetscCall(VecMin(c_, nullptr, &cmin));
    PetscCheck(cmin > 0, grid_->comm(), PETSC_ERR_ARG_OUTOFRANGE, "Wave speed must be positive, found c = %g", (double)cmin);
    PetscCall(VecMax(c_, nullptr, &cmax_));
    {
      ConstArray c(c_);
      PetscCall(c.error());
      two_c_.assign(grid_->xm(), 0.0);
      for (PetscInt il = 0; il < grid_->xm(); ++il) {
        const PetscReal ci = PetscRealPart(c[il]);
        c2_[il] = ci * ci;
        two_c_[il] = wall(grid_->xs() + il) ? 0.0 : 2 * ci;
      }
    }
    PetscCall(halo_c_.update(c_));
    stage_.invalidate(); // dG/dc and any fused product are taken at the new speed
    mark_operator_stale(); // assembled when an integrator asks for dG/dU
    PetscFunctionReturn(0);
  }

  // Records the state U (RecordedStage: no copy, no sweep yet). dG_v/dc_i = 2 c_i (D2 u)_i (0 at the
  // walls) is formed when the shell is applied, or, for its transpose, by the transpose of dG/dU in
  // its own sweep over the same vector (PETSc's RK adjoint stage applies both).
  PetscErrorCode rhs_jacobian_p(PetscReal, Vec U, Mat Jp) override {
    PetscFunctionBeginUser;
    PetscCall(stage_.record(U));
    PetscCall(MatAssemblyBegin(Jp, MAT_FINAL_ASSEMBLY)); // resets any scaling TS applied last time
    PetscCall(MatAssemblyEnd(Jp, MAT_FINAL_ASSEMBLY));
    PetscFunctionReturn(0);
  }

  bool accepts_point_source() const override { return true; }
  PetscErrorCode set_point_source(const PointSource *src) override {
    source_ = src;
    return 0;
  }
  // G = A U as a stencil sweep (u_t = v, v_t = c^2 D2 u, both 0 at the walls), plus the point
  // source's forcing on v.
  PetscErrorCode rhs(PetscReal t, Vec U, Vec G) override { return rhs_sweep<false>(t, U, G, nullptr); }
  // ... and with REC the record D2 u (0 at the walls) of stage_record_size.
  template <bool REC>
  PetscErrorCode rhs_sweep(PetscReal t, Vec U, Vec G, PetscScalar *record) {
    PetscFunctionBeginUser;
    {
      Array g(G);
      PetscCall(g.error());
      PetscScalar *ga = g.data();
      PetscCall(sweep_d2u(U, [&](PetscInt il, PetscReal du, const PetscScalar *u) {
        ga[2 * il] = u[2 * il + 1];
        ga[2 * il + 1] = c2_[il] * du;
        if (REC) record[il] = du;
      }));
      for (PetscInt il : {(PetscInt)0, grid_->xm() - 1}) // the walls: G = 0
        if (grid_->xm() > 0 && wall(grid_->xs() + il)) {
          ga[2 * il] = ga[2 * il + 1] = 0;
          if (REC) record[il] = 0;
        }
    }
    if (source_ && source_->stencil.n) {
      Array g(G);
      PetscCall(g.error());
      for (PetscInt k = 0; k < source_->stencil.n; ++k) {
        const PetscInt il = source_->stencil.local[k];
        if (wall(grid_->xs() + il)) continue; // the walls hold u = v = 0
        g[2 * il + 1] += source_->density(k, t);
      }
    }
    PetscFunctionReturn(0);
  }

  PetscErrorCode spectrum(Spectrum *s) override {
    s->imag_radius = cmax_ * std::sqrt(d2_.spectral_radius(grid_->h()));
    s->real_radius = 0;
    return 0;
  }

  void set_time_step(PetscReal dt) override { ic_dt_ = dt; }

  PetscErrorCode initial_condition(Vec p, Vec U0) override {
    PetscFunctionBeginUser;
    PetscCheck(ic_ != TwoLevel || ic_dt_ > 0, grid_->comm(), PETSC_ERR_ORDER,
               "-wave_ic two_level needs the integrator's step: make the initial condition through "
               "Simulation::initial_condition (Model::set_time_step)");
    Array U(U0);
    ConstArray c(c_);
    PetscCall(U.error());
    PetscCall(c.error());
    const PetscReal dt = ic_dt_;
    for (PetscInt il = 0; il < grid_->xm(); ++il) {
      const PetscInt i = grid_->xs() + il;
      const PetscReal ci = PetscRealPart(c[il]);
      PetscReal u0, du0, u1, du1;
      pulse(grid_->x(i), &u0, &du0);
      if (wall(i)) U[2 * il] = U[2 * il + 1] = 0.0;
      else if (ic_ == TwoLevel) {
        pulse(grid_->x(i) - ci * dt, &u1, &du1);
        U[2 * il] = u0;
        U[2 * il + 1] = (u1 - u0) / dt - 0.5 * dt * c2_[il] * d2u0_[il];
      } else {
        U[2 * il] = ic_ == Zero ? 0.0 : u0;
        U[2 * il + 1] = ic_ == Travelling ? -ci * du0 : 0.0;
      }
    }
    PetscFunctionReturn(0);
  }

  // grad += (dU0/dc)^T lambda0: dv0_i/dc_i is -u0'(x_i) (travelling) or -P'(x_i - c_i dt) - dt c_i (D2 u^0)_i
  // (two_level), pointwise; the other starts do not depend on c.
  PetscErrorCode initial_condition_transpose(Vec, Vec lambda0, Vec grad) override {
    PetscFunctionBeginUser;
    if (ic_ != Travelling && ic_ != TwoLevel) PetscFunctionReturn(0);
    std::vector<PetscReal> g(grid_->xm(), 0.0);
    {
      ConstArray L(lambda0), c(c_);
      PetscCall(L.error());
      PetscCall(c.error());
      for (PetscInt il = 0; il < grid_->xm(); ++il) {
        const PetscInt i = grid_->xs() + il;
        if (wall(i)) continue;
        const PetscReal ci = PetscRealPart(c[il]);
        PetscReal u, du;
        if (ic_ == TwoLevel) pulse(grid_->x(i) - ci * ic_dt_, &u, &du);
        else pulse(grid_->x(i), &u, &du);
        const PetscReal dv = ic_ == TwoLevel ? -du - ic_dt_ * ci * d2u0_[il] : -du;
        g[il] = dv * PetscRealPart(L[2 * il + 1]);
      }
    }
    PetscCall(params_->add_pointwise(grad, c_index_, g));
    PetscFunctionReturn(0);
  }

private:
  // The RK adjoint stage's sweep on the plain interior (stage_adjoint), by half-width.
  template <bool ADD, bool REC>
  void stage_interior(const PetscScalar *X, const PetscScalar *u, const PetscReal *c2, const PetscReal *dg,
                      PetscScalar *Y, PetscReal *g) const {
    if (hw_ == 1) fused_transpose_interior<1, ADD, REC>(lo_, hi_, wt_, X, u, c2, dg, Y, g);
    else fused_transpose_interior<2, ADD, REC>(lo_, hi_, wt_, X, u, c2, dg, Y, g);
  }
  // The drift lambda_v += s lambda_u and the kick on the plain interior, second-order stencil, u the
  // stored positions (points outside it drifted already): drift_kick_pairs, then the few points it left.
  void drift_kick_interior(const PetscScalar *ua, PetscScalar *L, const PetscReal *c2, const PetscReal *dg, PetscReal *out,
                           PetscReal w, bool add, PetscReal s, const PetscScalar *pf) const {
#if defined(FLEXIPDE_WAVE_DRIFT_KICK)
    const PetscInt k = add ? drift_kick_pairs<true>(lo_, hi_, wt_, ua, L, c2, dg, out, w, s, pf)
                           : drift_kick_pairs<false>(lo_, hi_, wt_, ua, L, c2, dg, out, w, s, pf);
    leapfrog_drift_transpose(L, k, hi_, 1, s);
    if (add) fused_kick_interior<1, true, 1>(k, hi_, wt_, ua, L, c2, dg, out, w);
    else fused_kick_interior<1, false, 1>(k, hi_, wt_, ua, L, c2, dg, out, w);
#else
    (void)ua, (void)L, (void)c2, (void)dg, (void)out, (void)w, (void)add, (void)s, (void)pf;
#endif
  }
  template <int SU>
  void kick_interior(const PetscScalar *ua, PetscScalar *L, const PetscReal *c2, const PetscReal *dg, PetscReal *out,
                     PetscReal w, bool add) const {
    if (hw_ == 1 && add) fused_kick_interior<1, true, SU>(lo_, hi_, wt_, ua, L, c2, dg, out, w);
    else if (hw_ == 1) fused_kick_interior<1, false, SU>(lo_, hi_, wt_, ua, L, c2, dg, out, w);
    else if (add) fused_kick_interior<2, true, SU>(lo_, hi_, wt_, ua, L, c2, dg, out, w);
    else fused_kick_interior<2, false, SU>(lo_, hi_, wt_, ua, L, c2, dg, out, w);
  }
  // The adjoint sweeps' ghosts of u (stride su: a whole state or the positions alone) and of z_v (z an
  // interleaved (u, v) array) in one exchange, one message per neighbour (pair_: fields 0 and 1).
  PetscErrorCode begin_pair(const PetscScalar *u, PetscInt su, const PetscScalar *z) {
    const Halo::Strided f[2] = {{u, su, 0}, {z + 1, 2, 0}};
    PetscFunctionBeginUser;
    PetscCall(pair_.begin(f));
    PetscFunctionReturn(0);
  }
  // At an edge point with stencil st (m entries): du = (D2 u) (u at stride su) and dz = D2 (c^2 z_v),
  // ghosts from pair_ (begin_pair, ended).
  void edge_sums(const std::array<StencilEntry, 5> &st, PetscInt m, const PetscScalar *u, PetscInt su,
                 const PetscScalar *z, PetscReal *du, PetscReal *dz) const {
    *du = 0;
    *dz = 0;
    for (PetscInt q = 0; q < m; ++q) {
      const PetscInt jl = local_offset(st[q].j);
      const bool owned = jl >= 0 && jl < grid_->xm();
      *du += st[q].weight * PetscRealPart(owned ? u[su * jl] : pair_(jl, 0, 0));
      *dz += st[q].weight * c2_at(jl) * PetscRealPart(owned ? z[2 * jl + 1] : pair_(jl, 0, 1));
    }
  }
  // U is a whole (u, v) state or u alone: the stride of u in it.
  PetscErrorCode u_layout(Vec U, PetscInt *su) {
    PetscInt nu;
    PetscFunctionBeginUser;
    PetscCall(VecGetLocalSize(U, &nu));
    *su = nu == grid_->xm() ? 1 : 2;
    PetscFunctionReturn(0);
  }
  // Local offset (i - xs) of global point j as the stencils see it: periodic neighbours of the
  // block's ends unwrapped into the halo.
  PetscInt local_offset(PetscInt j) const {
    PetscInt jl = j - grid_->xs();
    if (grid_->periodic()) {
      if (jl < -hw_) jl += grid_->n();
      else if (jl >= grid_->xm() + hw_) jl -= grid_->n();
    }
    return jl;
  }
  static PetscReal value(const PetscScalar *a, const Halo &h, PetscInt comp, PetscInt jl) {
    return PetscRealPart(jl >= 0 && jl < h.xm() ? a[2 * jl + comp] : h(jl, 0));
  }
  PetscReal c2_at(PetscInt jl) const {
    if (jl >= 0 && jl < grid_->xm()) return c2_[jl];
    const PetscReal c = PetscRealPart(halo_c_(jl, 0));
    return c * c;
  }
  // emit(il, (D2 u)_il, u) for every owned point off the walls.
  template <class Emit>
  PetscErrorCode sweep_d2u(Vec U, Emit &&emit) {
    return sweep_d2<false>(U, emit);
  }
  // Z = false: emit(il, (D2 u)_il, x); Z = true: emit(il, (D2 (c^2 v))_il, x), for every owned point
  // off the walls (u, v the components of X).
  template <bool Z, class Emit>
  PetscErrorCode sweep_d2(Vec X, Emit &&emit) {
    Halo &halo = Z ? halo_v_ : halo_u_;
    PetscFunctionBeginUser;
    PetscCall(halo.begin(X));
    ConstArray x(X);
    PetscCall(x.error());
    const PetscScalar *xa = x.data();
    if (hw_ == 1) d2_interior<1, Z>(xa, emit);
    else d2_interior<2, Z>(xa, emit);
    PetscCall(halo.end(X));
    for_edge_points([&](PetscInt il, const std::array<StencilEntry, 5> &st, PetscInt m) {
      PetscReal d = 0;
      for (PetscInt q = 0; q < m; ++q) {
        const PetscInt jl = local_offset(st[q].j);
        d += st[q].weight * (Z ? c2_at(jl) * value(xa, halo, 1, jl) : value(xa, halo, 0, jl));
      }
      emit(il, d, xa);
    });
    PetscFunctionReturn(0);
  }
  // f(il, row, entries) for the owned points off the walls outside the plain interior [lo_, hi_):
  // their D2 row from SecondDerivative::row (reflected closure, global indices).
  template <class F>
  void for_edge_points(F &&f) const {
    for (PetscInt il = 0; il < grid_->xm(); ++il) {
      if (il == lo_) il = hi_;
      if (il >= grid_->xm()) break;
      const PetscInt i = grid_->xs() + il;
      if (wall(i)) continue;
      std::array<StencilEntry, 5> st;
      f(il, st, d2_.row(*grid_, i, st));
    }
  }
  template <int HW, bool Z, class Emit>
  void d2_interior(const PetscScalar *x, Emit &emit) const {
    const PetscReal *c2 = c2_.data();
    for (PetscInt il = lo_; il < hi_; ++il) {
      PetscReal d = 0;
#pragma GCC unroll 8
      for (int k = -HW; k <= HW; ++k)
        d += wt_[k + HW] * (Z ? c2[il + k] * PetscRealPart(x[2 * (il + k) + 1]) : PetscRealPart(x[2 * (il + k)]));
      emit(il, d, x);
    }
  }
  // The matrix-free dG/dU = [0 I ; diag(c^2) D2 0] (wall rows and columns empty).
  template <bool T>
  static PetscErrorCode jmf_apply(Mat J, Vec x, Vec y) {
    WaveModel *m;
    PetscFunctionBeginUser;
    PetscCall(MatShellGetContext(J, &m));
    PetscCall(m->apply_jacobian(x, y, T));
    PetscFunctionReturn(0);
  }
  // y = J x, or J^T x = [D2 (c^2 x_v) ; x_u] off the walls (D2 symmetric on the interior points).
  // J^T with a recorded stage u also forms (dG/dc)^T x = 2 c (D2 u) x_v.
  PetscErrorCode apply_jacobian(Vec x, Vec y, bool transpose) {
    bool fuse = false;
    PetscFunctionBeginUser;
    if (transpose) PetscCall(stage_.unchanged(&fuse));
    if (fuse) {
      PetscCall(fused_transpose(x, y));
      PetscFunctionReturn(0);
    }
    Array ya(y);
    PetscCall(ya.error());
    PetscScalar *Y = ya.data();
    const PetscInt xm = grid_->xm();
    for (PetscInt il : {(PetscInt)0, xm - 1}) // the walls
      if (xm > 0 && wall(grid_->xs() + il)) Y[2 * il] = Y[2 * il + 1] = 0;
    if (transpose)
      PetscCall(sweep_d2<true>(x, [&](PetscInt il, PetscReal dz, const PetscScalar *X) {
        Y[2 * il] = dz;
        Y[2 * il + 1] = X[2 * il];
      }));
    else
      PetscCall(sweep_d2<false>(x, [&](PetscInt il, PetscReal du, const PetscScalar *X) {
        Y[2 * il] = X[2 * il + 1];
        Y[2 * il + 1] = c2_[il] * du;
      }));
    PetscFunctionReturn(0);
  }

  PetscErrorCode fused_transpose(Vec x, Vec y) {
    Vec U = nullptr;
    PetscFunctionBeginUser;
    PetscCall(stage_.get(&U));
    PetscCall(transpose_sweep(U, nullptr, x, y, fused_.g.data(), false, nullptr));
    PetscCall(fused_.store(x, stage_.serial()));
    PetscFunctionReturn(0);
  }

  // dgdc_ = 2 c D2 u at the recorded stage, unless it already holds it.
  PetscErrorCode recorded_columns() {
    Vec U = nullptr;
    PetscFunctionBeginUser;
    if (columns_serial_ == stage_.serial()) PetscFunctionReturn(0);
    PetscCall(stage_.get(&U));
    PetscCall(sweep_d2u(U, [&](PetscInt il, PetscReal du, const PetscScalar *) { dgdc_[il] = two_c_[il] * du; }));
    columns_serial_ = stage_.serial();
    PetscFunctionReturn(0);
  }

  // d2u0_ = D2 u^0 of the pulse u^0 (0 on the walls), by the sweep that gives the leapfrog its a(u^0).
  PetscErrorCode pulse_d2() {
    OwnedVec U;
    PetscFunctionBeginUser;
    PetscCall(DMCreateGlobalVector(dm_, U.out()));
    {
      Array u(U);
      PetscCall(u.error());
      for (PetscInt il = 0; il < grid_->xm(); ++il) {
        const PetscInt i = grid_->xs() + il;
        PetscReal u0, du0;
        pulse(grid_->x(i), &u0, &du0);
        u[2 * il] = wall(i) ? 0.0 : u0;
        u[2 * il + 1] = 0.0;
      }
    }
    d2u0_.assign(grid_->xm(), 0.0);
    PetscCall(sweep_d2u(U, [&](PetscInt il, PetscReal du, const PetscScalar *) { d2u0_[il] = du; }));
    PetscFunctionReturn(0);
  }

  // Walls of -wave_boundary walls: the end points of a non-periodic grid, held at u = v = 0.
  bool wall(PetscInt i) const { return boundary_ == Walls && grid_->is_boundary(i); }

  void pulse(PetscReal x, PetscReal *u, PetscReal *du) const {
    const PetscReal s = (x - center_) / width_;
    *u = std::exp(-s * s);
    *du = -2.0 * s / width_ * (*u);
  }

  PetscErrorCode assemble(Mat A) override {
    ConstArray c(c_);
    std::array<StencilEntry, 5> st;
    PetscFunctionBeginUser;
    PetscCall(c.error());
    PetscCall(MatZeroEntries(A));
    for (PetscInt il = 0; il < grid_->xm(); ++il) {
      const PetscInt i = grid_->xs() + il;
      if (wall(i)) continue;
      const PetscInt ru = 2 * i, rv = 2 * i + 1;
      const PetscScalar one = 1.0;
      PetscCall(MatSetValue(A, ru, rv, one, INSERT_VALUES));
      const PetscReal c2 = PetscRealPart(c[il]) * PetscRealPart(c[il]);
      PetscInt m = d2_.row(*grid_, i, st), cols[5];
      PetscScalar vals[5];
      for (PetscInt q = 0; q < m; ++q) {
        cols[q] = 2 * st[q].j;
        vals[q] = c2 * st[q].weight;
      }
      PetscCall(MatSetValues(A, 1, &rv, m, cols, vals, INSERT_VALUES));
    }
    PetscCall(MatAssemblyBegin(A, MAT_FINAL_ASSEMBLY));
    PetscCall(MatAssemblyEnd(A, MAT_FINAL_ASSEMBLY));
    PetscFunctionReturn(0);
  }

  // y = dG/dc x   (x in parameter space, y in state space)
  static PetscErrorCode jp_mult(Mat Jp, Vec x, Vec y) {
    WaveModel *m;
    PetscFunctionBeginUser;
    PetscCall(MatShellGetContext(Jp, &m));
    PetscCall(m->recorded_columns());
    const ParamInfo &pi = m->params_->info(m->c_index_);
    PetscReal dc_scalar = 0;
    if (!m->c_field_) PetscCall(m->params_->scalar(x, m->c_index_, &dc_scalar));
    ConstArray X(x);
    Array Y(y);
    PetscCall(X.error());
    PetscCall(Y.error());
    for (PetscInt il = 0; il < m->grid_->xm(); ++il) {
      const PetscReal dc = m->c_field_ ? PetscRealPart(X[pi.local_offset + il]) : dc_scalar;
      Y[2 * il] = 0;
      Y[2 * il + 1] = m->dgdc_[il] * dc;
    }
    PetscFunctionReturn(0);
  }

  // y = (dG/dc)^T x   (x in state space, y in parameter space): the field J^T formed from this x at
  // this stage, else 2 c (D2 u) x_v from the columns.
  static PetscErrorCode jp_mult_transpose(Mat Jp, Vec x, Vec y) {
    WaveModel *m;
    bool hit = false;
    PetscFunctionBeginUser;
    PetscCall(MatShellGetContext(Jp, &m));
    PetscCall(m->fused_.matches(x, m->stage_.serial(), &hit));
    std::vector<PetscReal> &g = hit ? m->fused_.g : m->gbuf_;
    if (!hit) {
      PetscCall(m->recorded_columns());
      ConstArray X(x);
      PetscCall(X.error());
      for (PetscInt il = 0; il < m->grid_->xm(); ++il) g[il] = m->dgdc_[il] * PetscRealPart(X[2 * il + 1]);
    }
    if (m->c_field_ && m->params_->count() == 1) { // c is the only parameter: the field is y
      Array Y(y);
      PetscCall(Y.error());
      std::copy(g.begin(), g.end(), Y.data());
      PetscFunctionReturn(0);
    }
    PetscCall(VecSet(y, 0.0));
    PetscCall(m->params_->add_pointwise(y, m->c_index_, g));
    PetscFunctionReturn(0);
  }

  const Grid *grid_ = nullptr;
  const PointSource *source_ = nullptr;
  DM dm_ = nullptr;
  Parameters *params_ = nullptr;
  SecondDerivative d2_;
  PetscBool c_field_ = PETSC_FALSE;
  enum { Travelling, Rest, Zero, TwoLevel };
  enum { Walls, ZeroOutside };
  PetscInt ic_ = Travelling, boundary_ = Walls, c_index_ = -1;
  PetscReal ic_dt_ = 0; // the integrator's step (set_time_step), for the two-level start
  std::vector<PetscReal> d2u0_; // D2 u^0 of the pulse, for the two-level start
  PetscReal center_ = 0.5, width_ = 0.2, cmax_ = 0, c_min_ = 0.01;
  OwnedVec c_;
  std::vector<PetscReal> dgdc_, c2_, two_c_, gbuf_; // 2 c D2 u at the last state; c^2; 2c (0 at walls); work
  Halo halo_u_, halo_v_, halo_c_; // ghosts of u, of lambda_v (adjoint) and of c
  Halo pair_; // the adjoint sweeps' ghosts of u and lambda_v in one exchange (begin_pair)
  std::vector<PetscReal> gacc_;   // a scalar c's pointwise gradient terms during an adjoint (begin_adjoint)
  bool scalar_pointwise_ = false; // ... being accumulated there
  PetscInt hw_ = 1, lo_ = 0, hi_ = 0; // stencil half-width; owned points [lo_, hi_) take the plain sweep
  PetscReal wt_[5] = {0, 0, 0, 0, 0}; // the centred weights / h^2
  // The state recorded by rhs_jacobian_p, the record dgdc_ was formed at, and J^T's fused dG/dc
  // transpose.
  RecordedStage stage_;
  unsigned long columns_serial_ = 0;
  FusedGradient fused_;
};

} // namespace

FLEXIPDE_REGISTER_MODEL("wave", WaveModel);

} // namespace flexipde
