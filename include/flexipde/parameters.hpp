// Named parameters packed into the single distributed Vec that TSAdjoint and TAO see.
//
// A scalar parameter is one entry owned by rank 0; a field has one value per grid point and is
// distributed exactly like the grid. Local layout on each rank: [scalars (rank 0 only)]
// [field 1 owned points] [field 2 owned points] ... A scene that declares only scalars allocates no
// field. Values are set from options through profiles, see `Profile`.
#pragma once
#include "flexipde/grid.hpp"
#include <string>
#include <vector>

namespace flexipde {

enum class ParamKind { Scalar, Field };

struct ParamInfo {
  std::string name;
  ParamKind kind;
  PetscInt local_offset = 0; // position of this parameter's first local entry in the packed local array
  PetscInt local_size = 0;
  PetscReal lower = PETSC_NINFINITY; // physical lower bound declared by the model (e.g. a speed > 0)
  PetscReal initial = 1.0;           // value when the options give none (the model's default)
  PetscInt global_start = 0;         // global index of its first entry (a scalar: the same on every rank)
};

class Parameters {
public:
  // Declaration (before finalize). Returns the index used to refer to the parameter later.
  PetscInt add(const std::string &name, ParamKind kind, PetscReal lower = PETSC_NINFINITY, PetscReal initial = 1.0);
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
// A scalar parameter takes -<prefix> only.
PetscErrorCode fill_from_options(const Parameters &params, PetscInt k, const char *prefix, PetscReal default_value,
                                 Vec p);

} // namespace flexipde
