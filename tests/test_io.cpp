// H5Writer round trip: what is written (distributed fields, replicated series, coordinates) is
// read back identically with PETSc's HDF5 viewer, on any number of ranks.
#include "flexipde/io.hpp"
#include "flexipde/scene.hpp"
#include "test_support.hpp"
#include <cstdio>
#include <petscviewerhdf5.h>
#include <unistd.h>

using namespace flexipde;
using flexipde_test::ScopedOptions;

namespace {

// Reads dataset group/name into a Vec with the layout of `like`.
PetscErrorCode read_vec(MPI_Comm comm, const std::string &file, const char *group, const char *name, Vec like,
                        Vec *out) {
  PetscViewer v;
  PetscFunctionBeginUser;
  PetscCall(VecDuplicate(like, out));
  PetscCall(PetscObjectSetName((PetscObject)*out, name));
  PetscCall(PetscViewerHDF5Open(comm, file.c_str(), FILE_MODE_READ, &v));
  PetscCall(PetscViewerHDF5PushGroup(v, group));
  PetscCall(VecLoad(*out, v));
  PetscCall(PetscViewerHDF5PopGroup(v));
  PetscCall(PetscViewerDestroy(&v));
  PetscFunctionReturn(0);
}

} // namespace

TEST(H5Writer, RoundTrip) {
  ScopedOptions opts{{"-da_grid_x", "37"}, {"-wave_c_field", "1"}};
  Scene scene;
  PETSC_ASSERT_OK(scene.setup(PETSC_COMM_WORLD));
  // One file name for all ranks (rank 0's pid).
  long pid = (long)getpid();
  MPI_Bcast(&pid, 1, MPI_LONG, 0, PETSC_COMM_WORLD);
  const std::string file = "/tmp/flexipde_test_io_" + std::to_string(pid) + ".h5";

  OwnedVec c, U;
  PETSC_ASSERT_OK(DMCreateGlobalVector(scene.grid.dm(), c.out()));
  PETSC_ASSERT_OK(scene.sim.create_state(U.out()));
  PETSC_ASSERT_OK(flexipde_test::fill_random(c, 0.5, 1.5, 5));
  PETSC_ASSERT_OK(flexipde_test::fill_random(U, -1, 1, 6));
  PETSC_ASSERT_OK(PetscObjectSetName((PetscObject)c.get(), "keep_me"));
  const std::vector<PetscReal> series = {3.0, 1.5, 0.25, -2.0};
  {
    H5Writer w;
    PETSC_ASSERT_OK(w.open(PETSC_COMM_WORLD, file));
    PETSC_ASSERT_OK(w.write_coordinates(scene.grid));
    PETSC_ASSERT_OK(w.write_vec("/fields", "c", c));
    PETSC_ASSERT_OK(w.write_vec("/fields", "U", U));
    PETSC_ASSERT_OK(w.write_series("/history", "objective", series));
    PETSC_ASSERT_OK(w.close());
  }
  const char *name;
  PETSC_ASSERT_OK(PetscObjectGetName((PetscObject)c.get(), &name));
  EXPECT_STREQ(name, "keep_me") << "write_vec must restore the Vec's name";

  OwnedVec c2, U2, x, s;
  PETSC_ASSERT_OK(read_vec(PETSC_COMM_WORLD, file, "/fields", "c", c, c2.out()));
  PETSC_ASSERT_OK(read_vec(PETSC_COMM_WORLD, file, "/fields", "U", U, U2.out()));
  PETSC_ASSERT_OK(read_vec(PETSC_COMM_WORLD, file, "/grid", "x", c, x.out()));
  EXPECT_EQ(flexipde_test::rel_diff(c2, c), 0.0);
  EXPECT_EQ(flexipde_test::rel_diff(U2, U), 0.0);
  std::vector<PetscReal> xa;
  PETSC_ASSERT_OK(flexipde_test::gather_all(x, xa));
  ASSERT_EQ(xa.size(), 37u);
  for (PetscInt i = 0; i < 37; ++i) EXPECT_NEAR(xa[i], i / 36.0, 1e-15);

  OwnedVec like;
  PETSC_ASSERT_OK(VecCreateMPI(PETSC_COMM_WORLD, PETSC_DECIDE, (PetscInt)series.size(), like.out()));
  PETSC_ASSERT_OK(read_vec(PETSC_COMM_WORLD, file, "/history", "objective", like, s.out()));
  std::vector<PetscReal> sa;
  PETSC_ASSERT_OK(flexipde_test::gather_all(s, sa));
  EXPECT_EQ(sa, series);

  MPI_Barrier(PETSC_COMM_WORLD);
  if (flexipde_test::is_rank0()) std::remove(file.c_str());
}
