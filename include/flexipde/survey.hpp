// A seismic survey: point sources fired one shot at a time, receivers recording u(x_r, t), and the
// receiver misfit integrated in time, summed over receivers and shots:
//
//   J(p) = sum_shots 0.5 int_0^T sum_r (u(x_r, t) - d_{s,r}(t))^2 dt.
//
// Sources. Shot s fires one point source at x_s with a Ricker wavelet of peak frequency f0,
//   w(t) = A (1 - 2 pi^2 f0^2 (t - t0)^2) exp(-pi^2 f0^2 (t - t0)^2),  t0 = delay (default 1.2/f0),
// added to the equation of the model's forced component (the wave: v_t = c^2 u_xx + w(t) delta_h(x - x_s)).
// The discrete delta spreads w over the grid points around x_s with the interpolation weights (linear,
// bilinear, trilinear, or Kaiser-windowed sinc: -survey_interpolation), divided by the cell volume, so
// that it integrates to w.
//
// Receivers. u(x_r, t) = (R U)_r, R the same interpolation weights on component u (a sparse
// matrix with one row per receiver, owned by rank 0). The misfit is an Objective integrand
//   r(t, U) = 0.5 ||R U - d(t)||^2,   dr/dU = R^T (R U - d(t)),   dr/dp = 0,
// integrated by the Simulation with the integrator's own quadrature, so the adjoint gradient is
// exact for this discrete objective.
//
// Data in time. The traces are samples d_k at t_k = k dt_d (k = 0..nt-1); d(t) between them is the
// cubic Lagrange interpolant through the four nearest samples (exact at the samples). Synthetic
// data are recorded by the same code at every step of the integrator (dt_d = the simulation's
// dt): CN (theta endpoint) and leapfrog evaluate r at the step states only, so at the true model the
// misfit is zero to round-off; RK evaluates it at its stages too, which are not the solution at the stage
// times, so the true model leaves a small misfit floor of the order of the time error (documented
// in docs/fwi_receivers.md).
//
// Options (prefix -survey_):
//   -survey_sources_x x1,x2,...      one shot per source (2D and 3D: -survey_sources_y, in 3D also
//                                    -survey_sources_z, each one value or one per source)
//   -survey_ricker_f0 F, -survey_ricker_delay T0, -survey_ricker_amplitude A
//   -survey_wavelet_file F           the wavelet from a text file instead: one "t w" pair per line
//   -survey_interpolation linear|sinc   how sources and receivers off the grid points are tied to it
//   -survey_receivers_x x1,...       receivers (2D and 3D: -survey_receivers_y, in 3D also -survey_receivers_z,
//                                    each one value or one per receiver), or
//   -survey_receivers_spread a,b,n   n receivers evenly spaced in x from a to b (2D: at depth
//                                    -survey_receivers_y; 3D: at -survey_receivers_y and -survey_receivers_z), or
//   -survey_receivers_file F         text file, one receiver per line: "x" (1D), "x y" (2D) or "x y z" (3D)
//   -survey_data_file F.h5           read the observed traces from F (written by -survey_data_write)
//   -survey_data_write F.h5          write the synthetic traces made from the true model to F
//
// Frequency bands (set_band, for frequency continuation): the data and every source wavelet pass through
// the same causal low-pass filter at f_c (order-4 Butterworth, two second-order sections, bilinear
// transform), applied to the samples. The filtered wavelet is sampled at the data's rate and
// interpolated like a wavelet from a file. The wave equation being linear and time-invariant, the
// filtered source makes the filtered data; a causal filter keeps that true up to the end of the time
// window (a zero-phase filter would mix in the data's truncation at T).
//
// Data file (HDF5, PETSc viewer): /survey/traces (nshots * nrec * nt, shot-major, then receiver,
// then sample), /survey/receivers_x, /survey/sources_x (and _y in 2D and 3D, _z in 3D), attributes on
// /survey/traces: nshots, nrec, nt (integers), sample_dt, dim.
#pragma once
#include "flexipde/model.hpp"
#include "flexipde/objective.hpp"
#include <string>
#include <vector>

namespace flexipde {

// Ricker wavelet of peak frequency f0 delayed by t0, amplitude a.
struct Ricker {
  PetscReal f0 = 10.0, t0 = 0.12, amplitude = 1.0;
  PetscReal operator()(PetscReal t) const;
};

// How a point off the grid is tied to it (-survey_interpolation):
//   linear  the 2 (1D), 4 (2D) or 8 (3D) nearest points, linear, bilinear or trilinear weights;
//   sinc    2r = 8 points per direction, w(d) = sinc(d) I0(b sqrt(1 - (d/r)^2)) / I0(b), d the distance
//           to the point in cells, r = 4, b = 6.31 (Kaiser-windowed sinc, Hicks 2002, with his b for
//           waves of 4 points per wavelength and more): exact on a grid point (w = 1 there, 0 at the
//           others), within about 1e-3 between points at 4 points per wavelength and more; in 2D and
//           3D the product of the directions' weights (8^3 = 512 points in 3D).
//           Points beyond a wall are left out (within 4 cells of a wall the weights no longer sum to 1).
// Sources and receivers use the same weights, so injection and sampling are each other's transposes.
enum class Interpolation { Linear, Sinc };
// The owned (point index, weight) pairs of a point's interpolation; weights summing to 1 over all ranks
// (sinc: up to the window's error, and away from walls). Points are local indices into the owned block
// (((k - zs) * ym + (j - ys)) * xm + (i - xs)). 8 KB: held once per source and filled in place, never
// copied in a loop over time steps. y is ignored in 1D, z below 3D.
struct PointStencil {
  static constexpr int max_points = 512; // the 3D sinc: 8 points per direction
  PetscInt n = 0;
  PetscInt local[max_points];
  PetscReal weight[max_points];
};
PetscErrorCode point_stencil(const Grid &grid, PetscReal x, PetscReal y, PetscReal z, PointStencil *st,
                             Interpolation how = Interpolation::Linear);

// A source's time function: the Ricker wavelet, or samples w_k at times t_k (increasing) read from a
// file, interpolated by the cubic Lagrange polynomial through the four nearest samples (as the data
// are in time), 0 outside [t_0, t_last].
struct Wavelet {
  Ricker ricker;
  std::vector<PetscReal> t, w; // samples (empty: the Ricker wavelet)
  PetscReal operator()(PetscReal time) const;
};

// The source of the current shot, as a model sees it: the local stencil and the wavelet.
struct PointSource {
  PointStencil stencil;
  Wavelet wavelet;
  PetscReal cell_volume = 1.0;
  // The forcing density at local point k of the stencil at time t; at_wavelet: with the wavelet's value
  // w(t) at hand (one evaluation for all the stencil's points).
  PetscReal density(PetscInt k, PetscReal t) const { return at_wavelet(k, wavelet(t)); }
  PetscReal at_wavelet(PetscInt k, PetscReal w) const { return w * stencil.weight[k] / cell_volume; }
};

class Survey final : public Objective {
public:
  // Reads the options above. component: the recorded component of U (dof per point).
  PetscErrorCode setup(const Grid &grid, Model &model, DM state_dm, PetscInt component, PetscInt dof);
  PetscInt shots() const { return nshots_; }
  PetscInt receivers() const { return (PetscInt)rec_x_.size(); }
  // Makes shot s the current one: the model's source and the data the misfit compares with.
  PetscErrorCode select_shot(PetscInt s);
  // Synthetic data: from now on the integrand records R U at the sample times instead of comparing
  // (the Scene runs each shot with the true model in between). sample_dt is the integrator's dt.
  PetscErrorCode begin_recording(PetscReal sample_dt, PetscReal final_time);
  // Records the initial state (sample 0) of the current shot.
  PetscErrorCode record_initial(Vec U0);
  // Ends the recording; checks every sample was recorded and writes -survey_data_write if set.
  PetscErrorCode end_recording();
  bool recording() const { return recording_; }
  // Shot groups (Scene, -shot_groups): this survey fires shots [first, end) alone; its recording checks
  // those and writes no file.
  void fire_only(PetscInt first, PetscInt end) { first_ = first, end_ = end; }
  // The traces that `group` recorded or read for its shots, from every group into this survey's (rank 0
  // of its communicator, which spans the groups); then -survey_data_write if set. Collective.
  PetscErrorCode gather_recording(const Survey &group);
  // Data and sources low-pass filtered at f_c (above; f_c <= 0: the whole band, as observed). Needs the
  // data (after Scene::make_synthetic_data).
  PetscErrorCode set_band(PetscReal f_c);
  // Reads -survey_data_file into the traces; false in *read when no file was given.
  PetscErrorCode read_data(PetscReal final_time, PetscBool *read);
  PetscErrorCode write_data(const char *file) const;
  const std::vector<PetscReal> &traces() const { return traces_; }
  PetscInt samples() const { return nt_; }
  PetscReal sample_dt() const { return sample_dt_; }
  const std::vector<PetscReal> &receivers_x() const { return rec_x_; }
  // R: u at the receivers from the state (one row per receiver, on rank 0; the sampling whose
  // transpose, over the cell volume, is the sources' injection).
  Mat receiver_matrix() const { return R_; }

  // Objective: no terminal part (except while recording), the integrand above.
  PetscErrorCode terminal(Vec UT, PetscReal *J, Vec dJdU) override;
  bool has_integrand() const override { return true; }
  PetscErrorCode integrand(PetscReal t, Vec U, PetscReal *r) override;
  PetscErrorCode integrand_dU(PetscReal t, Vec U, Vec drdU) override;
  bool integrand_reads_component(PetscInt c) const override { return c == component_; }
  bool integrand_reads_parameters() const override { return false; }
  bool adds_integrand_dU() const override { return true; }
  PetscErrorCode integrand_dU_add(PetscReal t, Vec U, PetscReal w, Vec lambda) override;

private:
  PetscErrorCode read_positions();
  PetscErrorCode read_wavelet(const char *file);
  PetscErrorCode build_receiver_matrix(DM state_dm);
  // d(t) of the current shot into dvec_ (rank 0 holds every entry).
  PetscErrorCode data_at(PetscReal t);
  PetscErrorCode sample(Vec U);                 // y_ = R U, U a state or the positions alone
  PetscErrorCode positions_sampling(Vec Q);     // R_positions_, Q shaped as the positions
  PetscErrorCode residual(PetscReal t, Vec U); // y_ = R U - d(t)
  // R for vectors of `per_point` components per grid point (the state's dof_, or the positions alone)
  PetscErrorCode assemble_sampling(PetscInt per_point, Vec like, Mat *R) const;

  const Grid *grid_ = nullptr;
  Model *model_ = nullptr;
  MPI_Comm comm_ = MPI_COMM_NULL;
  PetscMPIInt rank_ = 0;
  PetscInt component_ = 0, dof_ = 1, nshots_ = 1, shot_ = 0, nt_ = 0;
  PetscInt first_ = 0, end_ = -1; // the shots fired (end -1: all)
  std::vector<PetscReal> src_x_, src_y_, src_z_, rec_x_, rec_y_, rec_z_; // y, z: 0 where the grid lacks them
  std::vector<PointSource> sources_;
  Interpolation interpolation_ = Interpolation::Linear;
  Wavelet wavelet_;
  PetscReal sample_dt_ = 0;
  std::vector<PetscReal> traces_; // [shot][receiver][sample], on rank 0 (every rank after read/record)
  std::vector<char> recorded_;
  std::vector<PetscReal> observed_; // the traces before any band was set (empty: none set yet)
  Wavelet source_wavelet_;           // the wavelet before any band was set
  bool banded_ = false;
  bool recording_ = false;
  char data_file_[PETSC_MAX_PATH_LEN] = "", write_file_[PETSC_MAX_PATH_LEN] = "";
  OwnedMat R_, R_positions_; // sampling from states, and from the positions alone (made when first needed)
  OwnedVec y_, dvec_;
};

} // namespace flexipde
