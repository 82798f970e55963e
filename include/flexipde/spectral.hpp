// Fourier (pseudo-)spectral differentiation on periodic directions of a Grid, distributed with
// FFTW-MPI.
//
// For a grid function u on N points of a periodic direction of length L, with the DFT
// u^_k = sum_j u_j exp(-2 pi i j k / N) and the signed mode number k in [-N/2, N/2), a Fourier
// multiplier m applies
//     (M u)_j = Re( (1/N) sum_k m(kappa_k) u^_k exp(2 pi i j k / N) ),   kappa_k = 2 pi k / L,
// e.g. m = i kappa (d/dx), m = -kappa^2 (d^2/dx^2), m = 1 for |k| < N/3 and 0 otherwise (the 2/3
// de-aliasing filter). Taking the real part symmetrises the multiplier: M has the eigenvalues
// (m(k) + conj(m(-k)))/2, so an odd derivative has a zero Nyquist mode and is exactly
// skew-symmetric, and M is a real operator. Its transpose is the multiplier conj(m) (the DFT matrix
// is symmetric and F^{-1} = conj(F)/N), which apply(..., transpose = true) uses: this is what an
// adjoint needs, and what tests/test_spectral.cpp checks by the dot-product identity.
//
// Transforms (chosen by the grid and `x_only`):
//   1D grid                 FFTW-MPI 1D complex DFT, distributed over the ranks (FFTW's own
//                           input and output layouts, reached by VecScatters from the DMDA layout);
//                           on several ranks with at most kReplicateMax points (32768),
//                           replicated instead: every rank gathers the whole field (one
//                           MPI_Allgatherv) and transforms it with serial FFTW, holding every mode,
//                           so that a backward transform needs no communication. FFTW-MPI's 1D
//                           transform does three all-to-all transposes each way, which cost far
//                           more than small transforms.
//   2D grid                 FFTW-MPI 2D complex DFT on y-slabs (both directions periodic)
//   2D grid, x_only = true  the same y-slabs, each rank transforming its whole x-lines with serial
//                           FFTW: d/dx on a grid whose y direction need not be periodic (e.g. the
//                           velocity of a 1D1V phase space)
// The data are real; the complex transforms cost a factor ~2 over real-to-complex ones, which is
// what buys one code path for 1D and 2D and FFTW-MPI's 1D distribution (real 1D MPI transforms do
// not exist in FFTW), and apply_many's use of the imaginary part: two real outputs per backward
// transform. N must be even in every transformed direction.
#pragma once
#include "flexipde/grid.hpp"
#include <complex>
#include <functional>
#include <memory>
#include <vector>

namespace flexipde {

// One Fourier mode: signed mode numbers (ky = 0 for a 1D or x-only transform), the wavenumbers
// 2 pi k / L, and whether the 2/3 rule keeps it (3|k| < N in every transformed direction).
struct FourierMode {
  PetscInt kx = 0, ky = 0;
  PetscReal wx = 0, wy = 0;
  bool kept = true;
};

class SpectralDifferentiator {
public:
  using Multiplier = std::function<std::complex<PetscReal>(const FourierMode &)>;

  SpectralDifferentiator();
  ~SpectralDifferentiator();
  SpectralDifferentiator(SpectralDifferentiator &&) noexcept;
  SpectralDifferentiator &operator=(SpectralDifferentiator &&) noexcept;

  // The largest 1D grid transformed whole on every rank when there are several: up to about here a
  // replicated transform costs less than the distributed one's all-to-all transposes
  // (docs/performance.md).
  static constexpr PetscInt kReplicateMax = 32768;
  // Collective. u and y of apply() are global Vecs of grid.dm() (one value per grid point). The
  // grid must be periodic in every transformed direction with an even number of points there.
  // replicate_max: kReplicateMax (tests pass 0 to reach FFTW-MPI's distributed transform on small grids).
  PetscErrorCode setup(const Grid &grid, bool x_only = false, PetscInt replicate_max = kReplicateMax);
  bool ready() const { return impl_ != nullptr; }

  // y = M u (or M^T u); y may be u.
  PetscErrorCode apply(const Multiplier &m, Vec u, Vec y, bool transpose = false) const;
  // A multiplier evaluated once at the Fourier modes this rank holds, as the operator M sees it
  // ((m(k) + conj(m(-k))) / 2, whose backward transform is real), divided by the transform's
  // normalisation: what the transforms' loop reads, with no call or division per mode. Models keep
  // the symbols of their operators (rebuilt when a coefficient changes) for their hot paths.
  using Symbol = std::vector<std::complex<PetscReal>>;
  Symbol symbol(const Multiplier &m) const;
  PetscErrorCode apply(const Symbol &s, Vec u, Vec y, bool transpose = false) const;
  // ys[j] = S_j u for every j from one forward transform of u and one backward transform per two
  // outputs: (S_j + i S_{j+1}) u^ transforms back to S_j u + i S_{j+1} u, both real. Equal to
  // apply(*ss[j], u, ys[j]) to round-off. No y may be u.
  PetscErrorCode apply_many(const std::vector<const Symbol *> &ss, Vec u, const std::vector<Vec> &ys) const;
  // y = sum_j S_j v_j from one forward transform per two fields and one backward transform:
  // Z = F(v_j + i alpha v_{j+1}), alpha = ||v_j|| / ||v_{j+1}|| (so that neither part is lost in the
  // other's round-off), and Re F^-1 of (s_j - i s_{j+1} / alpha) Z is S_j v_j + S_{j+1} v_{j+1}, because
  // a symbol's backward transform of a real field is real. Equal to the sum of apply(*ss[j], v_j) to
  // round-off. y may be none of the v_j.
  PetscErrorCode apply_sum(const std::vector<const Symbol *> &ss, const std::vector<Vec> &vs, Vec y) const;
  // y = d^order u / d(x or y)^order (dir 0 = x, 1 = y), optionally de-aliased by the 2/3 rule.
  PetscErrorCode derivative(PetscInt dir, PetscInt order, Vec u, Vec y, bool dealias = false, bool transpose = false) const;
  // y = the 2/3-rule truncation of u (symmetric, a projection).
  PetscErrorCode dealias(Vec u, Vec y) const;
  // The multiplier of d^order/d(dir)^order: (i kappa)^order.
  static std::complex<PetscReal> derivative_symbol(const FourierMode &k, PetscInt dir, PetscInt order);
  // Largest |kappa| of a derivative along dir (the Nyquist mode excluded: its odd derivative is 0).
  PetscReal max_wavenumber(PetscInt dir) const;

  // A MatShell y = d^order u / d(dir)^order with MULT and MULT_TRANSPOSE (it refers to this
  // object, which must outlive it).
  PetscErrorCode create_derivative_mat(PetscInt dir, PetscInt order, Mat *A) const;

private:
  using Spectrum = std::vector<std::complex<PetscReal>>; // this rank's modes of F u
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

} // namespace flexipde
