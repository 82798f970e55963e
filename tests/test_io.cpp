// H5Writer round trip: what is written (distributed fields, replicated series, coordinates) is
// read back identically with PETSc's HDF5 viewer, on any number of ranks; on a 3D grid the datasets
// have shape (nz, ny, nx[, dof]) and the XDMF companion describes that volume.
#include "flexipde/io.hpp"
#include "flexipde/scene.hpp"
#include "test_support.hpp"
#include <cstdio>
#include <fstream>
#include <hdf5.h>
#include <petscviewerhdf5.h>
#include <sstream>
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

namespace {

// The dimensions of dataset `path` of an HDF5 file (empty when it is missing).
std::vector<hsize_t> dataset_shape(const std::string &file, const char *path) {
  std::vector<hsize_t> dims;
  hid_t f = H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (f < 0) return dims;
  if (H5Lexists(f, path, H5P_DEFAULT) > 0) {
    hid_t d = H5Dopen2(f, path, H5P_DEFAULT), sp = H5Dget_space(d);
    dims.resize((size_t)H5Sget_simple_extent_ndims(sp));
    H5Sget_simple_extent_dims(sp, dims.data(), nullptr);
    H5Sclose(sp);
    H5Dclose(d);
  }
  H5Fclose(f);
  return dims;
}

} // namespace

// A 3D grid (7 x 8 x 9, periodic in z, origin (-1, 0, 0.5); on 2 ranks split in z): coordinates and
// fields of shape (9, 8, 7), a two-component state (9, 8, 7, 2), /grid/z among the coordinates, each
// point's coordinates read back where the grid puts it, and an XDMF 3DCoRectMesh with origin and spacing
// in z, y, x order.
TEST(H5Writer, ThreeDimensionalGrid) {
  GridOptions go;
  go.dim = 3, go.n = 7, go.ny = 8, go.nz = 9;
  go.x0 = -1, go.x1 = 1, go.y0 = 0, go.y1 = 2, go.z0 = 0.5, go.z1 = 1.5, go.periodic_z = PETSC_TRUE;
  Grid grid;
  PETSC_ASSERT_OK(Grid::create(PETSC_COMM_WORLD, 1, go, grid));
  long pid = (long)getpid();
  MPI_Bcast(&pid, 1, MPI_LONG, 0, PETSC_COMM_WORLD);
  const std::string stem = "/tmp/flexipde_test_io3d_" + std::to_string(pid), file = stem + ".h5";

  OwnedDM state_dm;
  OwnedVec c, U;
  PETSC_ASSERT_OK(grid.create_dm(2, state_dm.out()));
  PETSC_ASSERT_OK(DMCreateGlobalVector(grid.dm(), c.out()));
  PETSC_ASSERT_OK(DMCreateGlobalVector(state_dm, U.out()));
  PETSC_ASSERT_OK(flexipde_test::fill_random(c, 0.5, 1.5, 5));
  PETSC_ASSERT_OK(flexipde_test::fill_random(U, -1, 1, 6));
  {
    H5Writer w;
    PETSC_ASSERT_OK(w.open(PETSC_COMM_WORLD, file));
    w.set_component_names({"u", "v"});
    PETSC_ASSERT_OK(w.write_coordinates(grid));
    PETSC_ASSERT_OK(w.write_vec("/fields", "c", c));
    PETSC_ASSERT_OK(w.write_vec("/fields", "U", U));
    PETSC_ASSERT_OK(w.close());
  }
  // every owned point's coordinates, read back in the grid's layout
  const char *axes[] = {"x", "y", "z"};
  PetscReal worst = 0;
  for (int d = 0; d < 3; ++d) {
    OwnedVec a;
    PETSC_ASSERT_OK(read_vec(PETSC_COMM_WORLD, file, "/grid", axes[d], c, a.out()));
    ConstArray v(a);
    PETSC_ASSERT_OK(v.error());
    for (PetscInt q = 0; q < grid.local_points(); ++q) {
      const PetscInt ijk[3] = {grid.xs() + q % grid.xm(), grid.ys() + (q / grid.xm()) % grid.ym(),
                               grid.zs() + q / (grid.xm() * grid.ym())};
      const PetscReal expected = d == 0 ? grid.x(ijk[0]) : d == 1 ? grid.y(ijk[1]) : grid.z(ijk[2]);
      worst = std::max(worst, std::fabs(PetscRealPart(v[q]) - expected));
    }
  }
  MPI_Allreduce(MPI_IN_PLACE, &worst, 1, MPIU_REAL, MPI_MAX, PETSC_COMM_WORLD);
  EXPECT_EQ(worst, 0.0);
  OwnedVec c2, U2;
  PETSC_ASSERT_OK(read_vec(PETSC_COMM_WORLD, file, "/fields", "c", c, c2.out()));
  PETSC_ASSERT_OK(read_vec(PETSC_COMM_WORLD, file, "/fields", "U", U, U2.out()));
  EXPECT_EQ(flexipde_test::rel_diff(c2, c), 0.0);
  EXPECT_EQ(flexipde_test::rel_diff(U2, U), 0.0);

  PetscInt ok = 1; // rank 0 reads the files; the verdict is shared so that every rank agrees
  if (flexipde_test::is_rank0()) {
    const std::vector<hsize_t> field = {9, 8, 7}, state = {9, 8, 7, 2};
    EXPECT_EQ(dataset_shape(file, "/grid/z"), field);
    EXPECT_EQ(dataset_shape(file, "/fields/c"), field);
    EXPECT_EQ(dataset_shape(file, "/fields/U"), state);
    std::ifstream in(stem + ".xmf");
    std::stringstream ss;
    ss << in.rdbuf();
    const std::string xmf = ss.str();
    char spacing[128];
    std::snprintf(spacing, sizeof spacing, "%.17g %.17g %.17g", (double)grid.hz(), (double)grid.hy(), (double)grid.h());
    EXPECT_DOUBLE_EQ(grid.hz(), 1.0 / 9); // periodic: the right end excluded
    for (const std::string &part :
         {std::string("<Topology TopologyType=\"3DCoRectMesh\" Dimensions=\"9 8 7\"/>"),
          std::string("<Geometry GeometryType=\"ORIGIN_DXDYDZ\">"), std::string(">0.5 0 -1</DataItem>"),
          std::string(">") + spacing + "</DataItem>", std::string("Name=\"fields_c\""), std::string("Name=\"fields_U_v\""),
          std::string("<DataItem Dimensions=\"9 8 7\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">"),
          std::string("<DataItem Dimensions=\"3 4\" Format=\"XML\">0 0 0 1 1 1 1 1 9 8 7 1</DataItem>"),
          std::string("<DataItem Dimensions=\"9 8 7 2\" NumberType=\"Float\"")}) {
      const bool found = xmf.find(part) != std::string::npos;
      EXPECT_TRUE(found) << "missing from the .xmf: " << part << "\n" << xmf;
      ok = ok && found;
    }
    std::remove(file.c_str());
    std::remove((stem + ".xmf").c_str());
  }
  MPI_Bcast(&ok, 1, MPIU_INT, 0, PETSC_COMM_WORLD);
  EXPECT_TRUE(ok);
}
