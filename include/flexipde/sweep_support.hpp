// Pieces the models' matrix-free sweeps share: the recorded RK stage that dG/dp is applied at
// (kept by reference, checked before every use), the tag of a product computed ahead for it, and a
// four-accumulator sum for a scalar
// parameter's gradient from its per-point terms.
#pragma once
#include "flexipde/petsc.hpp"
#include <petsc/private/petscimpl.h> // PetscObjectStateGet
#include <algorithm>
#include <cstdint>
#include <cstring>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace flexipde {

// *p = v, with a non-temporal store when `stream` (8 bytes past the caches; stream_copy's entries before
// its first and after its last 16-byte pair); stream_fence() after the last of them.
inline void record_store(PetscScalar *p, PetscReal v, bool stream) {
#if defined(__SSE2__) && !defined(PETSC_USE_COMPLEX) && defined(PETSC_USE_REAL_DOUBLE)
  if (stream) {
    long long bits;
    std::memcpy(&bits, &v, sizeof bits);
    _mm_stream_si64(reinterpret_cast<long long *>(p), bits);
    return;
  }
#endif
  (void)stream;
  *p = v;
}
inline void stream_fence() {
#if defined(__SSE2__)
  _mm_sfence();
#endif
}
// b[0, n) = x[0, n) with non-temporal stores (two entries at a time from the first 16-byte boundary of b;
// for buffers written once and read much later); stream_fence() after the last of them.
inline void stream_copy(PetscScalar *b, const PetscScalar *x, PetscInt n) {
#if defined(__SSE2__) && !defined(PETSC_USE_COMPLEX) && defined(PETSC_USE_REAL_DOUBLE)
  PetscInt i = 0;
  if (n > 0 && reinterpret_cast<uintptr_t>(b) % 16) record_store(b, x[0], true), i = 1;
  for (; i + 1 < n; i += 2) _mm_stream_pd(b + i, _mm_loadu_pd(x + i));
  for (; i < n; ++i) record_store(b + i, x[i], true);
#else
  std::copy(x, x + n, b);
#endif
}

// The state U that rhs_jacobian_p was last given, kept by reference instead of copied: dG/dp is
// evaluated at it only when applied (or fused into the transpose of dG/dU, see FusedProducts). Every
// use checks that U is the same Vec in the same state as when recorded, so data changed since can
// never be used: that is an error instead. serial() changes with every record and with every
// invalidate() (new parameters), so a product computed at one record is never taken for another.
class RecordedStage {
public:
  RecordedStage() = default;
  RecordedStage(const RecordedStage &) = delete;
  RecordedStage &operator=(const RecordedStage &) = delete;
  ~RecordedStage() { (void)VecDestroy(&U_); }
  // Keeps U and starts loading its values into the cache: the integrator does its own vector work
  // before the products read them (the stored stages are cold: each is read once per adjoint).
  PetscErrorCode record(Vec U) {
    PetscFunctionBeginUser;
    PetscCall(PetscObjectReference((PetscObject)U));
    PetscCall(VecDestroy(&U_));
    U_ = U;
    PetscCall(PetscObjectGetId((PetscObject)U, &id_));
    PetscCall(PetscObjectStateGet((PetscObject)U, &state_));
    ++serial_;
    const PetscScalar *u;
    PetscInt n;
    PetscCall(VecGetLocalSize(U, &n));
    PetscCall(VecGetArrayRead(U, &u));
    // A hint only (a prefetch never faults, whatever the address): U, and the block of the same
    // size just below it, which is where a full-storage trajectory keeps the stage (or state) the
    // adjoint reads next (descending through the buffer). Capped: large arrays stream anyway.
    const size_t bytes = std::min<size_t>((size_t)n * sizeof(PetscScalar), 256 * 1024);
    const char *b = reinterpret_cast<const char *>(u);
    for (size_t c = 0; c < bytes; c += 64) __builtin_prefetch(b + c, 0, 3);
    for (size_t c = 0; c < bytes; c += 64) __builtin_prefetch(b - (size_t)n * sizeof(PetscScalar) + c, 0, 2);
    PetscCall(VecRestoreArrayRead(U, &u));
    PetscFunctionReturn(0);
  }
  void invalidate() { ++serial_; }
  unsigned long serial() const { return serial_; }
  bool recorded() const { return U_ != nullptr; }
  // True when U is unchanged since record().
  PetscErrorCode unchanged(bool *same) const {
    PetscObjectState state;
    PetscFunctionBeginUser;
    *same = false;
    if (!U_) PetscFunctionReturn(0);
    PetscCall(PetscObjectStateGet((PetscObject)U_, &state));
    *same = state == state_;
    PetscFunctionReturn(0);
  }
  // U for the products; an error when none was recorded or U changed since.
  PetscErrorCode get(Vec *U) const {
    bool same = false;
    PetscFunctionBeginUser;
    PetscCall(unchanged(&same));
    PetscCheck(same, PETSC_COMM_SELF, PETSC_ERR_ARG_WRONGSTATE,
               "dG/dp applied %s: call rhs_jacobian_p at the state first", U_ ? "after its state U was changed" : "before any rhs_jacobian_p");
    *U = U_;
    PetscFunctionReturn(0);
  }

private:
  Vec U_ = nullptr;
  PetscObjectId id_ = -1;
  PetscObjectState state_ = -1;
  unsigned long serial_ = 0;
};

// Tags a product computed ahead (by a fused sweep) with the Vec x it was computed from (id and state)
// and the recorded stage (RecordedStage::serial()): a later product may take it only on an exact match.
struct ProductTag {
  bool valid = false;
  PetscObjectId x_id = -1;
  PetscObjectState x_state = -1;
  unsigned long serial = 0;
  PetscErrorCode store(Vec x, unsigned long stage_serial) {
    PetscFunctionBeginUser;
    PetscCall(PetscObjectGetId((PetscObject)x, &x_id));
    PetscCall(PetscObjectStateGet((PetscObject)x, &x_state));
    serial = stage_serial;
    valid = true;
    PetscFunctionReturn(0);
  }
  PetscErrorCode matches(Vec x, unsigned long stage_serial, bool *hit) const {
    PetscObjectId id;
    PetscObjectState state;
    PetscFunctionBeginUser;
    *hit = false;
    if (!valid || serial != stage_serial) PetscFunctionReturn(0);
    PetscCall(PetscObjectGetId((PetscObject)x, &id));
    PetscCall(PetscObjectStateGet((PetscObject)x, &state));
    *hit = id == x_id && state == x_state;
    PetscFunctionReturn(0);
  }
};

// s[0..3] += the sum of a[lo, hi) in four interleaved partial sums held in registers (indexing s by
// i & 3 inside the loop goes through memory, a dependency chain per element).
inline void sum4(const PetscReal *__restrict a, PetscInt lo, PetscInt hi, PetscReal s[4]) {
  PetscReal s0 = 0, s1 = 0, s2 = 0, s3 = 0;
  PetscInt i = lo;
  for (; i + 3 < hi; i += 4) s0 += a[i], s1 += a[i + 1], s2 += a[i + 2], s3 += a[i + 3];
  for (; i < hi; ++i) s0 += a[i];
  s[0] += s0, s[1] += s1, s[2] += s2, s[3] += s3;
}

} // namespace flexipde
