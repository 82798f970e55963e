// HDF5 input and output through PETSc's HDF5 viewer (parallel, one file for all ranks), with an
// XDMF companion for ParaView.
//
// Layout of a results file (datasets are plain arrays; a grid field of a 2D grid has shape
// (ny, nx), of a 3D grid (nz, ny, nx), a state with several components per point (n, dof),
// (ny, nx, dof) or (nz, ny, nx, dof)):
//   /grid/x, /grid/y, /grid/z    coordinates of every grid point (y in 2D and 3D, z in 3D)
//   /fields/<name>               parameter fields and states on the grid (e.g. wave_c_true,
//                                wave_c_initial, wave_c_recovered, U_final, data)
//   /history/<name>              one entry per optimisation iteration (iteration, objective,
//                                misfit, gradient_norm, rmse)
//   /restart/p, /restart/iteration  the last iterate of an inversion (-inv_restart reads it)
//   /gradient/dJdp, /gradient/J  the driver's -task gradient
// In Python:  import h5py;  f = h5py.File("results/fwi_field.h5");  c = f["/fields/wave_c_recovered"][:]
//
// close() writes <file>.xmf next to <file>.h5 (rank 0): a structured grid (1D as a line of points,
// 2D as an image, 3D as a volume) with every grid-shaped dataset of the file as a point attribute, states split
// into their components, so that ParaView opens the .xmf directly.
#pragma once
#include "flexipde/grid.hpp"
#include <string>
#include <vector>

namespace flexipde {

class H5Writer {
public:
  PetscErrorCode open(MPI_Comm comm, const std::string &file);
  PetscErrorCode write_vec(const char *group, const char *name, Vec v);
  // A replicated series (same on every rank) written once.
  PetscErrorCode write_series(const char *group, const char *name, const std::vector<PetscReal> &values);
  PetscErrorCode write_attribute(const char *dataset, const char *name, const char *value);
  PetscErrorCode write_coordinates(const Grid &grid);
  // Component names for the XDMF attributes of states with several components per point.
  void set_component_names(const std::vector<std::string> &names) { component_names_ = names; }
  PetscErrorCode close();

private:
  struct GridDataset {
    std::string path;
    PetscInt dof;
  };
  PetscErrorCode write_xdmf();
  MPI_Comm comm_ = MPI_COMM_NULL;
  OwnedViewer viewer_;
  std::string file_;
  const Grid *grid_ = nullptr;
  std::vector<GridDataset> grid_datasets_;
  std::vector<std::string> component_names_;
};

// Reads what H5Writer wrote. read_vec loads into a Vec of the right global size (its layout is
// kept); read_series returns a replicated series on every rank. Both fail with a message that
// names the file and the dataset when it is missing or of another size.
class H5Reader {
public:
  PetscErrorCode open(MPI_Comm comm, const std::string &file);
  PetscErrorCode has(const char *group, const char *name, bool *exists);
  PetscErrorCode read_vec(const char *group, const char *name, Vec v);
  PetscErrorCode read_series(const char *group, const char *name, std::vector<PetscReal> &values);
  PetscErrorCode close();

private:
  MPI_Comm comm_ = MPI_COMM_NULL;
  OwnedViewer viewer_;
  std::string file_;
};

} // namespace flexipde
