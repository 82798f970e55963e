// Named parameters packed into the single distributed Vec that TSAdjoint and TAO see.
//
// A scalar parameter is one entry owned by rank 0; a vector is `entries` scalars under one name (the
// weights of a learned discretisation: one option, one help line), also owned by rank 0; a field has
// one value per grid point and is distributed exactly like the grid. Local layout on each rank:
// [scalars, then vectors (rank 0 only)] [field 1 owned points] [field 2 owned points] ... A scene
// that declares only scalars allocates no field. Values are set from options through profiles, see
// `fill_from_options`.
#pragma once
#include "flexipde/grid.hpp"
#include <string>
#include <vector>

namespace flexipde {

enum class ParamKind { Scalar, Field, Vector };

struct ParamInfo {
  std::string name;
  ParamKind kind;
  PetscInt local_offset = 0; // position of this parameter's first local entry in the packed local array
  PetscInt local_size = 0;
  PetscReal lower = PETSC_NINFINITY; // physical lower bound declared by the model (e.g. a speed > 0)
  PetscReal initial = 1.0;           // value when the options give none (the model's default)
  PetscInt global_start = 0;         // global index of its first entry (a scalar: the same on every rank)
  PetscInt entries = 1;              // a vector's length (1 for a scalar; a field: the grid's points)
  std::vector<PetscReal> initial_entries; // a vector's default values (empty: `initial` everywhere)
};

class Parameters {
public:
  // Declaration (before finalize). Returns the index used to refer to the parameter later.
  PetscInt add(const std::string &name, ParamKind kind, PetscReal lower = PETSC_NINFINITY, PetscReal initial = 1.0);
  // A vector of `entries` values with these defaults (entries = initial.size()).
  PetscInt add_vector(const std::string &name, const std::vector<PetscReal> &initial, PetscReal lower = PETSC_NINFINITY);
  PetscErrorCode finalize(const Grid &grid);

  PetscErrorCode create_vec(Vec *p) const;
  PetscInt count() const { return static_cast<PetscInt>(info_.size()); }
  const ParamInfo &info(PetscInt k) const { return info_[k]; }
  PetscInt find(const std::string &name) const; // -1 when absent
  PetscInt local_size() const { return nlocal_; }
  PetscInt global_size() const { return nglobal_; }
  PetscInt rstart() const { return rstart_; }
  // Global index of a scalar, and of local point `i_local` of a field (for Jacobian columns).
  PetscInt global_index(PetscInt k, PetscInt i_local = 0) const { return info_[k].global_start + i_local; }

  // Value of scalar k, the same on every rank (collective).
  PetscErrorCode scalar(Vec p, PetscInt k, PetscReal *value) const;
  // Fill / read field k from / into a grid-shaped Vec (dof = 1 on grid.dm()).
  PetscErrorCode set_field(Vec p, PetscInt k, Vec field) const;
  PetscErrorCode get_field(Vec p, PetscInt k, Vec field) const;
  // Parameter k on the grid, whatever its kind: a field as get_field, a scalar at every point.
  PetscErrorCode as_field(Vec p, PetscInt k, Vec field) const;
  PetscErrorCode set_scalar(Vec p, PetscInt k, PetscReal value) const;
  // Vector k's values, the same on every rank (collective), and setting them (from any rank's copy:
  // rank 0 stores them).
  PetscErrorCode vector_values(Vec p, PetscInt k, std::vector<PetscReal> &values) const;
  PetscErrorCode set_vector(Vec p, PetscInt k, const std::vector<PetscReal> &values) const;
  // grad[vector k] += the sum over ranks of `local` (entries values per rank; collective).
  PetscErrorCode add_local_sums(Vec grad, PetscInt k, const PetscReal *local) const;
  // Gradient accumulation (collective). add_local_sum: grad[k] += sum over ranks of `local`, for
  // a scalar. add_pointwise: g holds one value per owned grid point; a field takes it entry by
  // entry, a scalar takes its sum over all points.
  PetscErrorCode add_local_sum(Vec grad, PetscInt k, PetscReal local) const;
  PetscErrorCode add_pointwise(Vec grad, PetscInt k, const std::vector<PetscReal> &g) const;
  // Deferred sums: after defer_sums(grad), add_local_sum(grad, ...) only adds to a per-rank partial
  // sum (no communication, grad untouched) until flush_sums() reduces them all at once (collective)
  // and adds them to grad. For an adjoint that adds to a scalar's gradient at every time level: one
  // reduction per gradient instead of one per level. Sums for any other Vec are not deferred.
  void defer_sums(Vec grad) const;
  PetscErrorCode flush_sums() const;

  const Grid *grid() const { return grid_; }

private:
  std::vector<ParamInfo> info_;
  const Grid *grid_ = nullptr;
  PetscInt nlocal_ = 0, nglobal_ = 0, rstart_ = 0;
  bool finalized_ = false;
  mutable Vec deferred_ = nullptr;          // the Vec whose scalar sums are deferred (not owned)
  mutable std::vector<PetscReal> pending_; // per scalar: this rank's deferred partial sum
};

// A profile fills a parameter (scalar or field) from options with a given prefix, e.g. for
// prefix "wave_c": -wave_c 1.0 | -wave_c_profile linear -wave_c_left 0.9 -wave_c_right 1.0 |
// -wave_c_profile gaussian -wave_c 1.0 -wave_c_bump 0.1 -wave_c_center 0.5 -wave_c_width 0.1.
// A scalar parameter takes -<prefix> only. A vector takes -<prefix> v1,v2,... (all its entries) or
// -<prefix>_file F: a text file of numbers, or an HDF5 file holding the series /vectors/<prefix>
// (what a training run writes; e.g. -learned_burgers_theta_file results/learned_burgers.h5).
PetscErrorCode fill_from_options(const Parameters &params, PetscInt k, const char *prefix, PetscReal default_value,
                                 Vec p);

} // namespace flexipde
