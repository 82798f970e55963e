// FFTW-MPI spectral differentiation (see include/flexipde/spectral.hpp for the mathematics).
//
// Data path of apply(): DMDA global Vec --VecScatter--> forward-input layout (complex, imaginary
// parts 0) --FFTW--> forward-output layout --multiply by m(k)/N--> [VecScatter to the backward
// input layout when FFTW's 1D layouts differ] --FFTW--> backward output --VecScatter of the real
// parts--> DMDA global Vec. FFTW-MPI distributes every layout in contiguous blocks of the natural
// (x fastest) ordering in rank order, so a complex entry with natural index g sits at entries 2g
// (real) and 2g+1 (imaginary) of a PETSc Vec wrapped around the FFTW buffer.
#include "flexipde/spectral.hpp"
#include <fftw3-mpi.h>
#include <algorithm>
#include <cmath>
#include <map>
#include <utility>
#include <vector>

#if defined(PETSC_USE_COMPLEX) || !defined(PETSC_USE_REAL_DOUBLE)
#error "spectral.cpp wraps FFTW's double-complex buffers as real double PETSc Vecs"
#endif

namespace flexipde {

namespace {
// Complex numbers stored as interleaved pairs of reals (FFTW's buffers, Symbols, Spectra).
inline void cmul(PetscReal fr, PetscReal fi, PetscReal vr, PetscReal vi, PetscReal &re, PetscReal &im) {
  re = fr * vr - fi * vi;
  im = fr * vi + fi * vr;
}
inline const PetscReal *reals(const std::vector<std::complex<PetscReal>> &v) { return reinterpret_cast<const PetscReal *>(v.data()); }

// alpha = ||a|| / ||b|| (1 when either is zero): the scale of b in apply_sum's pair a + i alpha b
// that keeps both parts at the same size, so that neither is lost in the other's round-off. Collective
// (one reduction for both norms).
PetscErrorCode balance(Vec a, Vec b, PetscReal *alpha) {
  PetscReal na, nb;
  PetscFunctionBeginUser;
  PetscCall(VecNormBegin(a, NORM_2, &na));
  PetscCall(VecNormBegin(b, NORM_2, &nb));
  PetscCall(VecNormEnd(a, NORM_2, &na));
  PetscCall(VecNormEnd(b, NORM_2, &nb));
  *alpha = na > 0 && nb > 0 ? na / nb : 1.0;
  PetscFunctionReturn(0);
}

struct Layout {
  ptrdiff_t start = 0, count = 0; // complex entries, natural ordering
  bool operator==(const Layout &o) const { return start == o.start && count == o.count; }
};
} // namespace

struct SpectralDifferentiator::Impl {
  MPI_Comm comm = MPI_COMM_NULL;
  PetscInt rank_dims = 1; // transformed directions: 1 (1D grid or x-only) or 2
  bool x_only = false;
  PetscInt nx = 0, ny = 1, nlocal = 0;
  PetscReal Lx = 1, Ly = 1, norm = 1;
  Layout fin, fout, bin, bout;
  fftw_complex *a_in = nullptr, *a_out = nullptr, *b_in = nullptr, *b_out = nullptr;
  bool same_mid = true; // backward input layout == forward output layout on every rank
  fftw_plan fwd = nullptr, bwd = nullptr;
  OwnedVec v_fin, v_fout, v_bin, v_bout;
  OwnedScatter to_fft, to_fft_imag, relayout, from_fft, from_fft_imag;
  // Every layout is this rank's block of the DMDA ordering (one rank, or y-slabs that match the
  // DMDA's): the copies in and out of the transforms are plain loops, no VecScatter.
  bool direct = false;
  // A 1D grid of at most kReplicateMax points (setup's replicate_max) on several ranks: every rank
  // gathers the whole field (one MPI_Allgatherv of its owned values, real and imaginary parts
  // interleaved, straight into a_in) and transforms all of it with serial FFTW, so it holds every mode
  // and the backward transform needs no communication at all. FFTW-MPI's distributed 1D transform does
  // three all-to-all transposes each way, which on small grids cost far more than the transform.
  bool replicated = false;
  PetscInt xs = 0; // this rank's first point (1D)
  std::vector<PetscMPIInt> counts, displs; // reals per rank in the gather
  std::vector<PetscReal> sendbuf;
  std::vector<FourierMode> modes; // of the forward output this rank holds (fout), made once
  std::map<PetscInt, SpectralDifferentiator::Symbol> derivatives; // derivative()'s symbols, made on first use
  SpectralDifferentiator::Spectrum uhat;                          // apply_many's transform
  std::vector<SpectralDifferentiator::Spectrum> packed;           // apply_sum's transforms but the last, one per two fields
  // The three parts of apply(): u (DMDA) -> a_out; a_out = s a_out mode by mode (conj(s) for the
  // transpose); a_out -> backward transform -> y (DMDA, real parts).
  // from_spectrum(y, y_imag): y = the real parts of the backward transform; y_imag (optional) = the
  // imaginary parts.
  PetscErrorCode to_spectrum(Vec u, Vec v = nullptr, PetscReal alpha = 1); // F(u + i alpha v)
  void multiply(const std::complex<PetscReal> *s, bool transpose);
  // a_out = s v; a_out = s0 u + i s1 v (symbols and spectra as interleaved reals; a spectrum may be
  // a_out itself).
  void product(const PetscReal *s, const PetscReal *v);
  void pair_products(const PetscReal *s0, const PetscReal *u, const PetscReal *s1, const PetscReal *v);
  PetscErrorCode from_spectrum(Vec y, Vec y_imag = nullptr);
  // s = a_out's modes (a spectrum kept while a_out takes the next transform).
  void keep(SpectralDifferentiator::Spectrum &s) const {
    const auto *out = reinterpret_cast<const std::complex<PetscReal> *>(a_out);
    s.assign(out, out + modes.size());
  }

  ~Impl() {
    if (fwd) fftw_destroy_plan(fwd);
    if (bwd) fftw_destroy_plan(bwd);
    fftw_free(a_in);
    fftw_free(a_out);
    if (!same_mid) fftw_free(b_in);
    fftw_free(b_out);
  }
  FourierMode mode(ptrdiff_t g) const {
    FourierMode k;
    const PetscInt ix = rank_dims == 1 && !x_only ? (PetscInt)g : (PetscInt)(g % nx);
    k.kx = ix < nx / 2 ? ix : ix - nx;
    k.wx = 2 * PETSC_PI * k.kx / Lx;
    k.kept = 3 * std::abs(k.kx) < nx;
    if (rank_dims == 2) {
      const PetscInt iy = (PetscInt)(g / nx);
      k.ky = iy < ny / 2 ? iy : iy - ny;
      k.wy = 2 * PETSC_PI * k.ky / Ly;
      k.kept = k.kept && 3 * std::abs(k.ky) < ny;
    }
    return k;
  }
  // The mode -k (the Nyquist mode is its own negative).
  FourierMode negative(const FourierMode &k) const {
    FourierMode n = k;
    if (2 * k.kx != -nx) n.kx = -k.kx;
    n.wx = 2 * PETSC_PI * n.kx / Lx;
    if (rank_dims == 2) {
      if (2 * k.ky != -ny) n.ky = -k.ky;
      n.wy = 2 * PETSC_PI * n.ky / Ly;
    }
    return n;
  }
};

namespace {

PetscErrorCode wrap(MPI_Comm comm, fftw_complex *buf, const Layout &l, Vec *v) {
  PetscInt lo;
  PetscFunctionBeginUser;
  PetscCall(VecCreateMPIWithArray(comm, 1, 2 * (PetscInt)l.count, PETSC_DECIDE, reinterpret_cast<PetscScalar *>(buf), v));
  PetscCall(VecGetOwnershipRange(*v, &lo, nullptr));
  // A rank FFTW leaves without data (e.g. 16 points over 3 ranks) may get any start: not checked. The
  // check is agreed on by every rank, so that a failure is reported (by rank 0) on all of them.
  int in_order = l.count == 0 || lo == 2 * (PetscInt)l.start;
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &in_order, 1, MPI_INT, MPI_LAND, comm));
  PetscCheck(in_order, comm, PETSC_ERR_PLIB, "FFTW layout is not in rank order");
  PetscFunctionReturn(0);
}

// Natural indices g of a layout, and the DMDA (PETSc-ordered) global indices of the same points.
PetscErrorCode layout_indices(DM dm, const Layout &l, std::vector<PetscInt> &natural, std::vector<PetscInt> &petsc) {
  AO ao;
  PetscFunctionBeginUser;
  natural.resize(l.count);
  for (ptrdiff_t p = 0; p < l.count; ++p) natural[p] = (PetscInt)(l.start + p);
  petsc = natural;
  PetscCall(DMDAGetAO(dm, &ao));
  PetscCall(AOApplicationToPetsc(ao, (PetscInt)petsc.size(), petsc.data()));
  PetscFunctionReturn(0);
}

PetscErrorCode make_is(MPI_Comm comm, const std::vector<PetscInt> &idx, IS *is) {
  PetscFunctionBeginUser;
  PetscCall(ISCreateGeneral(comm, (PetscInt)idx.size(), idx.data(), PETSC_COPY_VALUES, is));
  PetscFunctionReturn(0);
}

// FFTW wrote into the array behind v: a get/restore pair tells PETSc (its state moves on).
PetscErrorCode touched(Vec v) {
  PetscScalar *a;
  PetscFunctionBeginUser;
  PetscCall(VecGetArray(v, &a));
  PetscCall(VecRestoreArray(v, &a));
  PetscFunctionReturn(0);
}

struct DerivativeShell {
  const SpectralDifferentiator *d;
  PetscInt dir, order;
};

PetscErrorCode shell_mult(Mat A, Vec x, Vec y) {
  DerivativeShell *s;
  PetscFunctionBeginUser;
  PetscCall(MatShellGetContext(A, &s));
  PetscCall(s->d->derivative(s->dir, s->order, x, y, false, false));
  PetscFunctionReturn(0);
}
PetscErrorCode shell_mult_transpose(Mat A, Vec x, Vec y) {
  DerivativeShell *s;
  PetscFunctionBeginUser;
  PetscCall(MatShellGetContext(A, &s));
  PetscCall(s->d->derivative(s->dir, s->order, x, y, false, true));
  PetscFunctionReturn(0);
}
PetscErrorCode shell_destroy(Mat A) {
  DerivativeShell *s;
  PetscFunctionBeginUser;
  PetscCall(MatShellGetContext(A, &s));
  delete s;
  PetscFunctionReturn(0);
}

} // namespace

SpectralDifferentiator::SpectralDifferentiator() = default;
SpectralDifferentiator::~SpectralDifferentiator() = default;
SpectralDifferentiator::SpectralDifferentiator(SpectralDifferentiator &&) noexcept = default;
SpectralDifferentiator &SpectralDifferentiator::operator=(SpectralDifferentiator &&) noexcept = default;

PetscErrorCode SpectralDifferentiator::setup(const Grid &grid, bool x_only, PetscInt replicate_max) {
  static bool fftw_mpi_ready = false;
  MPI_Comm comm = grid.comm();
  PetscMPIInt size;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  // the transforms below are 1D or 2D FFTW-MPI plans over the grid's x (and y) lines
  PetscCheck(grid.dim() <= 2, comm, PETSC_ERR_SUP,
             "Spectral differentiation is offered on 1D and 2D grids only, the grid is %" PetscInt_FMT "D", grid.dim());
  if (!fftw_mpi_ready) {
    fftw_mpi_init();
    fftw_mpi_ready = true;
  }
  auto im = std::make_unique<Impl>();
  im->comm = comm;
  im->x_only = grid.dim() == 2 && x_only;
  im->rank_dims = grid.dim() == 2 && !x_only ? 2 : 1;
  im->nx = grid.n();
  im->ny = grid.dim() == 2 ? grid.ny() : 1;
  im->nlocal = grid.local_points();
  im->Lx = grid.x1() - grid.x0();
  im->Ly = grid.y1() - grid.y0();
  PetscCheck(grid.periodic(), comm, PETSC_ERR_ARG_WRONG, "Spectral differentiation needs a periodic grid in x (-grid_periodic 1)");
  PetscCheck(im->nx % 2 == 0, comm, PETSC_ERR_ARG_OUTOFRANGE,
             "Spectral differentiation needs an even number of points, got -da_grid_x %" PetscInt_FMT, im->nx);
  if (im->rank_dims == 2) {
    PetscCheck(grid.periodic_y(), comm, PETSC_ERR_ARG_WRONG,
               "Spectral differentiation in x and y needs a periodic grid in y too (-grid_periodic_y 1)");
    PetscCheck(im->ny % 2 == 0, comm, PETSC_ERR_ARG_OUTOFRANGE,
               "Spectral differentiation needs an even number of points, got -da_grid_y %" PetscInt_FMT, im->ny);
  }
  ptrdiff_t alloc = 1;
  if (grid.dim() == 1 && size > 1 && im->nx <= replicate_max) {
    im->replicated = true;
    im->fin = im->fout = im->bin = im->bout = Layout{0, (ptrdiff_t)im->nx};
    im->norm = im->nx;
    alloc = im->nx;
  } else if (grid.dim() == 1) {
    ptrdiff_t ni, is, no, os, bni, bis, bno, bos;
    alloc = std::max(alloc, fftw_mpi_local_size_1d(im->nx, comm, FFTW_FORWARD, FFTW_ESTIMATE, &ni, &is, &no, &os));
    alloc = std::max(alloc, fftw_mpi_local_size_1d(im->nx, comm, FFTW_BACKWARD, FFTW_ESTIMATE, &bni, &bis, &bno, &bos));
    im->fin = {is, ni};
    im->fout = {os, no};
    im->bin = {bis, bni};
    im->bout = {bos, bno};
    im->norm = im->nx;
  } else {
    ptrdiff_t n0, s0;
    alloc = std::max(alloc, fftw_mpi_local_size_2d(im->ny, im->nx, comm, &n0, &s0));
    im->fin = im->fout = im->bin = im->bout = Layout{s0 * im->nx, n0 * im->nx};
    im->norm = im->rank_dims == 2 ? (PetscReal)im->nx * im->ny : im->nx;
  }
  int same = im->fout == im->bin;
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &same, 1, MPI_INT, MPI_LAND, comm));
  im->same_mid = same;
  im->a_in = fftw_alloc_complex(alloc);
  im->a_out = fftw_alloc_complex(alloc);
  im->b_in = im->same_mid ? im->a_out : fftw_alloc_complex(alloc);
  im->b_out = fftw_alloc_complex(alloc);
  PetscCheck(im->a_in && im->a_out && im->b_in && im->b_out, comm, PETSC_ERR_MEM, "FFTW could not allocate its buffers");
  if (im->replicated) {
    im->fwd = fftw_plan_dft_1d((int)im->nx, im->a_in, im->a_out, FFTW_FORWARD, FFTW_ESTIMATE);
    im->bwd = fftw_plan_dft_1d((int)im->nx, im->b_in, im->b_out, FFTW_BACKWARD, FFTW_ESTIMATE);
  } else if (grid.dim() == 1) {
    im->fwd = fftw_mpi_plan_dft_1d(im->nx, im->a_in, im->a_out, comm, FFTW_FORWARD, FFTW_ESTIMATE);
    im->bwd = fftw_mpi_plan_dft_1d(im->nx, im->b_in, im->b_out, comm, FFTW_BACKWARD, FFTW_ESTIMATE);
  } else if (im->rank_dims == 2) {
    im->fwd = fftw_mpi_plan_dft_2d(im->ny, im->nx, im->a_in, im->a_out, comm, FFTW_FORWARD, FFTW_ESTIMATE);
    im->bwd = fftw_mpi_plan_dft_2d(im->ny, im->nx, im->b_in, im->b_out, comm, FFTW_BACKWARD, FFTW_ESTIMATE);
  } else if (im->fin.count > 0) { // x-lines: serial transforms of the rows this rank holds
    const int n = (int)im->nx, rows = (int)(im->fin.count / im->nx);
    im->fwd = fftw_plan_many_dft(1, &n, rows, im->a_in, nullptr, 1, n, im->a_out, nullptr, 1, n, FFTW_FORWARD, FFTW_ESTIMATE);
    im->bwd = fftw_plan_many_dft(1, &n, rows, im->b_in, nullptr, 1, n, im->b_out, nullptr, 1, n, FFTW_BACKWARD, FFTW_ESTIMATE);
  }
  int planned = (im->fwd && im->bwd) || (im->x_only && im->fin.count == 0);
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &planned, 1, MPI_INT, MPI_LAND, comm));
  PetscCheck(planned, comm, PETSC_ERR_SUP,
             "FFTW-MPI cannot distribute a transform of %" PetscInt_FMT " x %" PetscInt_FMT " points over %d ranks; "
             "choose a number of points with small prime factors (e.g. a power of 2)",
             im->nx, im->ny, (int)size);
  im->modes.resize((size_t)im->fout.count);
  for (ptrdiff_t p = 0; p < im->fout.count; ++p) im->modes[p] = im->mode(im->fout.start + p);
  if (im->replicated) { // the gather's counts and offsets (reals: two per point)
    const PetscMPIInt mine[2] = {(PetscMPIInt)(2 * grid.xm()), (PetscMPIInt)(2 * grid.xs())};
    std::vector<PetscMPIInt> all(2 * (size_t)size);
    PetscCallMPI(MPI_Allgather(mine, 2, MPI_INT, all.data(), 2, MPI_INT, comm));
    im->counts.resize(size);
    im->displs.resize(size);
    for (PetscMPIInt r = 0; r < size; ++r) im->counts[r] = all[2 * r], im->displs[r] = all[2 * r + 1];
    im->xs = grid.xs();
    im->sendbuf.resize(2 * (size_t)grid.xm());
    impl_ = std::move(im);
    PetscFunctionReturn(0);
  }

  PetscCall(wrap(comm, im->a_in, im->fin, im->v_fin.out()));
  PetscCall(wrap(comm, im->a_out, im->fout, im->v_fout.out()));
  PetscCall(wrap(comm, im->b_in, im->bin, im->v_bin.out()));
  PetscCall(wrap(comm, im->b_out, im->bout, im->v_bout.out()));
  OwnedVec g;
  PetscCall(DMCreateGlobalVector(grid.dm(), g.out()));
  std::vector<PetscInt> nat, pet, twice;
  for (int part = 0; part < 2; ++part) { // DMDA -> real (and imaginary) parts of the forward input
    OwnedIS from, to;
    PetscCall(layout_indices(grid.dm(), im->fin, nat, pet));
    twice.resize(nat.size());
    for (size_t p = 0; p < nat.size(); ++p) twice[p] = 2 * nat[p] + part;
    PetscCall(make_is(comm, pet, from.out()));
    PetscCall(make_is(comm, twice, to.out()));
    PetscCall(VecScatterCreate(g, from, im->v_fin, to, part ? im->to_fft_imag.out() : im->to_fft.out()));
  }
  for (int part = 0; part < 2; ++part) { // real (and imaginary) parts of the backward output -> DMDA
    OwnedIS from, to;
    PetscCall(layout_indices(grid.dm(), im->bout, nat, pet));
    twice.resize(nat.size());
    for (size_t p = 0; p < nat.size(); ++p) twice[p] = 2 * nat[p] + part;
    PetscCall(make_is(comm, twice, from.out()));
    PetscCall(make_is(comm, pet, to.out()));
    PetscCall(VecScatterCreate(im->v_bout, from, g, to, part ? im->from_fft_imag.out() : im->from_fft.out()));
  }
  { // direct copies: every layout equal to this rank's DMDA block, in the same order
    PetscInt lo;
    PetscCall(VecGetOwnershipRange(g, &lo, nullptr));
    int direct = im->fin == im->fout && im->fin == im->bin && im->fin == im->bout && (PetscInt)im->fin.count == im->nlocal;
    if (direct) {
      PetscCall(layout_indices(grid.dm(), im->fin, nat, pet));
      for (size_t p = 0; p < pet.size() && direct; ++p) direct = pet[p] == lo + (PetscInt)p;
    }
    PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &direct, 1, MPI_INT, MPI_LAND, comm));
    im->direct = direct;
  }
  if (!im->same_mid) { // forward output -> backward input, real and imaginary parts
    OwnedIS is;
    std::vector<PetscInt> both(2 * im->bin.count);
    for (ptrdiff_t p = 0; p < im->bin.count; ++p) {
      both[2 * p] = 2 * (PetscInt)(im->bin.start + p);
      both[2 * p + 1] = both[2 * p] + 1;
    }
    PetscCall(make_is(comm, both, is.out()));
    PetscCall(VecScatterCreate(im->v_fout, is, im->v_bin, is, im->relayout.out()));
  }
  impl_ = std::move(im);
  PetscFunctionReturn(0);
}

PetscErrorCode SpectralDifferentiator::Impl::to_spectrum(Vec u, Vec v, PetscReal alpha) {
  PetscFunctionBeginUser;
  if (replicated) { // this rank's points as complex values, gathered whole into a_in on every rank
    const PetscScalar *x, *y = nullptr;
    PetscReal *sb = sendbuf.data();
    PetscCall(VecGetArrayRead(u, &x));
    if (v) PetscCall(VecGetArrayRead(v, &y));
    for (PetscInt p = 0; p < nlocal; ++p) {
      sb[2 * p] = PetscRealPart(x[p]);
      sb[2 * p + 1] = y ? alpha * PetscRealPart(y[p]) : 0.0;
    }
    if (v) PetscCall(VecRestoreArrayRead(v, &y));
    PetscCall(VecRestoreArrayRead(u, &x));
    PetscCallMPI(MPI_Allgatherv(sb, (PetscMPIInt)(2 * nlocal), MPIU_REAL, &a_in[0][0], counts.data(), displs.data(), MPIU_REAL, comm));
    fftw_execute(fwd);
    PetscFunctionReturn(0);
  }
  if (direct) {
    const PetscScalar *x, *y;
    PetscReal *a = &a_in[0][0];
    PetscCall(VecGetArrayRead(u, &x));
    if (v) {
      PetscCall(VecGetArrayRead(v, &y));
      for (PetscInt p = 0; p < nlocal; ++p) {
        a[2 * p] = PetscRealPart(x[p]);
        a[2 * p + 1] = alpha * PetscRealPart(y[p]);
      }
      PetscCall(VecRestoreArrayRead(v, &y));
    } else
      for (PetscInt p = 0; p < nlocal; ++p) {
        a[2 * p] = PetscRealPart(x[p]);
        a[2 * p + 1] = 0;
      }
    PetscCall(VecRestoreArrayRead(u, &x));
  } else {
    if (!v) PetscCall(VecSet(v_fin, 0.0)); // else every entry is written below
    PetscCall(VecScatterBegin(to_fft, u, v_fin, INSERT_VALUES, SCATTER_FORWARD));
    PetscCall(VecScatterEnd(to_fft, u, v_fin, INSERT_VALUES, SCATTER_FORWARD));
    if (v) {
      PetscCall(VecScatterBegin(to_fft_imag, v, v_fin, INSERT_VALUES, SCATTER_FORWARD));
      PetscCall(VecScatterEnd(to_fft_imag, v, v_fin, INSERT_VALUES, SCATTER_FORWARD));
      if (alpha != 1) {
        PetscScalar *a;
        PetscInt n;
        PetscCall(VecGetLocalSize(v_fin, &n));
        PetscCall(VecGetArray(v_fin, &a));
        for (PetscInt p = 1; p < n; p += 2) a[p] *= alpha;
        PetscCall(VecRestoreArray(v_fin, &a));
      }
    }
  }
  if (fwd) fftw_execute(fwd);
  PetscFunctionReturn(0);
}

void SpectralDifferentiator::Impl::multiply(const std::complex<PetscReal> *s, bool transpose) {
  const ptrdiff_t n = fout.count;
  PetscReal *a = &a_out[0][0];
  const PetscReal *f = reinterpret_cast<const PetscReal *>(s);
  const PetscReal c = transpose ? -1.0 : 1.0; // conj(s)
  for (ptrdiff_t p = 0; p < n; ++p) {
    const PetscReal fr = f[2 * p], fi = c * f[2 * p + 1], vr = a[2 * p], vi = a[2 * p + 1];
    a[2 * p] = fr * vr - fi * vi;
    a[2 * p + 1] = fr * vi + fi * vr;
  }
}

PetscErrorCode SpectralDifferentiator::Impl::from_spectrum(Vec y, Vec y_imag) {
  PetscFunctionBeginUser;
  if (!same_mid) {
    PetscCall(touched(v_fout));
    PetscCall(VecScatterBegin(relayout, v_fout, v_bin, INSERT_VALUES, SCATTER_FORWARD));
    PetscCall(VecScatterEnd(relayout, v_fout, v_bin, INSERT_VALUES, SCATTER_FORWARD));
  }
  if (bwd) fftw_execute(bwd);
  if (direct || replicated) { // (replicated: this rank's points of the whole transform)
    const PetscReal *b = &b_out[0][0] + (replicated ? 2 * xs : 0);
    PetscScalar *re, *im = nullptr;
    PetscCall(VecGetArrayWrite(y, &re));
    if (y_imag) PetscCall(VecGetArrayWrite(y_imag, &im));
    for (PetscInt p = 0; p < nlocal; ++p) re[p] = b[2 * p];
    if (y_imag)
      for (PetscInt p = 0; p < nlocal; ++p) im[p] = b[2 * p + 1];
    PetscCall(VecRestoreArrayWrite(y, &re));
    if (y_imag) PetscCall(VecRestoreArrayWrite(y_imag, &im));
    PetscFunctionReturn(0);
  }
  PetscCall(touched(v_bout));
  PetscCall(VecScatterBegin(from_fft, v_bout, y, INSERT_VALUES, SCATTER_FORWARD));
  PetscCall(VecScatterEnd(from_fft, v_bout, y, INSERT_VALUES, SCATTER_FORWARD));
  if (y_imag) {
    PetscCall(VecScatterBegin(from_fft_imag, v_bout, y_imag, INSERT_VALUES, SCATTER_FORWARD));
    PetscCall(VecScatterEnd(from_fft_imag, v_bout, y_imag, INSERT_VALUES, SCATTER_FORWARD));
  }
  PetscFunctionReturn(0);
}

SpectralDifferentiator::Symbol SpectralDifferentiator::symbol(const Multiplier &m) const {
  const Impl &im = *impl_;
  Symbol s(im.modes.size());
  for (size_t p = 0; p < s.size(); ++p) // the part with a real backward transform: (m(k) + conj(m(-k))) / 2
    s[p] = (m(im.modes[p]) + std::conj(m(im.negative(im.modes[p])))) / (2 * im.norm);
  return s;
}

PetscErrorCode SpectralDifferentiator::apply(const Multiplier &m, Vec u, Vec y, bool transpose) const {
  PetscFunctionBeginUser;
  PetscCall(apply(symbol(m), u, y, transpose));
  PetscFunctionReturn(0);
}

PetscErrorCode SpectralDifferentiator::apply(const Symbol &s, Vec u, Vec y, bool transpose) const {
  PetscFunctionBeginUser;
  PetscCheck(s.size() == impl_->modes.size(), impl_->comm, PETSC_ERR_ARG_SIZ, "A spectral symbol of %zu modes for %zu", s.size(),
             impl_->modes.size());
  PetscCall(impl_->to_spectrum(u));
  impl_->multiply(s.data(), transpose);
  PetscCall(impl_->from_spectrum(y));
  PetscFunctionReturn(0);
}

// a_out = f v (v: a spectrum, or a_out itself: each mode is read before it is written).
void SpectralDifferentiator::Impl::product(const PetscReal *f, const PetscReal *v) {
  const size_t n = modes.size();
  PetscReal *a = &a_out[0][0];
  for (size_t p = 0; p < n; ++p) cmul(f[2 * p], f[2 * p + 1], v[2 * p], v[2 * p + 1], a[2 * p], a[2 * p + 1]);
}

// a_out = f u + i g v (u, v: spectra, or a_out itself). With both symbols' backward transforms real
// (symbol() makes them so), the real and imaginary parts of the backward transform are F u and G v.
void SpectralDifferentiator::Impl::pair_products(const PetscReal *f, const PetscReal *u, const PetscReal *g, const PetscReal *v) {
  const size_t n = modes.size();
  PetscReal *o = &a_out[0][0];
  if (u == v) { // one spectrum: (f + i g) u, one product per mode
    for (size_t p = 0; p < n; ++p) {
      PetscReal re, im;
      cmul(f[2 * p] - g[2 * p + 1], f[2 * p + 1] + g[2 * p], u[2 * p], u[2 * p + 1], re, im);
      o[2 * p] = re;
      o[2 * p + 1] = im;
    }
    return;
  }
  for (size_t p = 0; p < n; ++p) {
    PetscReal re0, im0, re1, im1;
    cmul(f[2 * p], f[2 * p + 1], u[2 * p], u[2 * p + 1], re0, im0);
    cmul(g[2 * p], g[2 * p + 1], v[2 * p], v[2 * p + 1], re1, im1);
    o[2 * p] = re0 - im1;
    o[2 * p + 1] = im0 + re1;
  }
}

PetscErrorCode SpectralDifferentiator::apply_many(const std::vector<const Symbol *> &ss, Vec u, const std::vector<Vec> &ys) const {
  Impl &im = *impl_;
  PetscFunctionBeginUser;
  PetscCheck(ss.size() == ys.size(), im.comm, PETSC_ERR_ARG_SIZ, "apply_many: %zu symbols for %zu outputs", ss.size(), ys.size());
  for (const Symbol *q : ss)
    PetscCheck(q->size() == im.modes.size(), im.comm, PETSC_ERR_ARG_SIZ, "A spectral symbol of %zu modes for %zu", q->size(), im.modes.size());
  const PetscReal *in = &im.a_out[0][0]; // one backward transform: multiply in place
  PetscCall(im.to_spectrum(u));
  if (ss.size() > 2) { // more than one: keep the spectrum
    im.keep(im.uhat);
    in = reals(im.uhat);
  }
  for (size_t j = 0; j < ss.size(); j += 2) { // two outputs per backward transform (real, imaginary parts)
    if (j + 1 < ss.size()) im.pair_products(reals(*ss[j]), in, reals(*ss[j + 1]), in);
    else im.product(reals(*ss[j]), in);
    PetscCall(im.from_spectrum(ys[j], j + 1 < ss.size() ? ys[j + 1] : nullptr));
  }
  PetscFunctionReturn(0);
}

PetscErrorCode SpectralDifferentiator::apply_sum(const std::vector<const Symbol *> &ss, const std::vector<Vec> &vs, Vec y) const {
  Impl &im = *impl_;
  const size_t n = im.modes.size(), np = (vs.size() + 1) / 2;
  std::vector<PetscReal> alpha(np, 1.0);
  PetscFunctionBeginUser;
  PetscCheck(ss.size() == vs.size() && !vs.empty(), im.comm, PETSC_ERR_ARG_SIZ, "apply_sum: %zu symbols for %zu fields", ss.size(), vs.size());
  for (const Symbol *q : ss)
    PetscCheck(q->size() == n, im.comm, PETSC_ERR_ARG_SIZ, "A spectral symbol of %zu modes for %zu", q->size(), n);
  im.packed.resize(np - 1);
  for (size_t p = 0; p < np; ++p) { // Z_p = F(v_2p + i alpha_p v_2p+1); the last one stays in a_out
    const Vec b = 2 * p + 1 < vs.size() ? vs[2 * p + 1] : nullptr;
    if (b) PetscCall(balance(vs[2 * p], b, &alpha[p]));
    PetscCall(im.to_spectrum(vs[2 * p], b, alpha[p]));
    if (p + 1 < np) im.keep(im.packed[p]);
  }
  // sum_p (s_2p - i s_2p+1 / alpha_p) Z_p: Re F^-1 of s_2p Z_p is S_2p v_2p and Re F^-1 of -i s_2p+1 Z_p /
  // alpha_p is S_2p+1 v_2p+1 (both symbols' backward transforms of a real field are real). The last
  // pair's term first, in place, then the others added: one plain loop over the modes each.
  PetscReal *a = &im.a_out[0][0];
  for (size_t q = 0; q < np; ++q) {
    const size_t p = (q + np - 1) % np; // np - 1, 0, 1, ..., np - 2
    const PetscReal *f = reals(*ss[2 * p]), *g = 2 * p + 1 < vs.size() ? reals(*ss[2 * p + 1]) : nullptr;
    const PetscReal *z = q ? reals(im.packed[p]) : a, ia = 1 / alpha[p];
    for (size_t k = 0; k < n; ++k) {
      PetscReal tr, ti;
      cmul(f[2 * k], f[2 * k + 1], z[2 * k], z[2 * k + 1], tr, ti);
      if (g) {
        PetscReal r1, i1;
        cmul(g[2 * k], g[2 * k + 1], z[2 * k], z[2 * k + 1], r1, i1);
        tr += ia * i1, ti -= ia * r1;
      }
      a[2 * k] = q ? a[2 * k] + tr : tr;
      a[2 * k + 1] = q ? a[2 * k + 1] + ti : ti;
    }
  }
  PetscCall(im.from_spectrum(y));
  PetscFunctionReturn(0);
}

std::complex<PetscReal> SpectralDifferentiator::derivative_symbol(const FourierMode &k, PetscInt dir, PetscInt order) {
  const std::complex<PetscReal> ik(0, dir == 0 ? k.wx : k.wy);
  std::complex<PetscReal> f = 1;
  for (PetscInt q = 0; q < order; ++q) f *= ik;
  return f;
}

PetscErrorCode SpectralDifferentiator::derivative(PetscInt dir, PetscInt order, Vec u, Vec y, bool dealias,
                                                  bool transpose) const {
  PetscFunctionBeginUser;
  PetscCheck(dir == 0 || (dir == 1 && impl_->rank_dims == 2), impl_->comm, PETSC_ERR_ARG_OUTOFRANGE,
             "Spectral derivative along direction %" PetscInt_FMT " is not transformed here", dir);
  const PetscInt key = 4 * order + 2 * dir + (dealias ? 1 : 0);
  auto it = impl_->derivatives.find(key);
  if (it == impl_->derivatives.end())
    it = impl_->derivatives
             .emplace(key, symbol([=](const FourierMode &k) {
               return dealias && !k.kept ? std::complex<PetscReal>(0) : derivative_symbol(k, dir, order);
             }))
             .first;
  PetscCall(apply(it->second, u, y, transpose));
  PetscFunctionReturn(0);
}

PetscErrorCode SpectralDifferentiator::dealias(Vec u, Vec y) const {
  PetscFunctionBeginUser;
  PetscCall(derivative(0, 0, u, y, true)); // the 0th derivative, de-aliased (its symbol kept with the others)
  PetscFunctionReturn(0);
}

PetscReal SpectralDifferentiator::max_wavenumber(PetscInt dir) const {
  const PetscInt n = dir == 0 ? impl_->nx : impl_->ny;
  const PetscReal L = dir == 0 ? impl_->Lx : impl_->Ly;
  return 2 * PETSC_PI * (n / 2 - 1) / L;
}

PetscErrorCode SpectralDifferentiator::create_derivative_mat(PetscInt dir, PetscInt order, Mat *A) const {
  PetscFunctionBeginUser;
  auto *ctx = new DerivativeShell{this, dir, order};
  PetscCall(MatCreateShell(impl_->comm, impl_->nlocal, impl_->nlocal, PETSC_DETERMINE, PETSC_DETERMINE, ctx, A));
  PetscCall(MatShellSetOperation(*A, MATOP_MULT, (void (*)(void))shell_mult));
  PetscCall(MatShellSetOperation(*A, MATOP_MULT_TRANSPOSE, (void (*)(void))shell_mult_transpose));
  PetscCall(MatShellSetOperation(*A, MATOP_DESTROY, (void (*)(void))shell_destroy));
  PetscFunctionReturn(0);
}

} // namespace flexipde
