#include "flexipde/io.hpp"
#include <petscviewerhdf5.h>

namespace flexipde {

PetscErrorCode H5Writer::open(MPI_Comm comm, const std::string &file) {
  PetscFunctionBeginUser;
  comm_ = comm;
  PetscCall(PetscViewerHDF5Open(comm, file.c_str(), FILE_MODE_WRITE, viewer_.out()));
  PetscFunctionReturn(0);
}

PetscErrorCode H5Writer::write_vec(const char *group, const char *name, Vec v) {
  const char *old;
  PetscFunctionBeginUser;
  PetscCall(PetscObjectGetName((PetscObject)v, &old));
  std::string keep = old ? old : "";
  PetscCall(PetscObjectSetName((PetscObject)v, name));
  PetscCall(PetscViewerHDF5PushGroup(viewer_, group));
  PetscCall(VecView(v, viewer_));
  PetscCall(PetscViewerHDF5PopGroup(viewer_));
  PetscCall(PetscObjectSetName((PetscObject)v, keep.c_str()));
  PetscFunctionReturn(0);
}

PetscErrorCode H5Writer::write_series(const char *group, const char *name, const std::vector<PetscReal> &values) {
  PetscMPIInt rank;
  OwnedVec v;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_rank(comm_, &rank));
  const PetscInt n = static_cast<PetscInt>(values.size());
  PetscCall(VecCreateMPI(comm_, rank == 0 ? n : 0, n, v.out()));
  if (rank == 0) {
    Array a(v);
    PetscCall(a.error());
    for (PetscInt i = 0; i < n; ++i) a[i] = values[i];
  }
  PetscCall(write_vec(group, name, v));
  PetscFunctionReturn(0);
}

PetscErrorCode H5Writer::write_attribute(const char *dataset, const char *name, const char *value) {
  PetscFunctionBeginUser;
  PetscCall(PetscViewerHDF5WriteAttribute(viewer_, dataset, name, PETSC_STRING, value));
  PetscFunctionReturn(0);
}

PetscErrorCode H5Writer::write_coordinates(const Grid &grid) {
  OwnedVec x, y;
  PetscFunctionBeginUser;
  PetscCall(DMCreateGlobalVector(grid.dm(), x.out()));
  {
    Array a(x);
    PetscCall(a.error());
    for (PetscInt i = 0; i < grid.local_points(); ++i) a[i] = grid.x(grid.xs() + i % grid.xm());
  }
  PetscCall(write_vec("/grid", "x", x));
  if (grid.dim() == 2) {
    PetscCall(DMCreateGlobalVector(grid.dm(), y.out()));
    {
      Array a(y);
      PetscCall(a.error());
      for (PetscInt i = 0; i < grid.local_points(); ++i) a[i] = grid.y(grid.ys() + i / grid.xm());
    }
    PetscCall(write_vec("/grid", "y", y));
  }
  PetscFunctionReturn(0);
}

PetscErrorCode H5Writer::close() {
  PetscFunctionBeginUser;
  viewer_.reset();
  PetscFunctionReturn(0);
}

} // namespace flexipde
