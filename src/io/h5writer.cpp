#include "flexipde/io.hpp"
#include <cstdio>
#include <petscviewerhdf5.h>
#include <sstream>

namespace flexipde {

PetscErrorCode H5Writer::open(MPI_Comm comm, const std::string &file) {
  PetscFunctionBeginUser;
  comm_ = comm;
  file_ = file;
  grid_ = nullptr;
  grid_datasets_.clear();
  PetscCall(PetscViewerHDF5Open(comm, file.c_str(), FILE_MODE_WRITE, viewer_.out()));
  PetscFunctionReturn(0);
}

PetscErrorCode H5Writer::write_vec(const char *group, const char *name, Vec v) {
  const char *old;
  DM dm;
  PetscFunctionBeginUser;
  PetscCall(PetscObjectGetName((PetscObject)v, &old));
  std::string keep = old ? old : "";
  PetscCall(PetscObjectSetName((PetscObject)v, name));
  PetscCall(PetscViewerHDF5PushGroup(viewer_, group));
  PetscCall(VecView(v, viewer_));
  PetscCall(PetscViewerHDF5PopGroup(viewer_));
  PetscCall(PetscObjectSetName((PetscObject)v, keep.c_str()));
  PetscCall(VecGetDM(v, &dm));
  if (dm) { // a DMDA vector: a field or state on the grid, listed in the XDMF companion
    PetscBool da;
    PetscCall(PetscObjectTypeCompare((PetscObject)dm, DMDA, &da));
    if (da) {
      PetscInt dof;
      PetscCall(DMDAGetInfo(dm, nullptr, nullptr, nullptr, nullptr, nullptr, nullptr, nullptr, &dof, nullptr, nullptr,
                            nullptr, nullptr, nullptr));
      grid_datasets_.push_back({std::string(group) + "/" + name, dof});
    }
  }
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
  OwnedVec x, y, z;
  PetscFunctionBeginUser;
  grid_ = &grid;
  // owned point q is ((k - zs) ym + (j - ys)) xm + (i - xs)
  const PetscInt xm = grid.xm(), ym = grid.ym();
  PetscCall(DMCreateGlobalVector(grid.dm(), x.out()));
  {
    Array a(x);
    PetscCall(a.error());
    for (PetscInt i = 0; i < grid.local_points(); ++i) a[i] = grid.x(grid.xs() + i % xm);
  }
  PetscCall(write_vec("/grid", "x", x));
  if (grid.dim() >= 2) {
    PetscCall(DMCreateGlobalVector(grid.dm(), y.out()));
    {
      Array a(y);
      PetscCall(a.error());
      for (PetscInt i = 0; i < grid.local_points(); ++i) a[i] = grid.y(grid.ys() + (i / xm) % ym);
    }
    PetscCall(write_vec("/grid", "y", y));
  }
  if (grid.dim() == 3) {
    PetscCall(DMCreateGlobalVector(grid.dm(), z.out()));
    {
      Array a(z);
      PetscCall(a.error());
      for (PetscInt i = 0; i < grid.local_points(); ++i) a[i] = grid.z(grid.zs() + i / (xm * ym));
    }
    PetscCall(write_vec("/grid", "z", z));
  }
  PetscFunctionReturn(0);
}

// The .xmf: a CoRectMesh (origin and spacing) with one point attribute per grid dataset; a state
// with dof components becomes dof attributes, each a hyperslab of the (..., dof) dataset.
PetscErrorCode H5Writer::write_xdmf() {
  PetscMPIInt rank;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_rank(comm_, &rank));
  if (rank != 0 || !grid_ || grid_datasets_.empty()) PetscFunctionReturn(0);
  const Grid &g = *grid_;
  std::string h5 = file_;
  const size_t slash = h5.find_last_of('/');
  if (slash != std::string::npos) h5 = h5.substr(slash + 1); // relative to the .xmf
  std::string xmf = file_;
  const size_t dot = xmf.find_last_of('.');
  xmf = (dot != std::string::npos && (slash == std::string::npos || dot > slash) ? xmf.substr(0, dot) : xmf) + ".xmf";
  std::ostringstream o;
  o.precision(17);
  // The datasets' shape, slowest direction first: (n), (ny, n) or (nz, ny, n), as PETSc writes a DMDA Vec.
  const PetscInt dim = g.dim();
  std::string dims = std::to_string(g.n());
  for (PetscInt d = 1; d < dim; ++d) dims = std::to_string(g.n((int)d)) + " " + dims;
  o << "<?xml version=\"1.0\" ?>\n<!DOCTYPE Xdmf SYSTEM \"Xdmf.dtd\" []>\n<Xdmf Version=\"3.0\">\n <Domain>\n"
    << "  <Grid Name=\"flexipde\" GridType=\"Uniform\">\n";
  if (dim == 3)
    o << "   <Topology TopologyType=\"3DCoRectMesh\" Dimensions=\"" << dims << "\"/>\n"
      << "   <Geometry GeometryType=\"ORIGIN_DXDYDZ\">\n"
      << "    <DataItem Dimensions=\"3\" NumberType=\"Float\" Precision=\"8\" Format=\"XML\">" << g.z0() << " " << g.y0()
      << " " << g.x0() << "</DataItem>\n"
      << "    <DataItem Dimensions=\"3\" NumberType=\"Float\" Precision=\"8\" Format=\"XML\">" << g.hz() << " " << g.hy()
      << " " << g.h() << "</DataItem>\n   </Geometry>\n";
  else if (dim == 2)
    o << "   <Topology TopologyType=\"2DCoRectMesh\" Dimensions=\"" << dims << "\"/>\n"
      << "   <Geometry GeometryType=\"ORIGIN_DXDY\">\n"
      << "    <DataItem Dimensions=\"2\" NumberType=\"Float\" Precision=\"8\" Format=\"XML\">" << g.y0() << " " << g.x0()
      << "</DataItem>\n"
      << "    <DataItem Dimensions=\"2\" NumberType=\"Float\" Precision=\"8\" Format=\"XML\">" << g.hy() << " " << g.h()
      << "</DataItem>\n   </Geometry>\n";
  else
    o << "   <Topology TopologyType=\"3DCoRectMesh\" Dimensions=\"1 1 " << g.n() << "\"/>\n"
      << "   <Geometry GeometryType=\"ORIGIN_DXDYDZ\">\n"
      << "    <DataItem Dimensions=\"3\" NumberType=\"Float\" Precision=\"8\" Format=\"XML\">0 0 " << g.x0()
      << "</DataItem>\n"
      << "    <DataItem Dimensions=\"3\" NumberType=\"Float\" Precision=\"8\" Format=\"XML\">1 1 " << g.h()
      << "</DataItem>\n   </Geometry>\n";
  for (const GridDataset &d : grid_datasets_) {
    std::string name = d.path;
    for (auto &ch : name)
      if (ch == '/') ch = '_';
    name = name.substr(name.find_first_not_of('_'));
    if (d.dof == 1) {
      o << "   <Attribute Name=\"" << name << "\" AttributeType=\"Scalar\" Center=\"Node\">\n"
        << "    <DataItem Dimensions=\"" << dims << "\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">" << h5 << ":"
        << d.path << "</DataItem>\n   </Attribute>\n";
      continue;
    }
    // hyperslab of component c: start (0, ..., 0, c), stride (1, ..., 1), count (dims, 1)
    std::string zeros, ones;
    for (PetscInt a = 0; a < dim; ++a) zeros += "0 ", ones += "1 ";
    for (PetscInt c = 0; c < d.dof; ++c) {
      const std::string comp = c < (PetscInt)component_names_.size() && d.dof == (PetscInt)component_names_.size()
                                   ? component_names_[c]
                                   : std::to_string(c);
      o << "   <Attribute Name=\"" << name << "_" << comp << "\" AttributeType=\"Scalar\" Center=\"Node\">\n"
        << "    <DataItem ItemType=\"HyperSlab\" Dimensions=\"" << dims << " 1\" Type=\"HyperSlab\">\n"
        << "     <DataItem Dimensions=\"3 " << dim + 1 << "\" Format=\"XML\">" << zeros << c << " " << ones << "1 "
        << dims << " 1</DataItem>\n"
        << "     <DataItem Dimensions=\"" << dims << " " << d.dof << "\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">"
        << h5 << ":" << d.path << "</DataItem>\n    </DataItem>\n   </Attribute>\n";
    }
  }
  o << "  </Grid>\n </Domain>\n</Xdmf>\n";
  FILE *f = std::fopen(xmf.c_str(), "w");
  PetscCheck(f, PETSC_COMM_SELF, PETSC_ERR_FILE_OPEN, "Cannot write the XDMF companion %s", xmf.c_str());
  const std::string s = o.str();
  const bool ok = std::fwrite(s.data(), 1, s.size(), f) == s.size();
  std::fclose(f);
  PetscCheck(ok, PETSC_COMM_SELF, PETSC_ERR_FILE_WRITE, "Cannot write the XDMF companion %s", xmf.c_str());
  PetscFunctionReturn(0);
}

PetscErrorCode H5Writer::close() {
  PetscFunctionBeginUser;
  viewer_.reset();
  PetscCall(write_xdmf());
  grid_datasets_.clear();
  grid_ = nullptr;
  PetscFunctionReturn(0);
}

PetscErrorCode H5Reader::open(MPI_Comm comm, const std::string &file) {
  PetscBool exists;
  PetscFunctionBeginUser;
  comm_ = comm;
  file_ = file;
  PetscCall(PetscTestFile(file.c_str(), 'r', &exists));
  PetscCheck(exists, comm, PETSC_ERR_FILE_OPEN, "Cannot read %s: no such file (or not readable)", file.c_str());
  PetscCall(PetscViewerHDF5Open(comm, file.c_str(), FILE_MODE_READ, viewer_.out()));
  PetscFunctionReturn(0);
}

PetscErrorCode H5Reader::has(const char *group, const char *name, bool *exists) {
  PetscBool e;
  PetscFunctionBeginUser;
  const std::string path = std::string(group) + "/" + name;
  PetscCall(PetscViewerHDF5HasDataset(viewer_, path.c_str(), &e));
  *exists = e;
  PetscFunctionReturn(0);
}

PetscErrorCode H5Reader::read_vec(const char *group, const char *name, Vec v) {
  bool exists;
  PetscInt n, nfile;
  PetscFunctionBeginUser;
  PetscCall(has(group, name, &exists));
  PetscCheck(exists, comm_, PETSC_ERR_FILE_UNEXPECTED, "%s has no dataset %s/%s", file_.c_str(), group, name);
  {
    OwnedVec probe;
    PetscCall(VecCreate(comm_, probe.out()));
    PetscCall(PetscObjectSetName((PetscObject)(Vec)probe, name));
    PetscCall(PetscViewerHDF5PushGroup(viewer_, group));
    PetscCall(VecLoad(probe, viewer_));
    PetscCall(PetscViewerHDF5PopGroup(viewer_));
    PetscCall(VecGetSize(probe, &nfile));
    PetscCall(VecGetSize(v, &n));
    PetscCheck(n == nfile, comm_, PETSC_ERR_FILE_UNEXPECTED, "%s:%s/%s has %" PetscInt_FMT " entries, expected %" PetscInt_FMT,
               file_.c_str(), group, name, nfile, n);
    // redistribute into v's layout (the file knows no layout)
    VecScatter sc;
    IS is;
    PetscInt lo, hi;
    PetscCall(VecGetOwnershipRange(v, &lo, &hi));
    PetscCall(ISCreateStride(comm_, hi - lo, lo, 1, &is));
    PetscCall(VecScatterCreate(probe, is, v, is, &sc));
    PetscCall(VecScatterBegin(sc, probe, v, INSERT_VALUES, SCATTER_FORWARD));
    PetscCall(VecScatterEnd(sc, probe, v, INSERT_VALUES, SCATTER_FORWARD));
    PetscCall(VecScatterDestroy(&sc));
    PetscCall(ISDestroy(&is));
  }
  PetscFunctionReturn(0);
}

PetscErrorCode H5Reader::read_series(const char *group, const char *name, std::vector<PetscReal> &values) {
  bool exists;
  PetscFunctionBeginUser;
  PetscCall(has(group, name, &exists));
  PetscCheck(exists, comm_, PETSC_ERR_FILE_UNEXPECTED, "%s has no dataset %s/%s", file_.c_str(), group, name);
  OwnedVec v, all;
  VecScatter sc;
  PetscCall(VecCreate(comm_, v.out()));
  PetscCall(PetscObjectSetName((PetscObject)(Vec)v, name));
  PetscCall(PetscViewerHDF5PushGroup(viewer_, group));
  PetscCall(VecLoad(v, viewer_));
  PetscCall(PetscViewerHDF5PopGroup(viewer_));
  PetscCall(VecScatterCreateToAll(v, &sc, all.out()));
  PetscCall(VecScatterBegin(sc, v, all, INSERT_VALUES, SCATTER_FORWARD));
  PetscCall(VecScatterEnd(sc, v, all, INSERT_VALUES, SCATTER_FORWARD));
  PetscCall(VecScatterDestroy(&sc));
  PetscInt n;
  PetscCall(VecGetSize(all, &n));
  ConstArray a(all);
  PetscCall(a.error());
  values.resize(n);
  for (PetscInt i = 0; i < n; ++i) values[i] = PetscRealPart(a[i]);
  PetscFunctionReturn(0);
}

PetscErrorCode H5Reader::close() {
  PetscFunctionBeginUser;
  viewer_.reset();
  PetscFunctionReturn(0);
}

} // namespace flexipde
