// HDF5 output through PETSc's HDF5 viewer (parallel, one file for all ranks).
//
// Layout of a results file:
//   /grid/x                      grid coordinates
//   /fields/<name>               parameter fields and states on the grid (e.g. c_true, c_initial,
//                                c_recovered, u_final, u_data)
//   /scalars/<name>              scalar parameters as length-1 datasets
//   /history/<name>              one entry per optimisation iteration (iteration, objective,
//                                misfit, gradient_norm, rmse)
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
  PetscErrorCode close();

private:
  MPI_Comm comm_ = MPI_COMM_NULL;
  OwnedViewer viewer_;
};

} // namespace flexipde
