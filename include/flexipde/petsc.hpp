// RAII ownership of PETSc objects and the project's error conventions.
//
// Every function that calls PETSc returns PetscErrorCode and wraps each call in PetscCall, so an
// error unwinds with PETSc's own traceback. Handles own exactly one object, destroy it in their
// destructor and are move-only.
#pragma once
#include <petsc.h>
#include <utility>

namespace flexipde {

template <typename T, PetscErrorCode (*Destroy)(T *)>
class Handle {
public:
  Handle() = default;
  explicit Handle(T obj) : obj_(obj) {}
  Handle(const Handle &) = delete;
  Handle &operator=(const Handle &) = delete;
  Handle(Handle &&o) noexcept : obj_(std::exchange(o.obj_, nullptr)) {}
  Handle &operator=(Handle &&o) noexcept {
    if (this != &o) {
      reset();
      obj_ = std::exchange(o.obj_, nullptr);
    }
    return *this;
  }
  ~Handle() { reset(); }

  void reset() {
    if (obj_) (void)Destroy(&obj_);
    obj_ = nullptr;
  }
  T get() const { return obj_; }
  operator T() const { return obj_; }
  // Address for PETSc creation functions; releases what was held before.
  T *out() {
    reset();
    return &obj_;
  }
  explicit operator bool() const { return obj_ != nullptr; }

private:
  T obj_ = nullptr;
};

using OwnedVec = Handle<Vec, VecDestroy>;
using OwnedMat = Handle<Mat, MatDestroy>;
using OwnedDM = Handle<DM, DMDestroy>;
using OwnedTS = Handle<TS, TSDestroy>;
using OwnedTao = Handle<Tao, TaoDestroy>;
using OwnedViewer = Handle<PetscViewer, PetscViewerDestroy>;
using OwnedIS = Handle<IS, ISDestroy>;
using OwnedScatter = Handle<VecScatter, VecScatterDestroy>;

// Read access to a Vec's local array for the lifetime of the object.
class ConstArray {
public:
  ConstArray(Vec v) : v_(v) { err_ = v_ ? VecGetArrayRead(v_, &a_) : 0; } // null: no array (data() null)
  ~ConstArray() {
    if (!err_ && v_) (void)VecRestoreArrayRead(v_, &a_);
  }
  ConstArray(const ConstArray &) = delete;
  ConstArray &operator=(const ConstArray &) = delete;
  const PetscScalar &operator[](PetscInt i) const { return a_[i]; }
  const PetscScalar *data() const { return a_; }
  PetscErrorCode error() const { return err_; }

private:
  Vec v_;
  const PetscScalar *a_ = nullptr;
  PetscErrorCode err_;
};

class Array {
public:
  Array(Vec v) : v_(v) { err_ = VecGetArray(v_, &a_); }
  ~Array() {
    if (!err_) (void)VecRestoreArray(v_, &a_);
  }
  Array(const Array &) = delete;
  Array &operator=(const Array &) = delete;
  PetscScalar &operator[](PetscInt i) { return a_[i]; }
  PetscScalar *data() { return a_; }
  PetscErrorCode error() const { return err_; }

private:
  Vec v_;
  PetscScalar *a_ = nullptr;
  PetscErrorCode err_;
};

// A heap object owned by a PETSc object: composed under `name` in a PetscContainer that deletes it
// with the object (compose_owned); attached_object finds it again (null when there is none).
template <class T>
PetscErrorCode compose_owned(PetscObject obj, const char *name, T *p) {
  PetscContainer container;
  PetscFunctionBegin;
  PetscCall(PetscContainerCreate(PetscObjectComm(obj), &container));
  PetscCall(PetscContainerSetPointer(container, p));
  PetscCall(PetscContainerSetUserDestroy(container, [](void *q) -> PetscErrorCode {
    delete static_cast<T *>(q);
    return 0;
  }));
  PetscCall(PetscObjectCompose(obj, name, (PetscObject)container));
  PetscCall(PetscContainerDestroy(&container));
  PetscFunctionReturn(0);
}
template <class T>
PetscErrorCode attached_object(PetscObject obj, const char *name, T **p) {
  PetscContainer container = nullptr;
  PetscFunctionBegin;
  *p = nullptr;
  PetscCall(PetscObjectQuery(obj, name, (PetscObject *)&container));
  if (container) PetscCall(PetscContainerGetPointer(container, (void **)p));
  PetscFunctionReturn(0);
}

} // namespace flexipde
