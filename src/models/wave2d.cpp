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
// dG/dc is a MatShell whose transpose is a pointwise product.
//
// Initial condition (-wave2d_ic zero|pulse): zero (waves from point sources, survey.hpp), or a
// Gaussian exp(-|x - x_c|^2 / w^2) at rest (-wave2d_ic_x, -wave2d_ic_y, -wave2d_ic_width).
//
//   mpiexec -n 2 ./flexipde -model wave2d -task forward -da_grid_x 101 -da_grid_y 101 -wave2d_ic pulse
//   mpiexec -n 2 ./flexipde -model wave2d -task taylor -da_grid_x 41 -da_grid_y 41 -wave2d_c_field 1
//           -wave2d_c 1.0 -true_wave2d_c 1.1 -objective_type receivers -survey_sources_x 0.5 -survey_sources_y 0.3
//           -survey_receivers_spread 0.2,0.8,7 -survey_receivers_y 0.7 -ts_max_time 0.6 -ts_dt 2e-3
//   (one command line)
#include "flexipde/model.hpp"
#include "flexipde/survey.hpp"
#include <cmath>
#include <vector>

namespace flexipde {
namespace {

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
    PetscCall(DMCreateLocalVector(dm_, Uloc_.out()));
    PetscCall(create_operator(dm_));
    const PetscInt n = grid.local_points();
    lap_.assign(n, 0.0);
    gbuf_.assign(n, 0.0);
    sigma_.assign(n, 0.0);
    for (PetscInt k = 0; k < n; ++k) {
      const PetscInt i = grid.xs() + k % grid.xm(), j = grid.ys() + k / grid.xm();
      sigma_[k] = sponge(grid.x(i), grid.y(j));
    }
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
    PetscCall(assemble(A_));
    PetscFunctionReturn(0);
  }

  PetscErrorCode rhs(PetscReal t, Vec U, Vec G) override {
    PetscFunctionBeginUser;
    PetscCall(MatMult(A_, U, G));
    if (source_ && source_->stencil.n) {
      Array g(G);
      PetscCall(g.error());
      for (PetscInt k = 0; k < source_->stencil.n; ++k) {
        const PetscInt il = source_->stencil.local[k];
        if (on_edge(il)) continue;
        g[2 * il + 1] += source_->density(k, t);
      }
    }
    PetscFunctionReturn(0);
  }

  // Records (L u)_k at this state for the shell dG/dc.
  PetscErrorCode rhs_jacobian_p(PetscReal, Vec U, Mat Jp) override {
    PetscFunctionBeginUser;
    PetscCall(DMGlobalToLocal(dm_, U, INSERT_VALUES, Uloc_));
    {
      ConstArray u(Uloc_);
      PetscCall(u.error());
      PetscInt gxs, gys, gxm, gym;
      PetscCall(DMDAGetGhostCorners(dm_, &gxs, &gys, nullptr, &gxm, &gym, nullptr));
      const PetscReal ihx2 = 1.0 / (grid_->h() * grid_->h()), ihy2 = 1.0 / (grid_->hy() * grid_->hy());
      for (PetscInt k = 0; k < grid_->local_points(); ++k) {
        const PetscInt i = grid_->xs() + k % grid_->xm(), j = grid_->ys() + k / grid_->xm();
        if (on_edge(k)) {
          lap_[k] = 0;
          continue;
        }
        auto at = [&](PetscInt ii, PetscInt jj) { return PetscRealPart(u[2 * ((jj - gys) * gxm + (ii - gxs))]); };
        const PetscReal c0 = at(i, j);
        lap_[k] = (at(i - 1, j) - 2 * c0 + at(i + 1, j)) * ihx2 + (at(i, j - 1) - 2 * c0 + at(i, j + 1)) * ihy2;
      }
    }
    PetscCall(MatAssemblyBegin(Jp, MAT_FINAL_ASSEMBLY));
    PetscCall(MatAssemblyEnd(Jp, MAT_FINAL_ASSEMBLY));
    PetscFunctionReturn(0);
  }

  PetscErrorCode spectrum(Spectrum *s) override {
    s->imag_radius = cmax_ * std::sqrt(4.0 / (grid_->h() * grid_->h()) + 4.0 / (grid_->hy() * grid_->hy()));
    s->real_radius = sigma_max_;
    return 0;
  }

  PetscErrorCode initial_condition(Vec p, Vec U0) override {
    PetscFunctionBeginUser;
    PetscCall(set_parameters(p));
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
  PetscInt ic_ = 0, c_index_ = -1;
  PetscReal c_min_ = 0.01, cmax_ = 0, sponge_width_ = 0.15, sigma_max_ = 60.0;
  PetscReal ic_x_ = 0.5, ic_y_ = 0.5, ic_w_ = 0.05;
  OwnedVec c_, Uloc_;
  std::vector<PetscReal> lap_, gbuf_, sigma_;
};

} // namespace

std::unique_ptr<Model> make_wave2d_model() { return std::make_unique<Wave2DModel>(); }

} // namespace flexipde
