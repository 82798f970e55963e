// Survey: Ricker point sources, receivers and the time-integrated receiver misfit (survey.hpp).
#include "flexipde/survey.hpp"
#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <hdf5.h>
#include <petscviewerhdf5.h>
#include <sstream>
#include <unistd.h>

namespace flexipde {

PetscReal Ricker::operator()(PetscReal t) const {
  const PetscReal a = PETSC_PI * f0 * (t - t0), a2 = a * a;
  return amplitude * (1.0 - 2.0 * a2) * std::exp(-a2);
}

namespace {

// w[a] = the Lagrange basis polynomial of node a of x[0, m) at s (the interpolant is sum_a w[a] f(x[a])).
void lagrange_weights(const PetscReal *x, PetscInt m, PetscReal s, PetscReal *w) {
  for (PetscInt a = 0; a < m; ++a) {
    w[a] = 1;
    for (PetscInt b = 0; b < m; ++b)
      if (b != a) w[a] *= (s - x[b]) / (x[a] - x[b]);
  }
}

} // namespace

PetscReal Wavelet::operator()(PetscReal time) const {
  if (t.empty()) return ricker(time);
  const PetscInt n = (PetscInt)t.size(), m = std::min<PetscInt>(4, n);
  if (time < t[0] || time > t[n - 1]) return 0.0;
  // the four samples around time (t[k0 + 1] <= time < t[k0 + 2]), moved inside at the ends
  PetscInt k0 = (PetscInt)(std::upper_bound(t.begin(), t.end(), time) - t.begin()) - 2;
  k0 = std::max<PetscInt>(0, std::min<PetscInt>(k0, n - m));
  PetscReal l[4], sum = 0;
  lagrange_weights(t.data() + k0, m, time, l);
  for (PetscInt a = 0; a < m; ++a) sum += l[a] * w[k0 + a];
  return sum;
}

namespace {

// The 1D weights of position pos: up to 8 (grid index, weight) pairs, indices wrapped on a periodic
// direction and left out beyond a wall.
int line_weights(PetscReal pos, PetscReal origin, PetscReal h, PetscInt n, bool periodic, Interpolation how,
                 PetscInt idx[8], PetscReal w[8]) {
  const PetscReal s = (pos - origin) / h;
  int m = 0;
  auto add = [&](PetscInt i, PetscReal wi) {
    if (wi == 0.0) return;
    if (periodic) i = (i % n + n) % n;
    else if (i < 0 || i >= n) return;
    idx[m] = i, w[m] = wi, ++m;
  };
  if (how == Interpolation::Linear) {
    const PetscInt last = periodic ? n - 1 : n - 2; // left node of the last cell
    PetscInt k = (PetscInt)std::floor(s);
    if (k > last) k = last;
    if (k < 0) k = 0;
    const PetscReal t = s - k;
    add(k, 1 - t);
    add(k + 1, t);
    return m;
  }
  constexpr int r = 4;
  constexpr PetscReal b = 6.31; // Hicks's value for r = 4 and wavenumbers up to pi / 2h (4 points per wavelength)
  const PetscReal k = std::round(s);
  if (std::fabs(s - k) < 1e-12) { // on a grid point: the sinc is a delta there
    add((PetscInt)k, 1.0);
    return m;
  }
  const PetscInt k0 = (PetscInt)std::floor(s);
  for (PetscInt i = k0 - r + 1; i <= k0 + r; ++i) {
    const PetscReal d = i - s, q = d / r;
    const PetscReal sinc = std::sin(PETSC_PI * d) / (PETSC_PI * d);
    add(i, sinc * std::cyl_bessel_i(0.0, b * std::sqrt(std::max<PetscReal>(0, 1 - q * q))) / std::cyl_bessel_i(0.0, b));
  }
  return m;
}

} // namespace

PetscErrorCode point_stencil(const Grid &grid, PetscReal x, PetscReal y, PetscReal z, PointStencil *st,
                             Interpolation how) {
  // A direction the grid lacks has the one index 0 with weight 1, so that the product below is the
  // 1D or 2D weight unchanged.
  PetscInt idx[3][8] = {{0}, {0}, {0}};
  PetscReal w[3][8] = {{1.0}, {1.0}, {1.0}};
  int m[3] = {1, 1, 1};
  const PetscReal pos[3] = {x, y, z};
  PetscFunctionBeginUser;
  st->n = 0;
  for (int d = 0; d < grid.dim(); ++d)
    m[d] = line_weights(pos[d], grid.lower(d), grid.h(d), grid.n(d), grid.periodic(d), how, idx[d], w[d]);
  static_assert(PointStencil::max_points >= 8 * 8 * 8, "PointStencil holds the 3D sinc stencil");
  const PetscInt xs = grid.xs(), ys = grid.ys(), zs = grid.zs(), xm = grid.xm(), ym = grid.ym(), zm = grid.zm();
  for (int c = 0; c < m[2]; ++c)
    for (int b = 0; b < m[1]; ++b)
      for (int a = 0; a < m[0]; ++a) {
        const PetscInt ii = idx[0][a], jj = idx[1][b], kk = idx[2][c];
        if (ii < xs || ii >= xs + xm || jj < ys || jj >= ys + ym || kk < zs || kk >= zs + zm) continue;
        st->local[st->n] = ((kk - zs) * ym + (jj - ys)) * xm + (ii - xs);
        st->weight[st->n] = w[0][a] * w[1][b] * w[2][c];
        ++st->n;
      }
  PetscFunctionReturn(0);
}

// Rows of `cols` finite numbers from a text file (blank lines and # comments skipped), read on rank 0
// and sent to every rank with the outcome, so that all ranks stop together on a bad file: *status 0,
// 1 (the file cannot be read) or 2 (a line without `cols` finite numbers).
static PetscErrorCode read_rows(MPI_Comm comm, const char *file, int cols, std::vector<PetscReal> &vals, PetscInt *status) {
  PetscMPIInt rank;
  PetscInt count = 0;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  *status = 0;
  vals.clear();
  if (rank == 0) {
    std::ifstream in(file);
    if (!in) *status = 1;
    std::string line;
    while (*status == 0 && std::getline(in, line)) {
      if (line.find_first_not_of(" \t\r") == std::string::npos || line[0] == '#') continue;
      std::istringstream ls(line);
      for (int c = 0; c < cols && *status == 0; ++c) {
        PetscReal a;
        if (!(ls >> a) || !std::isfinite(a)) *status = 2;
        else vals.push_back(a);
      }
    }
    count = (PetscInt)vals.size();
  }
  PetscCallMPI(MPI_Bcast(status, 1, MPIU_INT, 0, comm));
  PetscCallMPI(MPI_Bcast(&count, 1, MPIU_INT, 0, comm));
  vals.resize(count);
  PetscCallMPI(MPI_Bcast(vals.data(), (PetscMPIInt)count, MPIU_REAL, 0, comm));
  PetscFunctionReturn(0);
}

// The wavelet's samples from a text file: "t w" per line, times increasing, two samples at least.
PetscErrorCode Survey::read_wavelet(const char *file) {
  std::vector<PetscReal> vals;
  PetscInt status;
  PetscFunctionBeginUser;
  PetscCall(read_rows(comm_, file, 2, vals, &status));
  PetscCheck(status != 1, comm_, PETSC_ERR_FILE_OPEN, "-survey_wavelet_file %s cannot be read", file);
  PetscCheck(status != 2, comm_, PETSC_ERR_FILE_UNEXPECTED, "-survey_wavelet_file %s: every line must hold a time and a value", file);
  const size_t n = vals.size() / 2;
  PetscCheck(n >= 2, comm_, PETSC_ERR_FILE_UNEXPECTED, "-survey_wavelet_file %s: give at least two samples", file);
  wavelet_.t.resize(n), wavelet_.w.resize(n);
  for (size_t k = 0; k < n; ++k) {
    wavelet_.t[k] = vals[2 * k], wavelet_.w[k] = vals[2 * k + 1];
    PetscCheck(k == 0 || wavelet_.t[k] > wavelet_.t[k - 1], comm_, PETSC_ERR_FILE_UNEXPECTED,
               "-survey_wavelet_file %s: the times must increase (sample %zu)", file, k + 1);
  }
  PetscFunctionReturn(0);
}

// Values for the second or third coordinate: one per point, or one for all.
// In 2D and 3D they are required: a silent default on the edge would put the points on the Dirichlet wall.
static PetscErrorCode expand(MPI_Comm comm, PetscInt dim, const char *what, std::vector<PetscReal> &y, size_t n) {
  PetscFunctionBeginUser;
  PetscCheck(n == 0 || !y.empty(), comm, PETSC_ERR_ARG_WRONG,
             "%" PetscInt_FMT "D survey: give %s (one value, or one per point)", dim, what);
  if (y.size() == 1) y.assign(n, y[0]);
  PetscCheck(y.size() == n, comm, PETSC_ERR_ARG_SIZ, "%s: give one value or one per point (%zu), got %zu", what, n,
             y.size());
  PetscFunctionReturn(0);
}

PetscErrorCode Survey::read_positions() {
  const PetscInt dim = grid_->dim();
  PetscBool set_sx = PETSC_FALSE, set_sy = PETSC_FALSE, set_sz = PETSC_FALSE, set_rx = PETSC_FALSE, set_ry = PETSC_FALSE,
            set_rz = PETSC_FALSE, set_spread = PETSC_FALSE, set_file = PETSC_FALSE, set_delay = PETSC_FALSE;
  char rec_file[PETSC_MAX_PATH_LEN] = "", wavelet_file[PETSC_MAX_PATH_LEN] = "";
  PetscBool set_wavelet = PETSC_FALSE;
  PetscReal spread[3] = {0, 0, 0};
  PetscInt nspread = 3;
  PetscFunctionBeginUser;
  PetscOptionsBegin(comm_, nullptr, "Survey: point sources, receivers, observed data", "Survey");
  // A list option -name v1,v2,... (up to 1024 values).
  auto read_list = [&](MPI_Comm, const char *name, const char *help, std::vector<PetscReal> &out,
                       PetscBool *set) -> PetscErrorCode {
    PetscReal buf[1024] = {0}; // -help shows the first entry
    PetscInt n = 1024;
    PetscFunctionBeginUser;
    PetscCall(PetscOptionsRealArray(name, help, "Survey", buf, &n, set));
    if (*set) out.assign(buf, buf + n);
    PetscFunctionReturn(0);
  };
  PetscCall(read_list(comm_, "-survey_sources_x", "Source positions x, one shot each (none: one shot without source)",
                      src_x_, &set_sx));
  if (dim >= 2)
    PetscCall(read_list(comm_, "-survey_sources_y", "Source positions y (one value, or one per source)", src_y_, &set_sy));
  if (dim == 3)
    PetscCall(read_list(comm_, "-survey_sources_z", "Source positions z (one value, or one per source)", src_z_, &set_sz));
  PetscCall(PetscOptionsReal("-survey_ricker_f0", "Peak frequency of the Ricker wavelet", "Survey", wavelet_.ricker.f0,
                             &wavelet_.ricker.f0, nullptr));
  PetscCall(PetscOptionsReal("-survey_ricker_delay", "Delay t0 of the Ricker wavelet (default 1.2/f0)", "Survey",
                             1.2 / wavelet_.ricker.f0, &wavelet_.ricker.t0, &set_delay));
  PetscCall(PetscOptionsReal("-survey_ricker_amplitude", "Amplitude of the Ricker wavelet", "Survey",
                             wavelet_.ricker.amplitude, &wavelet_.ricker.amplitude, nullptr));
  {
    const char *kinds[] = {"linear", "sinc"};
    PetscInt kind = (PetscInt)interpolation_;
    PetscCall(PetscOptionsEList("-survey_interpolation",
                                "Sources and receivers between grid points: linear (2, 4 or 8 nearest points) or sinc "
                                "(Kaiser-windowed, 8 points per direction)",
                                "Survey", kinds, 2, kinds[kind], &kind, nullptr));
    interpolation_ = (Interpolation)kind;
  }
  PetscCall(PetscOptionsString("-survey_wavelet_file", "Source wavelet from a text file, one \"t w(t)\" pair per line "
                               "(times increasing; 0 outside them), instead of the Ricker wavelet",
                               "Survey", wavelet_file, wavelet_file, sizeof(wavelet_file), &set_wavelet));
  PetscCall(read_list(comm_, "-survey_receivers_x", "Receiver positions x", rec_x_, &set_rx));
  PetscCall(PetscOptionsRealArray("-survey_receivers_spread", "a,b,n: n receivers evenly spaced in x from a to b",
                                  "Survey", spread, &nspread, &set_spread));
  if (dim >= 2)
    PetscCall(read_list(comm_, "-survey_receivers_y", "Receiver positions y (one value, or one per receiver)", rec_y_,
                        &set_ry));
  if (dim == 3)
    PetscCall(read_list(comm_, "-survey_receivers_z", "Receiver positions z (one value, or one per receiver)", rec_z_,
                        &set_rz));
  PetscCall(PetscOptionsString("-survey_receivers_file", "Text file of receivers, one per line: x (1D), x y (2D) or x y z (3D)",
                               "Survey", rec_file, rec_file, sizeof(rec_file), &set_file));
  PetscCall(PetscOptionsString("-survey_data_file", "Observed traces (HDF5, as written by -survey_data_write)",
                               "Survey", data_file_, data_file_, sizeof(data_file_), nullptr));
  PetscCall(PetscOptionsString("-survey_data_write", "Write the synthetic traces of the true model to this HDF5 file",
                               "Survey", write_file_, write_file_, sizeof(write_file_), nullptr));
  PetscOptionsEnd();
  PetscCheck(wavelet_.ricker.f0 > 0, comm_, PETSC_ERR_ARG_OUTOFRANGE, "-survey_ricker_f0 must be positive, got %g",
             (double)wavelet_.ricker.f0);
  if (!set_delay) wavelet_.ricker.t0 = 1.2 / wavelet_.ricker.f0;
  PetscCheck((set_rx ? 1 : 0) + (set_spread ? 1 : 0) + (set_file ? 1 : 0) == 1, comm_, PETSC_ERR_ARG_WRONG,
             "-objective_type receivers needs exactly one of -survey_receivers_x, -survey_receivers_spread, "
             "-survey_receivers_file");
  if (set_spread) {
    PetscCheck(nspread == 3 && spread[2] >= 1 && spread[2] == std::floor(spread[2]), comm_, PETSC_ERR_ARG_WRONG,
               "-survey_receivers_spread takes a,b,n with a whole n >= 1");
    const PetscInt n = (PetscInt)spread[2];
    rec_x_.resize(n);
    for (PetscInt k = 0; k < n; ++k) rec_x_[k] = n == 1 ? spread[0] : spread[0] + (spread[1] - spread[0]) * k / (n - 1);
  }
  if (set_file) {
    std::vector<PetscReal> vals;
    const int cols = (int)dim;
    PetscInt status;
    PetscCall(read_rows(comm_, rec_file, cols, vals, &status));
    PetscCheck(status != 1, comm_, PETSC_ERR_FILE_OPEN, "-survey_receivers_file %s cannot be read", rec_file);
    PetscCheck(status != 2, comm_, PETSC_ERR_FILE_UNEXPECTED,
               "-survey_receivers_file %s: every line must hold %s", rec_file, dim == 3 ? "x y z" : dim == 2 ? "x y" : "x");
    const size_t count = vals.size() / cols;
    rec_x_.resize(count);
    rec_y_.resize(dim >= 2 ? count : 0);
    rec_z_.resize(dim == 3 ? count : 0);
    for (size_t k = 0; k < count; ++k) {
      rec_x_[k] = vals[cols * k];
      if (dim >= 2) rec_y_[k] = vals[cols * k + 1];
      if (dim == 3) rec_z_[k] = vals[cols * k + 2];
    }
  }
  if (set_wavelet) PetscCall(read_wavelet(wavelet_file));
  PetscCheck(!rec_x_.empty(), comm_, PETSC_ERR_ARG_WRONG, "The survey has no receivers");
  if (dim >= 2) {
    PetscCall(expand(comm_, dim, "-survey_receivers_y", rec_y_, rec_x_.size()));
    PetscCall(expand(comm_, dim, "-survey_sources_y", src_y_, src_x_.size()));
  } else {
    rec_y_.assign(rec_x_.size(), 0.0);
    src_y_.assign(src_x_.size(), 0.0);
  }
  if (dim == 3) {
    PetscCall(expand(comm_, dim, "-survey_receivers_z", rec_z_, rec_x_.size()));
    PetscCall(expand(comm_, dim, "-survey_sources_z", src_z_, src_x_.size()));
  } else {
    rec_z_.assign(rec_x_.size(), 0.0);
    src_z_.assign(src_x_.size(), 0.0);
  }
  const PetscReal tol = 1e-12 * (grid_->x1() - grid_->x0());
  auto inside = [&](PetscReal x, PetscReal y, PetscReal z) {
    return x >= grid_->x0() - tol && x <= grid_->x1() + tol &&
           (dim < 2 || (y >= grid_->y0() - tol && y <= grid_->y1() + tol)) &&
           (dim < 3 || (z >= grid_->z0() - tol && z <= grid_->z1() + tol));
  };
  auto check = [&](const char *what, const std::vector<PetscReal> &x, const std::vector<PetscReal> &y,
                   const std::vector<PetscReal> &z) -> PetscErrorCode {
    PetscFunctionBeginUser;
    for (size_t k = 0; k < x.size(); ++k) {
      if (dim == 3)
        PetscCheck(inside(x[k], y[k], z[k]), comm_, PETSC_ERR_ARG_OUTOFRANGE,
                   "%s %zu at (x, y, z) = (%g, %g, %g) is outside the domain [%g, %g] x [%g, %g] x [%g, %g]", what, k,
                   (double)x[k], (double)y[k], (double)z[k], (double)grid_->x0(), (double)grid_->x1(), (double)grid_->y0(),
                   (double)grid_->y1(), (double)grid_->z0(), (double)grid_->z1());
      else if (dim == 2)
        PetscCheck(inside(x[k], y[k], 0), comm_, PETSC_ERR_ARG_OUTOFRANGE,
                   "%s %zu at (x, y) = (%g, %g) is outside the domain [%g, %g] x [%g, %g]", what, k, (double)x[k],
                   (double)y[k], (double)grid_->x0(), (double)grid_->x1(), (double)grid_->y0(), (double)grid_->y1());
      else
        PetscCheck(inside(x[k], 0, 0), comm_, PETSC_ERR_ARG_OUTOFRANGE, "%s %zu at x = %g is outside the domain [%g, %g]",
                   what, k, (double)x[k], (double)grid_->x0(), (double)grid_->x1());
    }
    PetscFunctionReturn(0);
  };
  PetscCall(check("Receiver", rec_x_, rec_y_, rec_z_));
  PetscCall(check("Source", src_x_, src_y_, src_z_));
  PetscFunctionReturn(0);
}

PetscErrorCode Survey::assemble_sampling(PetscInt per_point, Vec like, Mat *R) const {
  PetscInt nloc, rstart;
  const PetscInt nrec = receivers();
  PetscFunctionBeginUser;
  PetscCall(VecGetLocalSize(like, &nloc));
  PetscCall(VecGetOwnershipRange(like, &rstart, nullptr));
  PetscCall(MatCreate(comm_, R));
  PetscCall(MatSetSizes(*R, rank_ == 0 ? nrec : 0, nloc, nrec, PETSC_DETERMINE));
  PetscCall(MatSetType(*R, MATAIJ));
  PetscInt per_row = 1; // the stencil's points: 2 (linear) or 8 (sinc) per direction
  for (PetscInt d = 0; d < grid_->dim(); ++d) per_row *= interpolation_ == Interpolation::Sinc ? 8 : 2;
  PetscCall(MatSeqAIJSetPreallocation(*R, per_row, nullptr));
  PetscCall(MatMPIAIJSetPreallocation(*R, per_row, nullptr, per_row, nullptr));
  PetscCall(MatSetOption(*R, MAT_NEW_NONZERO_ALLOCATION_ERR, PETSC_FALSE));
  for (PetscInt r = 0; r < nrec; ++r) {
    PointStencil st;
    PetscCall(point_stencil(*grid_, rec_x_[r], rec_y_[r], rec_z_[r], &st, interpolation_));
    for (PetscInt k = 0; k < st.n; ++k)
      PetscCall(MatSetValue(*R, r, rstart + st.local[k] * per_point + component_, st.weight[k], ADD_VALUES));
  }
  PetscCall(MatAssemblyBegin(*R, MAT_FINAL_ASSEMBLY));
  PetscCall(MatAssemblyEnd(*R, MAT_FINAL_ASSEMBLY));
  PetscFunctionReturn(0);
}

PetscErrorCode Survey::build_receiver_matrix(DM state_dm) {
  OwnedVec U;
  PetscFunctionBeginUser;
  PetscCall(DMCreateGlobalVector(state_dm, U.out()));
  PetscCall(assemble_sampling(dof_, U, R_.out()));
  PetscCall(MatCreateVecs(R_, nullptr, y_.out()));
  PetscCall(VecDuplicate(y_, dvec_.out()));
  PetscFunctionReturn(0);
}

PetscErrorCode Survey::setup(const Grid &grid, Model &model, DM state_dm, PetscInt component, PetscInt dof) {
  PetscFunctionBeginUser;
  grid_ = &grid;
  model_ = &model;
  comm_ = grid.comm();
  component_ = component;
  dof_ = dof;
  PetscCallMPI(MPI_Comm_rank(comm_, &rank_));
  PetscCall(read_positions());
  PetscCheck(src_x_.empty() || model.accepts_point_source(), comm_, PETSC_ERR_SUP,
             "Model %s takes no point sources (-survey_sources_x)", model.name());
  nshots_ = std::max<PetscInt>(1, (PetscInt)src_x_.size());
  sources_.resize(src_x_.size());
  for (size_t s = 0; s < src_x_.size(); ++s) {
    PetscCall(point_stencil(grid, src_x_[s], src_y_[s], src_z_[s], &sources_[s].stencil, interpolation_));
    sources_[s].wavelet = wavelet_;
    sources_[s].cell_volume = grid.cell_volume();
  }
  PetscCall(build_receiver_matrix(state_dm));
  PetscCall(select_shot(0));
  PetscFunctionReturn(0);
}

PetscErrorCode Survey::select_shot(PetscInt s) {
  PetscFunctionBeginUser;
  PetscCheck(s >= 0 && s < nshots_, comm_, PETSC_ERR_ARG_OUTOFRANGE, "Shot %" PetscInt_FMT " of %" PetscInt_FMT, s,
             nshots_);
  shot_ = s;
  if (!sources_.empty()) PetscCall(model_->set_point_source(&sources_[s]));
  PetscFunctionReturn(0);
}

// ---- recording synthetic data ----

PetscErrorCode Survey::begin_recording(PetscReal sample_dt, PetscReal final_time) {
  PetscFunctionBeginUser;
  sample_dt_ = sample_dt;
  nt_ = (PetscInt)std::llround(final_time / sample_dt) + 1;
  traces_.assign(rank_ == 0 ? (size_t)(nshots_ * receivers() * nt_) : 0, 0.0);
  recorded_.assign((size_t)(nshots_ * nt_), 0);
  recording_ = true;
  PetscFunctionReturn(0);
}

// Sample k of the current shot from y_ (rank 0), when t is a sample time.
static bool sample_index(PetscReal t, PetscReal dt, PetscInt nt, PetscInt *k) {
  const PetscReal s = t / dt;
  const PetscInt kk = (PetscInt)std::llround(s);
  if (std::fabs(s - kk) > 1e-8 || kk < 0 || kk >= nt) return false;
  *k = kk;
  return true;
}

PetscErrorCode Survey::record_initial(Vec U0) {
  PetscFunctionBeginUser;
  PetscCall(MatMult(R_, U0, y_));
  if (rank_ == 0) {
    ConstArray y(y_);
    PetscCall(y.error());
    for (PetscInt r = 0; r < receivers(); ++r) traces_[(shot_ * receivers() + r) * nt_] = PetscRealPart(y[r]);
  }
  recorded_[shot_ * nt_] = 1;
  PetscFunctionReturn(0);
}

PetscErrorCode Survey::end_recording() {
  PetscFunctionBeginUser;
  recording_ = false;
  const bool all = end_ < 0;
  for (PetscInt s = first_; s < (all ? nshots_ : end_); ++s)
    for (PetscInt k = 0; k < nt_; ++k)
      PetscCheck(recorded_[s * nt_ + k], comm_, PETSC_ERR_PLIB,
                 "Synthetic data: the integrator never visited t = %g (sample %" PetscInt_FMT "); record with a fixed step "
                 "of -ts_type rk or cn",
                 (double)(k * sample_dt_), k);
  if (all && write_file_[0]) PetscCall(write_data(write_file_));
  PetscFunctionReturn(0);
}

// x (n samples at spacing dt) through the causal order-4 Butterworth low-pass at f_c, in place: two
// second-order sections (quality factors 1/(2 cos(pi/8)) and 1/(2 cos(3 pi/8))), bilinear transform
// with the cutoff prewarped. Causal, so that filtered data up to t depend on the data up to t alone,
// as the response to the filtered source does.
static void low_pass(PetscReal *x, PetscInt n, PetscReal dt, PetscReal f_c) {
  const double w0 = 2 * M_PI * f_c * dt, cw = std::cos(w0), sw = std::sin(w0);
  for (double q : {1 / (2 * std::cos(M_PI / 8)), 1 / (2 * std::cos(3 * M_PI / 8))}) {
    const double alpha = sw / (2 * q), a0 = 1 + alpha;
    const double b0 = (1 - cw) / 2 / a0, b1 = (1 - cw) / a0, b2 = b0, a1 = -2 * cw / a0, a2 = (1 - alpha) / a0;
    double x1 = 0, x2 = 0, y1 = 0, y2 = 0;
    for (PetscInt k = 0; k < n; ++k) {
      const double y = b0 * x[k] + b1 * x1 + b2 * x2 - a1 * y1 - a2 * y2;
      x2 = x1, x1 = x[k], y2 = y1, y1 = y;
      x[k] = y;
    }
  }
}

PetscErrorCode Survey::set_band(PetscReal f_c) {
  PetscFunctionBeginUser;
  PetscCheck(nt_ > 0 && sample_dt_ > 0, comm_, PETSC_ERR_ORDER, "Survey: a frequency band needs the data first");
  if (!banded_) observed_ = traces_, source_wavelet_ = wavelet_, banded_ = true;
  traces_ = observed_;
  Wavelet w = source_wavelet_;
  if (f_c > 0) {
    PetscCheck(f_c < 0.5 / sample_dt_, comm_, PETSC_ERR_ARG_OUTOFRANGE,
               "Frequency band up to %g: above the data's Nyquist frequency %g", (double)f_c, (double)(0.5 / sample_dt_));
    const PetscInt n = nt_;
    for (size_t k = 0; k + n <= traces_.size(); k += n) low_pass(traces_.data() + k, n, sample_dt_, f_c);
    w.t.resize(n), w.w.resize(n);
    for (PetscInt k = 0; k < n; ++k) w.t[k] = k * sample_dt_, w.w[k] = source_wavelet_(k * sample_dt_);
    low_pass(w.w.data(), n, sample_dt_, f_c);
  }
  wavelet_ = w;
  for (auto &s : sources_) s.wavelet = w;
  PetscFunctionReturn(0);
}

PetscErrorCode Survey::gather_recording(const Survey &group) {
  const PetscInt per_shot = receivers() * group.nt_;
  std::vector<PetscReal> mine((size_t)(nshots_ * per_shot), 0.0);
  PetscFunctionBeginUser;
  sample_dt_ = group.sample_dt_, nt_ = group.nt_;
  if (group.rank_ == 0)
    for (PetscInt k = group.first_ * per_shot; k < group.end_ * per_shot; ++k) mine[k] = group.traces_[k];
  traces_.assign(rank_ == 0 ? mine.size() : 0, 0.0);
  PetscCallMPI(MPI_Reduce(mine.data(), rank_ == 0 ? traces_.data() : nullptr, (int)mine.size(), MPIU_REAL, MPI_SUM, 0, comm_));
  if (write_file_[0]) PetscCall(write_data(write_file_));
  PetscFunctionReturn(0);
}

// ---- data file ----

PetscErrorCode Survey::write_data(const char *file) const {
  OwnedViewer v;
  OwnedVec tr;
  const PetscInt n = nshots_ * receivers() * nt_, dim = grid_->dim(), nrec = receivers();
  PetscFunctionBeginUser;
  PetscCall(PetscViewerHDF5Open(comm_, file, FILE_MODE_WRITE, v.out()));
  PetscCall(PetscViewerHDF5PushGroup(v, "/survey"));
  // vals on rank 0 (m entries; the traces live on rank 0 only)
  auto series = [&](const char *name, const std::vector<PetscReal> &vals, PetscInt m) -> PetscErrorCode {
    OwnedVec s;
    PetscFunctionBeginUser;
    PetscCall(VecCreateMPI(comm_, rank_ == 0 ? m : 0, m, s.out()));
    if (rank_ == 0) {
      Array a(s);
      PetscCall(a.error());
      for (PetscInt i = 0; i < m; ++i) a[i] = vals[i];
    }
    PetscCall(PetscObjectSetName((PetscObject)s.get(), name));
    PetscCall(VecView(s, v));
    PetscFunctionReturn(0);
  };
  PetscCall(series("traces", traces_, n));
  PetscCall(series("receivers_x", rec_x_, nrec));
  if (!src_x_.empty()) PetscCall(series("sources_x", src_x_, (PetscInt)src_x_.size()));
  if (dim >= 2) {
    PetscCall(series("receivers_y", rec_y_, nrec));
    if (!src_y_.empty()) PetscCall(series("sources_y", src_y_, (PetscInt)src_y_.size()));
  }
  if (dim == 3) {
    PetscCall(series("receivers_z", rec_z_, nrec));
    if (!src_z_.empty()) PetscCall(series("sources_z", src_z_, (PetscInt)src_z_.size()));
  }
  PetscCall(PetscViewerHDF5WriteAttribute(v, "traces", "nshots", PETSC_INT, &nshots_));
  PetscCall(PetscViewerHDF5WriteAttribute(v, "traces", "nrec", PETSC_INT, &nrec));
  PetscCall(PetscViewerHDF5WriteAttribute(v, "traces", "nt", PETSC_INT, &nt_));
  PetscCall(PetscViewerHDF5WriteAttribute(v, "traces", "dim", PETSC_INT, &dim));
  PetscCall(PetscViewerHDF5WriteAttribute(v, "traces", "sample_dt", PETSC_REAL, &sample_dt_));
  PetscCall(PetscViewerHDF5PopGroup(v));
  PetscFunctionReturn(0);
}

// The file is read on rank 0 with the plain HDF5 library (no MPI-IO: an error must be able to end
// the run at once), everything it holds is broadcast, and every check is made on all ranks alike.
namespace {
struct DataFileContents {
  PetscInt status = 0; // 0 ok, 1 missing/unreadable, 2 not HDF5, 3 no /survey/traces, 4 a dataset or attribute missing
  PetscInt nshots = 0, nrec = 0, nt = 0, dim = 0;
  PetscReal dt = 0;
  std::vector<PetscReal> rec_x, rec_y, rec_z, src_x, src_y, src_z, traces;
};

bool read_dataset(hid_t file, const char *path, std::vector<PetscReal> &out) {
  if (H5Lexists(file, path, H5P_DEFAULT) <= 0) return false;
  hid_t d = H5Dopen2(file, path, H5P_DEFAULT);
  if (d < 0) return false;
  hid_t sp = H5Dget_space(d);
  const hssize_t n = H5Sget_simple_extent_npoints(sp);
  out.assign(n > 0 ? (size_t)n : 0, 0.0);
  herr_t e = n > 0 ? H5Dread(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data()) : 0;
  H5Sclose(sp);
  H5Dclose(d);
  return e >= 0;
}

template <class T> bool read_attribute(hid_t obj, const char *name, hid_t type, T *value) {
  if (H5Aexists(obj, name) <= 0) return false;
  hid_t a = H5Aopen(obj, name, H5P_DEFAULT);
  herr_t e = H5Aread(a, type, value);
  H5Aclose(a);
  return e >= 0;
}

// dim: the scene's; the y and z datasets are read when the file's dim is the same (else the caller
// reports the mismatch of dimensions, not a missing dataset).
void read_on_rank0(const char *f, PetscInt dim, bool with_sources, DataFileContents &c) {
  if (access(f, R_OK) != 0) {
    c.status = 1;
    return;
  }
  H5E_auto2_t func;
  void *data;
  H5Eget_auto2(H5E_DEFAULT, &func, &data);
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr); // our messages, not HDF5's error stack
  if (H5Fis_hdf5(f) <= 0) c.status = 2;
  hid_t file = c.status ? -1 : H5Fopen(f, H5F_ACC_RDONLY, H5P_DEFAULT);
  if (!c.status && file < 0) c.status = 2;
  if (!c.status && (H5Lexists(file, "/survey", H5P_DEFAULT) <= 0 || H5Lexists(file, "/survey/traces", H5P_DEFAULT) <= 0))
    c.status = 3;
  if (!c.status) {
    hid_t d = H5Dopen2(file, "/survey/traces", H5P_DEFAULT);
    long long ns = 0, nr = 0, nt = 0, dim = 0;
    bool ok = d >= 0 && read_attribute(d, "nshots", H5T_NATIVE_LLONG, &ns) && read_attribute(d, "nrec", H5T_NATIVE_LLONG, &nr) &&
              read_attribute(d, "nt", H5T_NATIVE_LLONG, &nt) && read_attribute(d, "dim", H5T_NATIVE_LLONG, &dim) &&
              read_attribute(d, "sample_dt", H5T_NATIVE_DOUBLE, &c.dt);
    if (d >= 0) H5Dclose(d);
    c.nshots = (PetscInt)ns, c.nrec = (PetscInt)nr, c.nt = (PetscInt)nt, c.dim = (PetscInt)dim;
    ok = ok && read_dataset(file, "/survey/traces", c.traces) && read_dataset(file, "/survey/receivers_x", c.rec_x);
    if (ok && with_sources) ok = read_dataset(file, "/survey/sources_x", c.src_x);
    if (ok && dim >= 2 && c.dim == dim) {
      ok = read_dataset(file, "/survey/receivers_y", c.rec_y);
      if (ok && with_sources) ok = read_dataset(file, "/survey/sources_y", c.src_y);
    }
    if (ok && dim == 3 && c.dim == dim) {
      ok = read_dataset(file, "/survey/receivers_z", c.rec_z);
      if (ok && with_sources) ok = read_dataset(file, "/survey/sources_z", c.src_z);
    }
    if (!ok) c.status = 4;
  }
  if (file >= 0) H5Fclose(file);
  H5Eset_auto2(H5E_DEFAULT, func, data);
}

PetscErrorCode bcast(MPI_Comm comm, std::vector<PetscReal> &v) {
  PetscInt n = (PetscInt)v.size();
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Bcast(&n, 1, MPIU_INT, 0, comm));
  v.resize(n);
  PetscCallMPI(MPI_Bcast(v.data(), n, MPIU_REAL, 0, comm));
  PetscFunctionReturn(0);
}
} // namespace

PetscErrorCode Survey::read_data(PetscReal final_time, PetscBool *read) {
  const char *f = data_file_;
  DataFileContents c;
  PetscFunctionBeginUser;
  *read = PETSC_FALSE;
  if (!f[0]) PetscFunctionReturn(0);
  if (rank_ == 0) read_on_rank0(f, grid_->dim(), !src_x_.empty(), c);
  PetscInt head[5] = {c.status, c.nshots, c.nrec, c.nt, c.dim};
  PetscCallMPI(MPI_Bcast(head, 5, MPIU_INT, 0, comm_));
  PetscCallMPI(MPI_Bcast(&c.dt, 1, MPIU_REAL, 0, comm_));
  c.status = head[0], c.nshots = head[1], c.nrec = head[2], c.nt = head[3], c.dim = head[4];
  PetscCheck(c.status != 1, comm_, PETSC_ERR_FILE_OPEN, "-survey_data_file %s does not exist or cannot be read", f);
  PetscCheck(c.status != 2, comm_, PETSC_ERR_FILE_UNEXPECTED,
             "-survey_data_file %s is not an HDF5 file (write one with -survey_data_write)", f);
  PetscCheck(c.status != 3, comm_, PETSC_ERR_FILE_UNEXPECTED, "-survey_data_file %s holds no /survey/traces dataset", f);
  PetscCheck(c.status != 4, comm_, PETSC_ERR_FILE_UNEXPECTED,
             "-survey_data_file %s lacks a survey dataset or attribute (nshots, nrec, nt, dim, sample_dt, receivers_x, "
             "sources_x; receivers_y, sources_y in 2D and 3D; receivers_z, sources_z in 3D)",
             f);
  PetscCheck(c.dim == grid_->dim(), comm_, PETSC_ERR_FILE_UNEXPECTED,
             "-survey_data_file %s holds %" PetscInt_FMT "D data, the scene is %" PetscInt_FMT "D", f, c.dim, grid_->dim());
  PetscCheck(c.nshots == nshots_ && c.nrec == receivers(), comm_, PETSC_ERR_FILE_UNEXPECTED,
             "-survey_data_file %s holds %" PetscInt_FMT " shots x %" PetscInt_FMT " receivers, the survey has %" PetscInt_FMT
             " x %" PetscInt_FMT,
             f, c.nshots, c.nrec, nshots_, receivers());
  PetscCheck(c.nt >= 2 && c.dt > 0, comm_, PETSC_ERR_FILE_UNEXPECTED,
             "-survey_data_file %s: bad sampling (nt %" PetscInt_FMT ", sample_dt %g)", f, c.nt, (double)c.dt);
  PetscCheck((c.nt - 1) * c.dt >= final_time * (1 - 1e-10), comm_, PETSC_ERR_FILE_UNEXPECTED,
             "-survey_data_file %s covers t <= %g only, the run goes to T = %g", f, (double)((c.nt - 1) * c.dt),
             (double)final_time);
  const PetscInt dim = grid_->dim();
  // a coordinate the scene lacks was not read: its datasets are empty
  auto sized = [&](const std::vector<PetscReal> &v, PetscInt d, size_t n) { return dim < d || v.size() == n; };
  PetscInt sizes_ok = rank_ == 0 ? (PetscInt)(c.traces.size() == (size_t)(c.nshots * c.nrec * c.nt) &&
                                              c.rec_x.size() == (size_t)c.nrec && c.src_x.size() == src_x_.size() &&
                                              sized(c.rec_y, 2, c.nrec) && sized(c.src_y, 2, src_x_.size()) &&
                                              sized(c.rec_z, 3, c.nrec) && sized(c.src_z, 3, src_x_.size()))
                                 : 1;
  PetscCallMPI(MPI_Bcast(&sizes_ok, 1, MPIU_INT, 0, comm_));
  PetscCheck(sizes_ok, comm_, PETSC_ERR_FILE_UNEXPECTED,
             "-survey_data_file %s: the datasets' sizes do not match its attributes (nshots %" PetscInt_FMT ", nrec %" PetscInt_FMT
             ", nt %" PetscInt_FMT ")",
             f, c.nshots, c.nrec, c.nt);
  PetscCall(bcast(comm_, c.rec_x));
  PetscCall(bcast(comm_, c.rec_y));
  PetscCall(bcast(comm_, c.src_x));
  PetscCall(bcast(comm_, c.src_y));
  PetscCall(bcast(comm_, c.rec_z));
  PetscCall(bcast(comm_, c.src_z));
  const PetscReal tol = 1e-9 * (grid_->x1() - grid_->x0());
  const char *other = dim == 3 ? " (or y or z differs)" : dim == 2 ? " (or y differs)" : "";
  using Coords = std::vector<PetscReal>;
  auto same = [&](const Coords &fx, const Coords &fy, const Coords &fz, const Coords &x, const Coords &y, const Coords &z,
                  size_t k) {
    return std::fabs(fx[k] - x[k]) <= tol && (dim < 2 || std::fabs(fy[k] - y[k]) <= tol) &&
           (dim < 3 || std::fabs(fz[k] - z[k]) <= tol);
  };
  for (PetscInt r = 0; r < c.nrec; ++r)
    PetscCheck(same(c.rec_x, c.rec_y, c.rec_z, rec_x_, rec_y_, rec_z_, (size_t)r), comm_, PETSC_ERR_FILE_UNEXPECTED,
               "-survey_data_file %s: receiver %" PetscInt_FMT " was recorded at x = %g, the survey puts it at x = %g%s", f,
               r, (double)c.rec_x[r], (double)rec_x_[r], other);
  for (size_t k = 0; k < src_x_.size(); ++k)
    PetscCheck(same(c.src_x, c.src_y, c.src_z, src_x_, src_y_, src_z_, k), comm_, PETSC_ERR_FILE_UNEXPECTED,
               "-survey_data_file %s: shot %zu was fired at x = %g, the survey has x = %g%s", f, k, (double)c.src_x[k],
               (double)src_x_[k], other);
  PetscInt bad = -1; // the traces stay on rank 0
  if (rank_ == 0)
    for (size_t i = 0; i < c.traces.size() && bad < 0; ++i)
      if (!std::isfinite((double)c.traces[i])) bad = (PetscInt)i;
  PetscCallMPI(MPI_Bcast(&bad, 1, MPIU_INT, 0, comm_));
  PetscCheck(bad < 0, comm_, PETSC_ERR_FILE_UNEXPECTED,
             "-survey_data_file %s holds NaN/Inf: shot %" PetscInt_FMT ", receiver %" PetscInt_FMT ", sample %" PetscInt_FMT, f,
             bad / (c.nrec * c.nt), (bad / c.nt) % c.nrec, bad % c.nt);
  traces_ = std::move(c.traces);
  nt_ = c.nt;
  sample_dt_ = c.dt;
  *read = PETSC_TRUE;
  PetscFunctionReturn(0);
}

// ---- the misfit ----

// Cubic Lagrange interpolation in time through the four samples around t (fewer when nt < 4).
PetscErrorCode Survey::data_at(PetscReal t) {
  PetscFunctionBeginUser;
  if (rank_ != 0) PetscFunctionReturn(0);
  Array d(dvec_);
  PetscCall(d.error());
  const PetscReal s = t / sample_dt_;
  const PetscInt m = std::min<PetscInt>(4, nt_);
  PetscInt k0 = (PetscInt)std::floor(s) - (m == 4 ? 1 : 0);
  k0 = std::max<PetscInt>(0, std::min<PetscInt>(k0, nt_ - m));
  const PetscReal nodes[4] = {(PetscReal)k0, (PetscReal)k0 + 1, (PetscReal)k0 + 2, (PetscReal)k0 + 3};
  PetscReal w[4];
  lagrange_weights(nodes, m, s, w);
  for (PetscInt r = 0; r < receivers(); ++r) {
    const PetscReal *tr = traces_.data() + (shot_ * receivers() + r) * nt_;
    PetscReal v = 0;
    for (PetscInt a = 0; a < m; ++a) v += w[a] * tr[k0 + a];
    d[r] = v;
  }
  PetscFunctionReturn(0);
}

PetscErrorCode Survey::residual(PetscReal t, Vec U) {
  PetscFunctionBeginUser;
  PetscCheck(nt_ > 0, comm_, PETSC_ERR_ORDER, "The survey has no data: record synthetic data or give -survey_data_file");
  PetscCall(sample(U));
  PetscCall(data_at(t));
  PetscCall(VecAXPY(y_, -1.0, dvec_));
  PetscFunctionReturn(0);
}

PetscErrorCode Survey::sample(Vec U) {
  PetscFunctionBeginUser;
  PetscInt n, nstate;
  PetscCall(VecGetLocalSize(U, &n));
  PetscCall(MatGetLocalSize(R_, nullptr, &nstate));
  if (n == nstate) PetscCall(MatMult(R_, U, y_));
  else {
    if (!R_positions_) PetscCall(positions_sampling(U));
    PetscCall(MatMult(R_positions_, U, y_));
  }
  PetscFunctionReturn(0);
}

// R_positions_ for vectors shaped as Q: the positions alone, n / points components per grid point,
// the recorded one among them.
PetscErrorCode Survey::positions_sampling(Vec Q) {
  PetscInt n, nstate;
  PetscFunctionBeginUser;
  PetscCall(VecGetLocalSize(Q, &n));
  PetscCall(MatGetLocalSize(R_, nullptr, &nstate));
  const PetscInt points = nstate / dof_, per_point = points ? n / points : 0;
  PetscCheck(points == 0 || (n == points * per_point && component_ < per_point), PETSC_COMM_SELF, PETSC_ERR_PLIB,
             "Survey: a vector of %" PetscInt_FMT " local entries is neither a state nor its positions", n);
  PetscCall(assemble_sampling(per_point, Q, R_positions_.out()));
  PetscFunctionReturn(0);
}

PetscErrorCode Survey::terminal(Vec UT, PetscReal *J, Vec dJdU) {
  PetscFunctionBeginUser;
  *J = 0;
  if (dJdU) PetscCall(VecSet(dJdU, 0.0));
  if (recording_) { // the final state: the last stage an RK step visited at T is not U(T)
    PetscCall(MatMult(R_, UT, y_));
    if (rank_ == 0) {
      ConstArray y(y_);
      PetscCall(y.error());
      for (PetscInt r = 0; r < receivers(); ++r)
        traces_[(shot_ * receivers() + r) * nt_ + nt_ - 1] = PetscRealPart(y[r]);
    }
    recorded_[shot_ * nt_ + nt_ - 1] = 1;
  }
  PetscFunctionReturn(0);
}

PetscErrorCode Survey::integrand(PetscReal t, Vec U, PetscReal *r) {
  PetscReal nrm;
  PetscFunctionBeginUser;
  if (recording_) {
    // The last visit at a sample time wins: RK visits t_{n+1} first as the last stage of step n,
    // then as the first stage of step n+1, which is the step state U_{n+1}.
    PetscInt k;
    *r = 0;
    if (!sample_index(t, sample_dt_, nt_, &k)) PetscFunctionReturn(0);
    PetscCall(sample(U));
    if (rank_ == 0) {
      ConstArray y(y_);
      PetscCall(y.error());
      for (PetscInt q = 0; q < receivers(); ++q) traces_[(shot_ * receivers() + q) * nt_ + k] = PetscRealPart(y[q]);
    }
    recorded_[shot_ * nt_ + k] = 1;
    PetscFunctionReturn(0);
  }
  PetscCall(residual(t, U));
  PetscCall(VecNorm(y_, NORM_2, &nrm));
  *r = 0.5 * nrm * nrm;
  PetscFunctionReturn(0);
}

PetscErrorCode Survey::integrand_dU(PetscReal t, Vec U, Vec drdU) {
  PetscFunctionBeginUser;
  PetscCall(residual(t, U));
  PetscCall(MatMultTranspose(R_, y_, drdU));
  PetscFunctionReturn(0);
}

// lambda += w R^T (R U - d(t)): a few entries per receiver, not a state-sized dr/dU.
PetscErrorCode Survey::integrand_dU_add(PetscReal t, Vec U, PetscReal w, Vec lambda) {
  PetscInt n, nstate;
  PetscFunctionBeginUser;
  PetscCall(residual(t, U));
  PetscCall(VecScale(y_, w));
  PetscCall(VecGetLocalSize(lambda, &n));
  PetscCall(MatGetLocalSize(R_, nullptr, &nstate));
  if (n == nstate) PetscCall(MatMultTransposeAdd(R_, y_, lambda, lambda));
  else { // the adjoint's positions part alone: sampled as the positions are
    if (!R_positions_) PetscCall(positions_sampling(lambda));
    PetscCall(MatMultTransposeAdd(R_positions_, y_, lambda, lambda));
  }
  PetscFunctionReturn(0);
}

} // namespace flexipde
