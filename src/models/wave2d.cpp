// Acoustic wave equation in 2D with a spatially varying speed and an absorbing sponge layer,
// written as a first-order system on a 2D DMDA:
//
//   u_t = v,   v_t = c(x, y)^2 (u_xx + u_yy) - sigma(x, y) v + w(t) delta_h(x - x_s)
//
// on [x0, x1] x [y0, y1] with u = v = 0 on the outer edge (Dirichlet). U = (u, v) interleaved per
// point; the Laplacian is the 5-point stencil (second order). The sponge damps waves in a layer of
// width W (-wave2d_sponge_width, physical units) along every edge:
//   sigma = sigma_max (d / W)^2,  d = depth into the layer (0 in the interior), -wave2d_sponge_strength sigma_max,
// so that waves leaving the region of interest are absorbed instead of coming back from the walls
// (the reflection of a quadratic sponge falls like exp(-2 sigma_max W / (3 c))).
//
// The damping term -sigma v makes G_v depend on v: with a sponge (W > 0) the model is not in the
// second-order form a leapfrog integrator needs (second_order_pairs() = 0), so use -ts_type rk or
// cn; with -wave2d_sponge_width 0 (plain Dirichlet walls) it is, and -ts_type leapfrog works.
//
// Parameter c: one scalar (-wave2d_c_field 0) or a field (-wave2d_c_field 1, one value per point).
//   G(U; c)   = [v ; c^2 L u - sigma v + f(t)]      dG/dU = [0 I ; diag(c^2) L  -diag(sigma)]
//   dG/dc_k   = 2 c_k (L u)_k e_{v,k}   (field; a scalar takes the sum)
// dG/dc is a MatShell whose transpose is a pointwise product. G and L u are matrix-free sweeps
// (owned values read in place, only the ghosts of u exchanged, halo.hpp); the assembled dG/dU
// serves implicit integrators and PETSc's RK/theta adjoints. Without a sponge the model also offers
// the leapfrog's fused adjoint (Model::second_order_adjoint): one sweep gives
// lambda_u += w L (c^2 lambda_v) (c^2 taken as 0 on the edge rows, which A does not have) and
// mu += w 2 c (L u) lambda_v; with full storage it reads L u from the record that the forward's
// evaluation of G wrote at that level (Model::second_order_adjoint_takes_record), one Laplacian instead
// of two. For the explicit RK adjoint it offers the stage products fused
// (Model::stage_adjoint, sponge or not): one sweep gives y = (dG/dU)^T x and mu += (dG/dc)^T x, the
// numbers of the two transposes above; without a sponge they also take a stage's u alone, so that
// full storage keeps only the stages' positions (half the memory).
//
// Initial condition (-wave2d_ic zero|pulse): zero (waves from point sources, survey.hpp), or a
// Gaussian exp(-|x - x_c|^2 / w^2) at rest (-wave2d_ic_x, -wave2d_ic_y, -wave2d_ic_width).
//
//   mpiexec -n 2 ./flexipde -model wave2d -task forward -da_grid_x 101 -da_grid_y 101 -wave2d_ic pulse
//   mpiexec -n 2 ./flexipde -model wave2d -task taylor -da_grid_x 41 -da_grid_y 41 -wave2d_c_field 1
//           -wave2d_c 1.0 -true_wave2d_c 1.1 -objective_type receivers -survey_sources_x 0.5 -survey_sources_y 0.3
//           -survey_receivers_spread 0.2,0.8,7 -survey_receivers_y 0.7 -ts_max_time 0.6 -ts_dt 2e-3
//   (one command line)
#include "flexipde/halo.hpp"
#include "flexipde/leapfrog.hpp"
#include "flexipde/sweep_support.hpp"
#include "flexipde/model.hpp"
#include "flexipde/survey.hpp"
#include <cmath>
#include <type_traits>
#include <vector>

namespace flexipde {
namespace {

// One row of the RK adjoint stage's operands made contiguous (Wave2DModel::stage_adjoint): z = c^2 x_v
// (x interleaved (u, v)) and u (read at stride SU: 2 in a whole (u, v) state, 1 in positions alone).
template <int SU>
void stage_operands(PetscInt n, const PetscScalar *__restrict X, const PetscScalar *__restrict u,
                    const PetscReal *__restrict c2, PetscReal *__restrict z, PetscReal *__restrict ur) {
  for (PetscInt i = 0; i < n; ++i) z[i] = c2[i] * PetscRealPart(X[2 * i + 1]);
  for (PetscInt i = 0; i < n; ++i) ur[i] = PetscRealPart(u[SU * i]);
}

// The interior points [1, xm - 1) of one interior row (all four neighbours owned) of the RK adjoint stage
// (Wave2DModel::stage_adjoint): y = [L (c^2 x_v) ; x_u - sigma x_v] and g = 2 c (L u) x_v, added to g
// when ADD (a field's gradient), else written (a scalar's terms); u: a whole (u, v) state, or with REC
// the stage's record L u itself; sigma only when SPONGE. z = c^2 x_v of the row and of the rows below
// and above is formed once per point into a ring (zm, z0, zp, contiguous). The expressions of
// jmf_apply<true> and jp_mult_transpose, term by term (and of rhs's L u, which made the record).
// X, Y, u, tc... point at the row's first point.
template <bool REC, bool SPONGE, bool ADD>
void stage_ring_row(PetscInt xm, PetscReal ax, PetscReal ay, PetscReal a0, const PetscReal *__restrict zm,
                    const PetscReal *__restrict z0, const PetscReal *__restrict zp, const PetscScalar *__restrict X,
                    const PetscScalar *__restrict u, const PetscReal *__restrict tc, const PetscReal *__restrict sig,
                    PetscScalar *__restrict Y, PetscReal *__restrict g) {
  for (PetscInt i = 1; i < xm - 1; ++i) {
    const PetscReal lu = REC ? PetscRealPart(u[i])
                             : ax * (PetscRealPart(u[2 * (i - 1)]) + PetscRealPart(u[2 * (i + 1)])) +
                                   ay * (PetscRealPart(u[2 * (i - xm)]) + PetscRealPart(u[2 * (i + xm)])) +
                                   a0 * PetscRealPart(u[2 * i]);
    const PetscReal xv = PetscRealPart(X[2 * i + 1]);
    Y[2 * i] = ax * (z0[i - 1] + z0[i + 1]) + ay * (zm[i] + zp[i]) + a0 * z0[i];
    Y[2 * i + 1] = SPONGE ? X[2 * i] - sig[i] * X[2 * i + 1] : X[2 * i];
    if (ADD) g[i] += tc[i] * lu * xv;
    else g[i] = tc[i] * lu * xv;
  }
}

// The same for n points of a row whose operands z = c^2 x_v and u were made contiguous (stage_operands,
// ghosts included): rows m, 0, p below, at and above it, z0[-1] and z0[n] its left and right neighbours.
// REC: u0 is the row of the record L u (um, up unread).
template <bool REC, bool SPONGE, bool ADD>
void stage_row(PetscInt n, PetscReal ax, PetscReal ay, PetscReal a0, const PetscReal *__restrict zm,
               const PetscReal *__restrict z0, const PetscReal *__restrict zp, const PetscReal *__restrict um,
               const PetscReal *__restrict u0, const PetscReal *__restrict up, const PetscScalar *__restrict X,
               const PetscReal *__restrict tc, const PetscReal *__restrict sig, PetscScalar *__restrict Y,
               PetscReal *__restrict g) {
  for (PetscInt i = 0; i < n; ++i) {
    const PetscReal lu = REC ? u0[i] : ax * (u0[i - 1] + u0[i + 1]) + ay * (um[i] + up[i]) + a0 * u0[i];
    const PetscReal lz = ax * (z0[i - 1] + z0[i + 1]) + ay * (zm[i] + zp[i]) + a0 * z0[i];
    const PetscReal xv = PetscRealPart(X[2 * i + 1]);
    Y[2 * i] = lz;
    Y[2 * i + 1] = SPONGE ? X[2 * i] - sig[i] * X[2 * i + 1] : X[2 * i];
    if (ADD) g[i] += tc[i] * lu * xv;
    else g[i] = tc[i] * lu * xv;
  }
}

class Wave2DModel final : public LinearModel {
public:
  const char *name() const override { return "wave2d"; }
  PetscInt dof() const override { return 2; }
  const char *component_name(PetscInt c) const override { return c == 0 ? "u" : "v"; }
  PetscInt stencil_width(MPI_Comm) const override { return 1; }
  PetscInt dim() const override { return 2; }
  void grid_defaults(GridOptions &g) const override {
    g.n = 101;
    g.ny = 101;
  }
  PetscInt second_order_pairs() const override { return sponge_width_ > 0 ? 0 : 1; }
  bool accepts_point_source() const override { return true; }
  PetscErrorCode set_point_source(const PointSource *src) override {
    source_ = src;
    return 0;
  }

  PetscErrorCode setup(const Grid &grid, DM state_dm, Parameters &params) override {
    const char *ics[] = {"zero", "pulse"};
    PetscFunctionBeginUser;
    grid_ = &grid;
    dm_ = state_dm;
    params_ = &params;
    PetscOptionsBegin(grid.comm(), nullptr, "2D acoustic wave model u_tt = c(x,y)^2 (u_xx + u_yy) with a sponge",
                      "Wave2D");
    PetscCall(PetscOptionsBool("-wave2d_c_field", "Speed c is a field (one value per grid point), else one scalar",
                               "Wave2D", c_field_, &c_field_, nullptr));
    PetscCall(PetscOptionsReal("-wave2d_c_min", "Smallest admissible speed: optimisers never go below it", "Wave2D",
                               c_min_, &c_min_, nullptr));
    PetscCall(PetscOptionsReal("-wave2d_sponge_width", "Width W of the absorbing layer along each edge (0: none)",
                               "Wave2D", sponge_width_, &sponge_width_, nullptr));
    PetscCall(PetscOptionsReal("-wave2d_sponge_strength", "Damping sigma_max at the outer edge of the layer",
                               "Wave2D", sigma_max_, &sigma_max_, nullptr));
    PetscCall(PetscOptionsEList("-wave2d_ic", "Initial condition", "Wave2D", ics, 2, ics[ic_], &ic_, nullptr));
    PetscCall(PetscOptionsReal("-wave2d_ic_x", "Centre x of the initial pulse", "Wave2D", ic_x_, &ic_x_, nullptr));
    PetscCall(PetscOptionsReal("-wave2d_ic_y", "Centre y of the initial pulse", "Wave2D", ic_y_, &ic_y_, nullptr));
    PetscCall(PetscOptionsReal("-wave2d_ic_width", "Width of the initial pulse", "Wave2D", ic_w_, &ic_w_, nullptr));
    PetscOptionsEnd();
    PetscCheck(c_min_ > 0, grid.comm(), PETSC_ERR_ARG_OUTOFRANGE, "-wave2d_c_min must be positive, got %g",
               (double)c_min_);
    PetscCheck(sponge_width_ >= 0 && sigma_max_ >= 0, grid.comm(), PETSC_ERR_ARG_OUTOFRANGE,
               "-wave2d_sponge_width and -wave2d_sponge_strength must be non-negative");
    PetscCheck(ic_w_ > 0, grid.comm(), PETSC_ERR_ARG_OUTOFRANGE, "-wave2d_ic_width must be positive");
    c_index_ = params.add("wave2d_c", c_field_ ? ParamKind::Field : ParamKind::Scalar, c_min_);
    PetscCall(DMCreateGlobalVector(grid.dm(), c_.out()));
    PetscCall(halo_u_.setup(grid, dm_, 0, 1));
    PetscCall(halo_v_.setup(grid, dm_, 1, 1));
    PetscCall(halo_c_.setup(grid, grid.dm(), 0, 1));
    PetscCall(halo_q_.setup(grid, grid.dm(), 0, 1));
    PetscCall(create_operator(dm_));
    const PetscInt n = grid.local_points();
    lap_.assign(n, 0.0);
    c2m_.assign(n, 0.0);
    two_c_.assign(n, 0.0);
    edge_.assign(n, 0);
    for (PetscInt k = 0; k < n; ++k) edge_[k] = on_edge(k);
    ihx2_ = 1.0 / (grid.h() * grid.h());
    ihy2_ = 1.0 / (grid.hy() * grid.hy());
    gbuf_.assign(n, 0.0);
    rows_.assign(6 * (grid.xm() + 2), 0.0);
    walls_[0] = !grid.periodic() && grid.xs() == 0;
    walls_[1] = !grid.periodic() && grid.xs() + grid.xm() == grid.n();
    walls_[2] = !grid.periodic_y() && grid.ys() == 0;
    walls_[3] = !grid.periodic_y() && grid.ys() + grid.ym() == grid.ny();
    sigma_.assign(n, 0.0);
    for (PetscInt k = 0; k < n; ++k) {
      const PetscInt i = grid.xs() + k % grid.xm(), j = grid.ys() + k / grid.xm();
      sigma_[k] = sponge(grid.x(i), grid.y(j));
    }
    PetscFunctionReturn(0);
  }

  PetscErrorCode create_jacobian_matrix_free(Mat *J) override {
    const PetscInt nstate = grid_->local_points() * dof();
    PetscFunctionBeginUser;
    PetscCall(MatCreateShell(grid_->comm(), nstate, nstate, PETSC_DETERMINE, PETSC_DETERMINE, this, J));
    PetscCall(MatShellSetOperation(*J, MATOP_MULT, (void (*)(void))jmf_apply<false>));
    PetscCall(MatShellSetOperation(*J, MATOP_MULT_TRANSPOSE, (void (*)(void))jmf_apply<true>));
    PetscFunctionReturn(0);
  }

  PetscErrorCode create_jacobian_p(Mat *Jp) override {
    const PetscInt nstate = grid_->local_points() * dof();
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
    PetscCheck(cmin > 0, grid_->comm(), PETSC_ERR_ARG_OUTOFRANGE, "Wave speed must be positive, found c = %g",
               (double)cmin);
    PetscCall(VecMax(c_, nullptr, &cmax_));
    {
      ConstArray c(c_);
      PetscCall(c.error());
      for (PetscInt k = 0; k < grid_->local_points(); ++k) {
        const PetscReal ck = PetscRealPart(c[k]);
        c2m_[k] = edge_[k] ? 0.0 : ck * ck;
        two_c_[k] = edge_[k] ? 0.0 : 2 * ck;
      }
    }
    PetscCall(halo_c_.update(c_));
    mark_operator_stale(); // assembled when an integrator asks for dG/dU
    PetscFunctionReturn(0);
  }

  // G = A U as a sweep: u_t = v, v_t = c^2 L u - sigma v off the edges, 0 on them; plus the source.
  PetscErrorCode rhs(PetscReal t, Vec U, Vec G) override { return rhs_sweep<false>(t, U, G, nullptr); }
  // The same, also writing the stage record L u (0 on the edges) for stage_adjoint.
  PetscInt stage_record_size() const override { return grid_->local_points(); }
  bool stage_record_replaces_state() const override { return true; }
  PetscErrorCode rhs_record(PetscReal t, Vec U, Vec G, PetscScalar *record) override {
    return rhs_sweep<true>(t, U, G, record);
  }
  template <bool REC>
  PetscErrorCode rhs_sweep(PetscReal t, Vec U, Vec G, PetscScalar *record) {
    PetscFunctionBeginUser;
    {
      Array g(G);
      PetscCall(g.error());
      PetscScalar *ga = g.data();
      const PetscReal *sig = sigma_.data(), *c2 = c2m_.data();
      // Records (kept by full storage, read by the adjoint much later) are written with non-temporal
      // stores, past the caches: formed in a buffer of the whole block first (in cache) and streamed from
      // there in one contiguous pass after the sweep: whole cache lines, not the pieces that the interior
      // rows and, later, the perimeter would write (a line written in parts by non-temporal stores is
      // flushed in parts, slower than plain stores).
      const PetscInt n = grid_->local_points();
      if (REC && rec_stage_.size() < (size_t)n) rec_stage_.resize(n);
      PetscScalar *rec = REC ? rec_stage_.data() : nullptr;
      auto emit = [&](PetscInt k, PetscReal lu, const PetscScalar *u) {
        if (edge_[k]) {
          ga[2 * k] = ga[2 * k + 1] = 0;
          if (REC) rec[k] = 0.0;
        } else {
          ga[2 * k] = u[2 * k + 1];
          ga[2 * k + 1] = c2[k] * lu - sig[k] * u[2 * k + 1];
          if (REC) rec[k] = lu;
        }
      };
      // the block's interior rows in a loop of their own that vectorises (rhs_row)
      const PetscInt xm = grid_->xm();
      const PetscReal ax = ihx2_, ay = ihy2_, a0 = -2 * (ihx2_ + ihy2_);
      PetscCall(sweep<false>(U, emit, [&](PetscInt jl, const PetscScalar *u) {
        rhs_row<REC>(xm, u + 2 * jl * xm, ga + 2 * jl * xm, c2 + jl * xm, sig + jl * xm, REC ? rec + jl * xm : nullptr,
                     ax, ay, a0);
      }));
      if (REC) {
        stream_copy(record, rec, n);
        stream_fence();
      }
    }
    if (source_ && source_->stencil.n) {
      Array g(G);
      PetscCall(g.error());
      for (PetscInt k = 0; k < source_->stencil.n; ++k) {
        const PetscInt il = source_->stencil.local[k];
        if (edge_[il]) continue;
        g[2 * il + 1] += source_->density(k, t);
      }
    }
    PetscFunctionReturn(0);
  }

  // G at the interior points [1, xm - 1) of one row (arrays at the row's first point, rows xm points
  // apart): the expressions of rhs_sweep's emit off the edges, in a loop the compiler vectorises.
  template <bool REC>
  __attribute__((optimize("tree-vectorize", "vect-cost-model=dynamic")))
  static void rhs_row(PetscInt xm, const PetscScalar *__restrict u, PetscScalar *__restrict g, const PetscReal *__restrict c2,
                      const PetscReal *__restrict sig, PetscScalar *__restrict rec, PetscReal ax, PetscReal ay, PetscReal a0) {
    for (PetscInt i = 1; i < xm - 1; ++i) {
      const PetscReal lu = ax * (PetscRealPart(u[2 * (i - 1)]) + PetscRealPart(u[2 * (i + 1)])) +
                           ay * (PetscRealPart(u[2 * (i - xm)]) + PetscRealPart(u[2 * (i + xm)])) + a0 * PetscRealPart(u[2 * i]);
      g[2 * i] = u[2 * i + 1];
      g[2 * i + 1] = c2[i] * lu - sig[i] * u[2 * i + 1];
      if (REC) rec[i] = lu;
    }
  }

  // Records (L u)_k at this state for the shell dG/dc (0 on the edges).
  PetscErrorCode rhs_jacobian_p(PetscReal, Vec U, Mat Jp) override {
    PetscFunctionBeginUser;
    PetscCall(sweep_lap(U, [&](PetscInt k, PetscReal lu, const PetscScalar *) { lap_[k] = edge_[k] ? 0.0 : lu; }));
    PetscCall(MatAssemblyBegin(Jp, MAT_FINAL_ASSEMBLY));
    PetscCall(MatAssemblyEnd(Jp, MAT_FINAL_ASSEMBLY));
    PetscFunctionReturn(0);
  }

  bool has_second_order_adjoint() const override { return sponge_width_ <= 0; }
  bool second_order_adjoint_takes_positions() const override { return true; }
  // The kick reads u only through L u off the edges: the record rhs_record writes (0 on the edges).
  bool second_order_adjoint_takes_record() const override { return sponge_width_ <= 0; }
  // lambda_u += w L (c^2 lambda_v) at every point (edge columns included, as in A^T), and
  // mu += w 2 c (L u) lambda_v off the edges, in one sweep. U is a whole state or u alone, or null with
  // the state's record L u (no Laplacian of u then, and no exchange of its ghosts).
  PetscErrorCode second_order_adjoint(PetscReal, Vec U, const PetscScalar *record, Vec lambda, PetscReal w, Vec mu,
                                      PetscReal drift, const PetscScalar *prefetch) override {
    const ParamInfo &pi = params_->info(c_index_);
    PetscReal local[4] = {0, 0, 0, 0}; // four partial sums: no single dependency chain through the sweep
    PetscInt nu;
    PetscFunctionBeginUser;
    PetscCheck(sponge_width_ <= 0, grid_->comm(), PETSC_ERR_SUP, "wave2d: no fused leapfrog adjoint with a sponge");
    leapfrog_prefetch(prefetch, grid_->local_points()); // the next level's positions
    // the drift's transpose: folded into the kick's ring pass, or in a pass of its own first
    const bool fold = drift != 0 && grid_->xm() >= 3 && grid_->ym() >= 3;
    if (drift != 0 && !fold) {
      Array l(lambda);
      PetscCall(l.error());
      leapfrog_drift_transpose(l.data(), 0, grid_->local_points(), 1, drift);
    }
    if (record) PetscCall(kick<0>(nullptr, record, lambda, w, mu, pi, local, fold ? drift : 0));
    else {
      PetscCall(VecGetLocalSize(U, &nu));
      if (nu == grid_->local_points()) PetscCall(kick<1>(U, nullptr, lambda, w, mu, pi, local, fold ? drift : 0));
      else PetscCall(kick<2>(U, nullptr, lambda, w, mu, pi, local, fold ? drift : 0));
    }
    if (mu && !c_field_) PetscCall(params_->add_local_sum(mu, c_index_, w * (local[0] + local[1] + local[2] + local[3])));
    PetscFunctionReturn(0);
  }

  // (L u) at point k of the kick: from u read at stride SU (k's neighbours xm apart in y), or with SU = 0
  // the record L u itself.
  template <int SU>
  static PetscReal kick_lu(const PetscScalar *ua, PetscInt k, PetscInt xm, PetscReal ax, PetscReal ay, PetscReal a0) {
    if (SU == 0) return PetscRealPart(ua[k]);
    return ax * PetscRealPart(ua[SU * (k - 1)] + ua[SU * (k + 1)]) + ay * PetscRealPart(ua[SU * (k - xm)] + ua[SU * (k + xm)]) +
           a0 * PetscRealPart(ua[SU * k]);
  }
  // kick's ring row: lambda_v += s lambda_u at the row's interior points [1, xm - 1) (s != 0: the folded
  // drift, leapfrog_drift_transpose's expression), then z = c^2 lambda_v at all xm points; loops that vectorise.
  __attribute__((optimize("tree-vectorize", "vect-cost-model=dynamic")))
  static void ring_row(PetscInt xm, PetscScalar *__restrict L, const PetscReal *__restrict c2, PetscReal *__restrict z, PetscReal s) {
    if (s != 0)
      for (PetscInt i = 1; i < xm - 1; ++i) L[2 * i + 1] += s * L[2 * i];
    for (PetscInt i = 0; i < xm; ++i) z[i] = c2[i] * PetscRealPart(L[2 * i + 1]);
  }
  // One row's interior points [1, xm - 1) of kick's ring pass (arrays at the row's first point; the row of u
  // xm apart from its neighbours, z's three rows from the ring).
  template <int SU, bool ADD>
  __attribute__((optimize("tree-vectorize", "vect-cost-model=dynamic")))
  static void kick_row(PetscInt xm, const PetscScalar *__restrict ua, PetscScalar *__restrict L, const PetscReal *__restrict c2,
                       const PetscReal *__restrict tc, const PetscReal *__restrict zm, const PetscReal *__restrict z0,
                       const PetscReal *__restrict zp, PetscScalar *__restrict out, PetscReal ax, PetscReal ay, PetscReal a0,
                       PetscReal w) {
    for (PetscInt i = 1; i < xm - 1; ++i) {
      const PetscReal lu = kick_lu<SU>(ua, i, xm, ax, ay, a0);
      const PetscReal v = PetscRealPart(L[2 * i + 1]);
      const PetscReal lz = ax * (z0[i - 1] + z0[i + 1]) + ay * (zm[i] + zp[i]) + a0 * c2[i] * v;
      L[2 * i] += w * lz;
      const PetscReal gk = tc[i] * lu * v;
      if (ADD) out[i] += w * gk;
      else out[i] = gk;
    }
  }
  // The sweep of second_order_adjoint with u read at stride SU in U (2: a whole state, 1: u alone), or
  // (SU = 0, U null) with L u read from the record rec.
  // s != 0 (xm, ym >= 3): the drift lambda_v += s lambda_u folded in: the block's
  // perimeter first (the points whose lambda_v the neighbours receive), the interior points by the ring
  // pass, a row ahead of that row's kick and with its lambda_u from before it. Bitwise the same.
  template <int SU>
  PetscErrorCode kick(Vec U, const PetscScalar *rec, Vec lambda, PetscReal w, Vec mu, const ParamInfo &pi, PetscReal local[4],
                      PetscReal s) {
    const PetscInt xm = grid_->xm(), ym = grid_->ym();
    Halo &halo_u = SU == 1 ? halo_q_ : halo_u_;
    PetscFunctionBeginUser;
    if (SU) PetscCall(halo_u.begin(U));
    if (s != 0) {
      Array l(lambda);
      PetscCall(l.error());
      PetscScalar *L = l.data();
      leapfrog_drift_transpose(L, 0, xm, 1, s);
      leapfrog_drift_transpose(L, (ym - 1) * xm, ym * xm, 1, s);
      for (PetscInt jl = 1; jl < ym - 1; ++jl) {
        leapfrog_drift_transpose(L, jl * xm, jl * xm + 1, 1, s);
        leapfrog_drift_transpose(L, jl * xm + xm - 1, jl * xm + xm, 1, s);
      }
    }
    PetscCall(halo_v_.begin(lambda));
    {
      ConstArray u(SU ? U : nullptr);
      Array l(lambda);
      if (SU) PetscCall(u.error());
      PetscCall(l.error());
      PetscScalar *g = nullptr;
      if (mu && c_field_) PetscCall(VecGetArray(mu, &g));
      const PetscScalar *ua = SU ? u.data() : rec;
      PetscScalar *L = l.data();
      const PetscReal *c2 = c2m_.data(), *tc = two_c_.data();
      const PetscReal ax = ihx2_, ay = ihy2_, a0 = -2 * (ihx2_ + ihy2_);
      auto body = [&](PetscInt k, PetscReal lu, PetscReal lz) {
        L[2 * k] += w * lz;
        const PetscReal gk = tc[k] * lu * PetscRealPart(L[2 * k + 1]);
        if (g) g[pi.local_offset + k] += w * gk;
        else local[k & 3] += gk;
      };
      // the interior: a field's gradient in place, a scalar's per-point terms into gbuf_, summed per row
      // (no reduction inside the loop, which keeps it vectorised)
      PetscReal *out = g ? g + pi.local_offset : gbuf_.data();
      // The products c^2 lambda_v that the transpose's stencil reads at four neighbours are formed once per
      // point, a row ahead, into a ring of three rows (contiguous, in L1), not four times from the
      // interleaved lambda (the same products, so the same numbers: the centre's (a0 c^2) lambda_v keeps
      // its own order).
      if (zring_.size() < (size_t)(3 * xm)) zring_.resize(3 * xm);
      PetscReal *zr = zring_.data();
      auto zrow = [&](PetscInt j) {
        PetscReal *__restrict z = zr + (j % 3) * xm;
        // an interior row: its interior points drifted first (the perimeter was, before the exchange)
        ring_row(xm, L + 2 * j * xm, c2 + j * xm, z, s != 0 && j > 0 && j < ym - 1 ? s : 0);
      };
      auto interior = [&](auto add) {
        constexpr bool ADD = decltype(add)::value;
        if (ym > 2) {
          zrow(0);
          zrow(1);
        }
        for (PetscInt jl = 1; jl < ym - 1; ++jl) {
          zrow(jl + 1);
          const PetscReal *__restrict zm = zr + ((jl - 1) % 3) * xm, *__restrict z0 = zr + (jl % 3) * xm,
                                      *__restrict zp = zr + ((jl + 1) % 3) * xm;
          kick_row<SU, ADD>(xm, ua + (SU ? SU : 1) * jl * xm, L + 2 * jl * xm, c2 + jl * xm, tc + jl * xm, zm, z0, zp,
                            out + jl * xm, ax, ay, a0, w);
        }
      };
      if (g) interior(std::true_type{});
      else {
        interior(std::false_type{});
        for (PetscInt jl = 1; jl < ym - 1; ++jl) sum4(out, jl * xm + 1, jl * xm + xm - 1, local);
      }
      if (SU) PetscCall(halo_u.end(U));
      PetscCall(halo_v_.end(lambda));
      PetscCall(perimeter_laps<SU>(ua, L, halo_u, body));
      if (g) PetscCall(VecRestoreArray(mu, &g));
    }
    PetscFunctionReturn(0);
  }

  // The explicit RK adjoint's stage products (rk_adjoint.hpp) in one sweep, at a stage U (a whole
  // state), or from the stage's record L u (rhs_record) alone:
  //   y = (dG/dU)^T x = [L (c^2 x_v) ; x_u - sigma x_v]  (L (c^2 x_v) at every point, edge columns
  //       included as in A^T; the second block 0 on the edge rows)
  //   mu += (dG/dc)^T x = 2 c (L u) x_v  off the edges (a scalar c: its sum, deferred to the Parameters).
  // The same expressions as jmf_apply<true> and jp_mult_transpose: a field's gradient equals theirs
  // bitwise, a scalar's up to the order of the sum. dG/dU is constant and dG/dc reads L u only, sponge
  // or not (with a sponge G_v depends on v, so the model is not in second-order form for the leapfrog,
  // but the record still serves the RK adjoint): full storage keeps the records alone, half the memory
  // of whole stages, and the sweep computes one Laplacian instead of two (and exchanges no ghosts of u).
  bool has_stage_adjoint() const override { return true; }
  PetscErrorCode stage_adjoint(PetscReal, Vec U, const PetscScalar *record, Vec x, Vec y, Vec mu) override {
    PetscReal local[4] = {0, 0, 0, 0};
    PetscFunctionBeginUser;
    const bool sponge = sponge_width_ > 0;
    if (record) {
      if (sponge) PetscCall(stage_sweep<true, true>(nullptr, record, x, y, mu, local));
      else PetscCall(stage_sweep<true, false>(nullptr, record, x, y, mu, local));
    } else if (sponge) PetscCall(stage_sweep<false, true>(U, nullptr, x, y, mu, local));
    else PetscCall(stage_sweep<false, false>(U, nullptr, x, y, mu, local));
    if (mu && !c_field_) PetscCall(params_->add_local_sum(mu, c_index_, local[0] + local[1] + local[2] + local[3]));
    PetscFunctionReturn(0);
  }

  // stage_adjoint's sweep: REC: L u read from the record lu (U unread), else from the whole state U;
  // SPONGE: sigma read (else 0).
  template <bool REC, bool SPONGE>
  PetscErrorCode stage_sweep(Vec U, const PetscScalar *lu_record, Vec x, Vec y, Vec mu, PetscReal local[4]) {
    const PetscInt xm = grid_->xm(), ym = grid_->ym(), w = xm + 2;
    Halo &halo_u = halo_u_;
    PetscFunctionBeginUser;
    if (!REC) PetscCall(halo_u.begin(U));
    PetscCall(halo_v_.begin(x));
    {
      ConstArray u(REC ? nullptr : U), xa(x);
      Array ya(y);
      PetscCall(u.error());
      PetscCall(xa.error());
      PetscCall(ya.error());
      PetscScalar *gm = nullptr;
      if (mu && c_field_) PetscCall(VecGetArray(mu, &gm));
      const PetscScalar *ua = REC ? lu_record : u.data(), *X = xa.data();
      PetscScalar *Y = ya.data();
      const PetscReal *c2 = c2m_.data(), *tc = two_c_.data(), *sig = sigma_.data();
      const PetscReal ax = ihx2_, ay = ihy2_, a0 = -2 * (ihx2_ + ihy2_);
      // A field's gradient is added in place; a scalar's per-point terms are written to gbuf_ and
      // summed per row (no reduction inside the loop, which keeps it vectorised).
      PetscReal *g = gm ? gm + params_->info(c_index_).local_offset : gbuf_.data();
      // the interior (all four neighbours owned), while the ghosts travel: z = c^2 x_v of each row formed
      // once, a row ahead, into three contiguous rows (zring_), not at every neighbour from the interleaved x
      const bool ring = ym > 2 && xm > 2; // (else no interior)
      if (ring && zring_.size() < (size_t)(3 * xm)) zring_.resize(3 * xm);
      PetscReal *zq = zring_.data();
      auto zrow = [&](PetscInt j) {
        PetscReal *__restrict z = zq + (j % 3) * xm;
        const PetscScalar *__restrict xr = X + 2 * j * xm;
        const PetscReal *__restrict cr = c2 + j * xm;
        for (PetscInt i = 0; i < xm; ++i) z[i] = cr[i] * PetscRealPart(xr[2 * i + 1]);
      };
      if (ring) {
        zrow(0), zrow(1);
        for (PetscInt jl = 1; jl < ym - 1; ++jl) {
          const PetscInt r = jl * xm;
          zrow(jl + 1);
          const PetscReal *zm = zq + ((jl - 1) % 3) * xm, *z0 = zq + (jl % 3) * xm, *zp = zq + ((jl + 1) % 3) * xm;
          const PetscScalar *ur = ua + (REC ? r : 2 * r);
          if (gm) stage_ring_row<REC, SPONGE, true>(xm, ax, ay, a0, zm, z0, zp, X + 2 * r, ur, tc + r, sig + r, Y + 2 * r, g + r);
          else stage_ring_row<REC, SPONGE, false>(xm, ax, ay, a0, zm, z0, zp, X + 2 * r, ur, tc + r, sig + r, Y + 2 * r, g + r);
          if (!gm && mu) sum4(g, r + 1, r + xm - 1, local);
        }
      }
      if (!REC) PetscCall(halo_u.end(U));
      PetscCall(halo_v_.end(x));
      auto zg = [&](PetscInt il, PetscInt jl) { return ghost_z(il, jl); };
      // The first and last rows whole, from their rows of z = c^2 x_v and u and those below and above
      // made contiguous with their ghosts (stage_operands; three rows of xm + 2, entry 1 + il, the two
      // ends for the ghosts; with REC the record's own row only).
      PetscReal *zr = rows_.data(), *ur = zr + 3 * w;
      auto own_row = [&](PetscInt jl, PetscInt slot) {
        if (REC) stage_operands<1>(xm, X + 2 * jl * xm, ua + jl * xm, c2 + jl * xm, zr + slot * w + 1, ur + slot * w + 1);
        else stage_operands<2>(xm, X + 2 * jl * xm, ua + 2 * jl * xm, c2 + jl * xm, zr + slot * w + 1, ur + slot * w + 1);
      };
      auto row = [&](PetscInt jl) {
        const PetscInt k0 = jl * xm;
        const PetscReal *zm = zr + 1, *z0 = zr + w + 1, *zp = zr + 2 * w + 1;
        const PetscReal *um = ur + 1, *u0 = ur + w + 1, *up = ur + 2 * w + 1;
        if (gm) stage_row<REC, SPONGE, true>(xm, ax, ay, a0, zm, z0, zp, um, u0, up, X + 2 * k0, tc + k0, sig + k0, Y + 2 * k0, g + k0);
        else {
          stage_row<REC, SPONGE, false>(xm, ax, ay, a0, zm, z0, zp, um, u0, up, X + 2 * k0, tc + k0, sig + k0, Y + 2 * k0, g + k0);
          if (mu) sum4(g, k0, k0 + xm, local);
        }
      };
      for (PetscInt jl : {(PetscInt)0, ym - 1}) {
        for (PetscInt d = -1; d <= 1; ++d) {
          const PetscInt jr = jl + d, slot = d + 1;
          if (jr >= 0 && jr < ym) own_row(jr, slot);
          else
            for (PetscInt il = 0; il < xm; ++il) {
              zr[slot * w + 1 + il] = zg(il, jr);
              ur[slot * w + 1 + il] = REC ? 0.0 : PetscRealPart(halo_u(il, jr));
            }
        }
        zr[w] = zg(-1, jl), zr[w + xm + 1] = zg(xm, jl);
        if (!REC) ur[w] = PetscRealPart(halo_u(-1, jl)), ur[w + xm + 1] = PetscRealPart(halo_u(xm, jl));
        row(jl);
        for (PetscInt k = jl * xm; k < jl * xm + xm; ++k)
          if (edge_[k]) Y[2 * k + 1] = 0;
        if (ym == 1) break;
      }
      // the first and last columns between them, point by point
      for (PetscInt il : {(PetscInt)0, xm - 1}) {
        for (PetscInt jl = 1; jl < ym - 1; ++jl) {
          const PetscInt k = jl * xm + il;
          const PetscReal zl = il > 0 ? c2[k - 1] * PetscRealPart(X[2 * (k - 1) + 1]) : zg(il - 1, jl);
          const PetscReal zx = il < xm - 1 ? c2[k + 1] * PetscRealPart(X[2 * (k + 1) + 1]) : zg(il + 1, jl);
          const PetscReal ul = REC ? 0.0 : PetscRealPart(il > 0 ? ua[2 * (k - 1)] : halo_u(il - 1, jl));
          const PetscReal ux = REC ? 0.0 : PetscRealPart(il < xm - 1 ? ua[2 * (k + 1)] : halo_u(il + 1, jl));
          const PetscReal xv = PetscRealPart(X[2 * k + 1]);
          const PetscReal lz = ax * (zl + zx) + ay * (c2[k - xm] * PetscRealPart(X[2 * (k - xm) + 1]) + c2[k + xm] * PetscRealPart(X[2 * (k + xm) + 1])) + a0 * (c2[k] * xv);
          const PetscReal lu = REC ? PetscRealPart(ua[k])
                                   : ax * (ul + ux) + ay * (PetscRealPart(ua[2 * (k - xm)]) + PetscRealPart(ua[2 * (k + xm)])) +
                                         a0 * PetscRealPart(ua[2 * k]);
          Y[2 * k] = lz;
          Y[2 * k + 1] = edge_[k] ? 0.0 : (SPONGE ? X[2 * k] - sig[k] * X[2 * k + 1] : X[2 * k]);
          const PetscReal gk = tc[k] * lu * xv; // 0 on the edges (2c = 0 there)
          if (gm) g[k] += gk;
          else local[k & 3] += gk;
        }
        if (xm < 2) break;
      }
      if (gm) PetscCall(VecRestoreArray(mu, &gm));
    }
    PetscFunctionReturn(0);
  }

  PetscErrorCode spectrum(Spectrum *s) override {
    s->imag_radius = cmax_ * std::sqrt(4.0 / (grid_->h() * grid_->h()) + 4.0 / (grid_->hy() * grid_->hy()));
    s->real_radius = sigma_max_;
    return 0;
  }

  PetscErrorCode initial_condition(Vec p, Vec U0) override {
    PetscFunctionBeginUser;
    Array U(U0);
    PetscCall(U.error());
    for (PetscInt k = 0; k < grid_->local_points(); ++k) {
      const PetscInt i = grid_->xs() + k % grid_->xm(), j = grid_->ys() + k / grid_->xm();
      const PetscReal dx = grid_->x(i) - ic_x_, dy = grid_->y(j) - ic_y_;
      U[2 * k] = (ic_ == 1 && !on_edge(k)) ? std::exp(-(dx * dx + dy * dy) / (ic_w_ * ic_w_)) : 0.0;
      U[2 * k + 1] = 0.0;
    }
    PetscFunctionReturn(0);
  }
  PetscErrorCode initial_condition_transpose(Vec, Vec, Vec) override { return 0; } // U0 does not depend on c

private:
  bool inside(PetscInt il, PetscInt jl) const { return il >= 0 && il < grid_->xm() && jl >= 0 && jl < grid_->ym(); }
  // a point on the outer Dirichlet edge, by global index (also for ghosts); periodic directions have none
  bool edge_point(PetscInt i, PetscInt j) const {
    auto wrap = [](PetscInt a, PetscInt n) { return (a % n + n) % n; };
    if (grid_->periodic()) i = wrap(i, grid_->n());
    if (grid_->periodic_y()) j = wrap(j, grid_->ny());
    return grid_->is_boundary(i) || grid_->is_boundary_y(j);
  }
  // f(il, jl) once for every owned point on the block's perimeter (the points a sweep's interior
  // loop [1, xm-1) x [1, ym-1) leaves out).
  template <class F>
  PetscErrorCode for_perimeter(F &&f) const {
    const PetscInt xm = grid_->xm(), ym = grid_->ym();
    PetscFunctionBeginUser;
    for (PetscInt jl = 0; jl < ym; ++jl) {
      if (jl == 0 || jl == ym - 1) {
        for (PetscInt il = 0; il < xm; ++il) PetscCall(f(il, jl));
      } else {
        PetscCall(f(0, jl));
        if (xm > 1) PetscCall(f(xm - 1, jl));
      }
    }
    PetscFunctionReturn(0);
  }
  // The ghost (il, jl) (local indices, within one point of the block) lies beyond a wall: outside the grid
  // in a direction that is not periodic (walls_: which sides of this block have one, set up once).
  bool beyond_wall(PetscInt il, PetscInt jl) const {
    return (il < 0 && walls_[0]) || (il >= grid_->xm() && walls_[1]) || (jl < 0 && walls_[2]) || (jl >= grid_->ym() && walls_[3]);
  }
  // z = c^2 v at the ghost point (il, jl) of the block (v from halo_v_, c from halo_c_): 0 at an edge point,
  // and beyond a wall (not periodic), where the halo holds 0, c too: such a ghost is 0 without reading the
  // halo, the same number.
  PetscReal ghost_z(PetscInt il, PetscInt jl) const {
    if (beyond_wall(il, jl)) return 0.0;
    if (edge_point(grid_->xs() + il, grid_->ys() + jl)) return 0.0;
    const PetscReal c = PetscRealPart(halo_c_(il, jl));
    return c * c * PetscRealPart(halo_v_(il, jl));
  }
  // f(k, (L u)_k, (L z)_k) at every owned point on the block's perimeter, z = c^2 v (0 on the edges)
  // with v component 1 of the interleaved V (ghosts: halo_v_, filled from V's Vec), u read at stride
  // SU in ua (ghosts: halo_u); (L u)_k = 0 on the edges (where no gradient is taken).
  template <int SU, class F>
  PetscErrorCode perimeter_laps(const PetscScalar *ua, const PetscScalar *V, const Halo &halo_u, F &&f) const {
    const PetscInt xm = grid_->xm();
    const PetscReal *c2 = c2m_.data();
    const PetscReal ax = ihx2_, ay = ihy2_, a0 = -2 * (ihx2_ + ihy2_);
    auto uat = [&](PetscInt il, PetscInt jl) {
      return PetscRealPart(inside(il, jl) ? ua[SU * (jl * xm + il)] : halo_u(il, jl));
    };
    auto zat = [&](PetscInt il, PetscInt jl) {
      return inside(il, jl) ? c2[jl * xm + il] * PetscRealPart(V[2 * (jl * xm + il) + 1]) : ghost_z(il, jl);
    };
    // (SU = 0: ua is the record L u, 0 on the edges)
    auto lu_at = [&](PetscInt il, PetscInt jl, PetscInt k) {
      return SU == 0 ? PetscRealPart(ua[k])
             : edge_[k] ? 0.0
                        : ax * (uat(il - 1, jl) + uat(il + 1, jl)) + ay * (uat(il, jl - 1) + uat(il, jl + 1)) + a0 * uat(il, jl);
    };
    // In for_perimeter's order: z of the first and last rows and of the rows beyond them formed once per
    // point into three rows of xm + 2 (entry 1 + il, the ends for the ghosts: ghost_z only where a point is
    // not owned), the columns between them reading owned z directly
    const PetscInt ym = grid_->ym(), w = xm + 2;
    if (pbuf_.size() < (size_t)(3 * w)) pbuf_.resize(3 * w);
    PetscReal *zb = pbuf_.data();
    auto zown = [&](PetscInt k) { return c2[k] * PetscRealPart(V[2 * k + 1]); };
    auto row = [&](PetscInt jl) {
      for (PetscInt d = -1; d <= 1; ++d) {
        const PetscInt j = jl + d;
        PetscReal *z = zb + (d + 1) * w + 1;
        if (j >= 0 && j < ym)
          for (PetscInt il = 0; il < xm; ++il) z[il] = zown(j * xm + il);
        else if (beyond_wall(0, j)) // (a row of ghosts beyond a wall: ghost_z's 0)
          for (PetscInt il = 0; il < xm; ++il) z[il] = 0.0;
        else
          for (PetscInt il = 0; il < xm; ++il) z[il] = ghost_z(il, j);
        if (d == 0) z[-1] = zat(-1, j), z[xm] = zat(xm, j);
      }
      const PetscReal *zm = zb + 1, *z0 = zb + w + 1, *zp = zb + 2 * w + 1;
      for (PetscInt il = 0; il < xm; ++il) {
        const PetscInt k = jl * xm + il;
        f(k, lu_at(il, jl, k), ax * (z0[il - 1] + z0[il + 1]) + ay * (zm[il] + zp[il]) + a0 * z0[il]);
      }
    };
    row(0);
    for (PetscInt jl = 1; jl < ym - 1; ++jl) {
      for (PetscInt il : {(PetscInt)0, xm - 1}) {
        const PetscInt k = jl * xm + il;
        const PetscReal zl = il > 0 ? zown(k - 1) : zat(il - 1, jl), zr = il < xm - 1 ? zown(k + 1) : zat(il + 1, jl);
        f(k, lu_at(il, jl, k), ax * (zl + zr) + ay * (zown(k - xm) + zown(k + xm)) + a0 * zown(k));
        if (xm == 1) break;
      }
    }
    if (ym > 1) row(ym - 1);
    return 0;
  }
  // emit(k, (L u)_k, u) for every owned point (edges included: the caller masks them).
  template <class Emit>
  PetscErrorCode sweep_lap(Vec U, Emit &&emit) {
    return sweep<false>(U, emit);
  }
  // Z = false: emit(k, (L u)_k, x); Z = true: emit(k, (L z)_k, x) with z = c^2 v, 0 on the edges;
  // for every owned point (u, v the components of X).
  // Row (not null): row(jl, x) does the interior points of row jl itself (the same numbers as emit would
  // get there; the block's interior holds no edge point: the walls are the grid's first and last rows and
  // columns, on the perimeter of the blocks that have them).
  template <bool Z, class Emit, class Row = std::nullptr_t>
  PetscErrorCode sweep(Vec X, Emit &&emit, Row row = nullptr) {
    const PetscInt xm = grid_->xm(), ym = grid_->ym();
    const PetscReal ax = ihx2_, ay = ihy2_, a0 = -2 * (ihx2_ + ihy2_);
    Halo &halo = Z ? halo_v_ : halo_u_;
    const PetscReal *c2 = c2m_.data();
    PetscFunctionBeginUser;
    PetscCall(halo.begin(X));
    ConstArray x(X);
    PetscCall(x.error());
    const PetscScalar *xa = x.data();
    auto own = [&](PetscInt k) { return Z ? c2[k] * PetscRealPart(xa[2 * k + 1]) : PetscRealPart(xa[2 * k]); };
    if constexpr (!std::is_same_v<Row, std::nullptr_t>) {
      for (PetscInt jl = 1; jl < ym - 1; ++jl) row(jl, xa);
    } else {
      for (PetscInt jl = 1; jl < ym - 1; ++jl)
        for (PetscInt k = jl * xm + 1; k < jl * xm + xm - 1; ++k)
          emit(k, ax * (own(k - 1) + own(k + 1)) + ay * (own(k - xm) + own(k + xm)) + a0 * own(k), xa);
    }
    PetscCall(halo.end(X));
    auto at = [&](PetscInt il, PetscInt jl) -> PetscReal {
      if (inside(il, jl)) return own(jl * xm + il);
      if (!Z) return PetscRealPart(halo(il, jl));
      if (edge_point(grid_->xs() + il, grid_->ys() + jl)) return 0.0;
      const PetscReal c = PetscRealPart(halo_c_(il, jl));
      return c * c * PetscRealPart(halo(il, jl));
    };
    PetscCall(for_perimeter([&](PetscInt il, PetscInt jl) {
      emit(jl * xm + il, ax * (at(il - 1, jl) + at(il + 1, jl)) + ay * (at(il, jl - 1) + at(il, jl + 1)) + a0 * at(il, jl), xa);
      return PetscErrorCode(0);
    }));
    PetscFunctionReturn(0);
  }
  // The matrix-free dG/dU = [0 I ; diag(c^2) L  -diag(sigma)] (edge rows empty) and its transpose
  // [L (c^2 x_v) ; x_u - sigma x_v] (edge rows of the second block empty).
  template <bool T>
  static PetscErrorCode jmf_apply(Mat J, Vec x, Vec y) {
    Wave2DModel *m;
    PetscFunctionBeginUser;
    PetscCall(MatShellGetContext(J, &m));
    Array ya(y);
    PetscCall(ya.error());
    PetscScalar *Y = ya.data();
    const PetscReal *sig = m->sigma_.data(), *c2 = m->c2m_.data();
    const char *edge = m->edge_.data();
    PetscCall(m->sweep<T>(x, [&](PetscInt k, PetscReal l, const PetscScalar *X) {
      if (T) { // [L (c^2 x_v) ; x_u - sigma x_v]
        Y[2 * k] = l;
        Y[2 * k + 1] = edge[k] ? 0.0 : X[2 * k] - sig[k] * X[2 * k + 1];
      } else if (edge[k]) Y[2 * k] = Y[2 * k + 1] = 0;
      else { // [x_v ; c^2 L x_u - sigma x_v]
        Y[2 * k] = X[2 * k + 1];
        Y[2 * k + 1] = c2[k] * l - sig[k] * X[2 * k + 1];
      }
    }));
    PetscFunctionReturn(0);
  }

  bool on_edge(PetscInt k) const {
    const PetscInt i = grid_->xs() + k % grid_->xm(), j = grid_->ys() + k / grid_->xm();
    return grid_->is_boundary(i) || grid_->is_boundary_y(j);
  }
  PetscReal sponge(PetscReal x, PetscReal y) const {
    if (sponge_width_ <= 0) return 0;
    const PetscReal dx = std::min(x - grid_->x0(), grid_->x1() - x), dy = std::min(y - grid_->y0(), grid_->y1() - y);
    const PetscReal d = std::max<PetscReal>(0, sponge_width_ - std::min(dx, dy)) / sponge_width_;
    return sigma_max_ * d * d;
  }

  PetscErrorCode assemble(Mat A) override {
    ConstArray c(c_);
    PetscFunctionBeginUser;
    PetscCall(c.error());
    PetscCall(MatZeroEntries(A));
    const PetscReal ihx2 = 1.0 / (grid_->h() * grid_->h()), ihy2 = 1.0 / (grid_->hy() * grid_->hy());
    for (PetscInt k = 0; k < grid_->local_points(); ++k) {
      if (on_edge(k)) continue;
      const PetscInt i = grid_->xs() + k % grid_->xm(), j = grid_->ys() + k / grid_->xm();
      MatStencil row_u{0, j, i, 0}, row_v{0, j, i, 1}, cols[6];
      PetscScalar vals[6];
      const PetscScalar one = 1.0;
      cols[0] = {0, j, i, 1};
      PetscCall(MatSetValuesStencil(A, 1, &row_u, 1, cols, &one, INSERT_VALUES));
      const PetscReal c2 = PetscRealPart(c[k]) * PetscRealPart(c[k]);
      cols[0] = {0, j, i - 1, 0};
      vals[0] = c2 * ihx2;
      cols[1] = {0, j, i + 1, 0};
      vals[1] = c2 * ihx2;
      cols[2] = {0, j - 1, i, 0};
      vals[2] = c2 * ihy2;
      cols[3] = {0, j + 1, i, 0};
      vals[3] = c2 * ihy2;
      cols[4] = {0, j, i, 0};
      vals[4] = -2.0 * c2 * (ihx2 + ihy2);
      cols[5] = {0, j, i, 1};
      vals[5] = -sigma_[k];
      PetscCall(MatSetValuesStencil(A, 1, &row_v, sigma_[k] != 0 ? 6 : 5, cols, vals, INSERT_VALUES));
    }
    PetscCall(MatAssemblyBegin(A, MAT_FINAL_ASSEMBLY));
    PetscCall(MatAssemblyEnd(A, MAT_FINAL_ASSEMBLY));
    PetscFunctionReturn(0);
  }

  // y = dG/dc x
  static PetscErrorCode jp_mult(Mat Jp, Vec x, Vec y) {
    Wave2DModel *m;
    PetscFunctionBeginUser;
    PetscCall(MatShellGetContext(Jp, &m));
    const ParamInfo &pi = m->params_->info(m->c_index_);
    PetscReal dc_scalar = 0;
    if (!m->c_field_) PetscCall(m->params_->scalar(x, m->c_index_, &dc_scalar));
    ConstArray X(x), c(m->c_);
    Array Y(y);
    PetscCall(X.error());
    PetscCall(Y.error());
    PetscCall(c.error());
    for (PetscInt k = 0; k < m->grid_->local_points(); ++k) {
      const PetscReal dc = m->c_field_ ? PetscRealPart(X[pi.local_offset + k]) : dc_scalar;
      Y[2 * k] = 0;
      Y[2 * k + 1] = 2.0 * PetscRealPart(c[k]) * m->lap_[k] * dc;
    }
    PetscFunctionReturn(0);
  }

  // y = (dG/dc)^T x
  static PetscErrorCode jp_mult_transpose(Mat Jp, Vec x, Vec y) {
    Wave2DModel *m;
    PetscFunctionBeginUser;
    PetscCall(MatShellGetContext(Jp, &m));
    {
      ConstArray X(x), c(m->c_);
      PetscCall(X.error());
      PetscCall(c.error());
      for (PetscInt k = 0; k < m->grid_->local_points(); ++k)
        m->gbuf_[k] = 2.0 * PetscRealPart(c[k]) * m->lap_[k] * PetscRealPart(X[2 * k + 1]);
    }
    PetscCall(VecSet(y, 0.0));
    PetscCall(m->params_->add_pointwise(y, m->c_index_, m->gbuf_));
    PetscFunctionReturn(0);
  }

  const Grid *grid_ = nullptr;
  const PointSource *source_ = nullptr;
  DM dm_ = nullptr;
  Parameters *params_ = nullptr;
  PetscBool c_field_ = PETSC_FALSE;
  mutable std::vector<PetscReal> pbuf_;   // perimeter_laps' three rows of z
  bool walls_[4] = {false, false, false, false}; // a wall beyond this block's left, right, lower, upper side
  std::vector<PetscScalar> rec_stage_;    // rhs_sweep's records of the block, to be streamed
  std::vector<PetscReal> zring_;  // the kick's and the RK stage's ring of three rows of z = c^2 v
  PetscInt ic_ = 0, c_index_ = -1;
  PetscReal c_min_ = 0.01, cmax_ = 0, sponge_width_ = 0.15, sigma_max_ = 60.0;
  PetscReal ic_x_ = 0.5, ic_y_ = 0.5, ic_w_ = 0.05;
  OwnedVec c_;
  std::vector<PetscReal> lap_, gbuf_, sigma_, c2m_, two_c_; // L u; work; sponge; c^2 and 2c, 0 on the edges
  std::vector<PetscReal> rows_;                             // stage_adjoint: rings of 3 rows of z and of u
  std::vector<char> edge_;                                  // owned point on the outer edge
  Halo halo_u_, halo_v_, halo_c_;                           // ghosts of u, of lambda_v (adjoint) and of c
  Halo halo_q_;                                             // ghosts of u given alone (stored positions)
  PetscReal ihx2_ = 0, ihy2_ = 0;
};

} // namespace

FLEXIPDE_REGISTER_MODEL("wave2d", Wave2DModel);

} // namespace flexipde
